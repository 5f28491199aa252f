"""The service's message protocol (version :data:`PROTOCOL_VERSION`; ``docs/service.md`` is its reference):
every message a client may send, its fields with their types and ranges, checked at the edge.

A message is a JSON object with a ``type`` and, for a request, an optional ``id`` (a string or an integer the
reply carries back). :func:`parse` turns the text of one WebSocket message into a :class:`Message` whose fields
are typed and in range, or raises :class:`ProtocolError` with an error code and one line saying what is wrong.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from ultraglide.errors import UltraglideError

PROTOCOL_VERSION = 1
MAX_MESSAGE_BYTES = 4 * 1024 * 1024  # the largest message: a PNG of some 3 MB in base64 (the socket refuses more)
MAX_SMALL_MESSAGE_BYTES = 64 * 1024  # every message but a texture's bytes
MAX_NAME = 64  # ids of textures, views, sprites, effects' events
MAX_TOUCH_CHARS = 1024  # a touch as clients write it is shorter (~400 with every field at its longest); a longer
# message is not parsed for its own time while its client is over its rate as read (server.Session.may_send)
MAX_DEPTH = 16  # JSON nesting (an effects description nests some 10 levels)
PHASES = ("down", "move", "up", "cancel")
ROLES = ("control", "observe")
DRIVES = ("first", "latest", "none")  # which pointer drives when two are down, as a rig's [touch] drives

# error codes (docs/service.md lists them)
BAD_MESSAGE = "bad-message"
TOO_BIG = "too-big"
RATE = "rate"
NO_HELLO = "no-hello"
BUSY = "busy"
READ_ONLY = "read-only"
UNKNOWN = "unknown"
TEXTURE = "texture"
LIMIT = "limit"
ENGINE = "engine"
TOUCH_PANEL = "touch-panel"  # a touch refused: the engine reads the touch panel itself (serve --touch-panel)


class ProtocolError(UltraglideError, ValueError):
    """A message refused: ``code`` (docs/service.md) and one line saying what is wrong."""

    def __init__(self, code: str, message: str, request_id=None):
        super().__init__(message)
        self.code = code
        self.request_id = request_id


@dataclass(frozen=True)
class Message:
    """A checked message: its ``type``, the client's ``id`` (or None) and its typed ``fields``."""

    type: str
    id: object
    fields: dict

    def __getitem__(self, key):
        return self.fields[key]

    def get(self, key, default=None):
        return self.fields.get(key, default)


def _name(value, key):
    if not isinstance(value, str) or not 1 <= len(value) <= MAX_NAME or not value.isprintable():
        raise ValueError(f"'{key}' must be a name of 1 to {MAX_NAME} printable characters")
    return value


def _text(limit):
    def check(value, key):
        if not isinstance(value, str) or len(value) > limit:
            raise ValueError(f"'{key}' must be a string of at most {limit} characters")
        return value
    return check


def _number(low, high, unit=""):
    def check(value, key):
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
                or not low <= value <= high:
            raise ValueError(f"'{key}' must be a number from {low:g} to {high:g}{unit}")
        return float(value)
    return check


def _positive(high, unit=""):
    def check(value, key):
        value = _number(0.0, high, unit)(value, key)
        if value <= 0:
            raise ValueError(f"'{key}' must be more than 0 and at most {high:g}{unit}")
        return value
    return check


def _choice(options):
    def check(value, key):
        if value not in options:
            raise ValueError(f"'{key}' must be one of {', '.join(options)}")
        return value
    return check


def _flag(value, key):
    if not isinstance(value, bool):
        raise ValueError(f"'{key}' must be true or false")
    return value


def _integer(low, high):
    def check(value, key):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ValueError(f"'{key}' must be a whole number from {low} to {high}")
        return value
    return check


def _rate_or_flag(high):
    def check(value, key):
        if value is False or value is None:
            return 0.0
        if value is True:
            return -1.0  # the default rate
        return _positive(high, " Hz")(value, key)
    return check


def _material(value, key):
    if isinstance(value, bool) or not (isinstance(value, int) and 0 <= value < 1_000_000
                                       or isinstance(value, str) and 1 <= len(value) <= 200 and value.isprintable()):
        raise ValueError(f"'{key}' must be a haptic material's name (1 to 200 printable characters) or its index "
                         "(a whole number from 0)")
    return value


def _object(value, key):
    if value is not None and not isinstance(value, dict | list):
        raise ValueError(f"'{key}' must be an object, a list or null")
    return value


COORD = _number(-1e6, 1e6)
SIZE = _positive(1e6)
RATIO = _number(0.0, 1.0)

# each type: {field: (check, required)}
SPECS: dict[str, dict] = {
    "hello": {"protocol": (_integer(1, 1000), True), "role": (_choice(ROLES), False),
              "client": (_text(200), False), "token": (_text(200), False)},
    "texture.load": {"texture": (_name, True), "library": (_text(200), False), "file": (_text(4096), False),
                     "png": (_text(MAX_MESSAGE_BYTES), False), "width_mm": (_positive(10000.0, " mm"), False),
                     "height_mm": (_positive(10000.0, " mm"), False), "name": (_text(200), False),
                     "material": (_material, False)},
    "texture.unload": {"texture": (_name, True)},
    "view.set": {"view": (_name, True), "width": (SIZE, True), "height": (SIZE, True),
                 "units": (_choice(("px", "mm")), False), "width_mm": (_positive(2000.0, " mm"), False),
                 "height_mm": (_positive(2000.0, " mm"), False), "background_ratio": (RATIO, False)},
    "view.remove": {"view": (_name, True)},
    "sprite.set": {"sprite": (_name, True), "view": (_name, False), "texture": (_name, False), "x": (COORD, False),
                   "y": (COORD, False), "width": (SIZE, False), "height": (SIZE, False),
                   "rotation_deg": (_number(-1e6, 1e6, " degrees"), False), "z": (COORD, False),
                   "visible": (_flag, False)},
    "sprite.remove": {"sprite": (_name, True)},
    "touch": {"view": (_name, False), "pointer": (_integer(-2**31, 2**31 - 1), False), "phase": (_choice(PHASES), True),
              "x": (COORD, True), "y": (COORD, True), "pressure": (RATIO, False),
              "force_n": (_number(0.0, 50.0, " N"), False), "t": (_number(-1e12, 1e12, " s"), False),
              "pointer_type": (_text(16), False)},
    "effects.set": {"effects": (_object, True)},
    "effect.trigger": {"name": (_name, True)},
    "effect.stop": {},
    "effects.attach": {"sprite": (_name, True), "effect": (_object, False), "effects": (_object, False),
                       "file": (_text(4096), False), "release_s": (_number(0.0, 60.0, " s"), False)},
    "effects.detach": {"sprite": (_name, True)},
    "touches.set": {"drives": (_choice(DRIVES), True)},
    "subscribe": {"status": (_rate_or_flag(20.0), False), "output": (_rate_or_flag(1000.0), False),
                  "touch": (_flag, False), "scene": (_flag, False)},
    "state": {},
}
CONTROL_TYPES = frozenset(SPECS) - {"hello", "subscribe", "state"}  # what an observer may not send


def _depth(value, level=0) -> int:
    if level > MAX_DEPTH:
        return level
    if isinstance(value, dict):
        return max((_depth(v, level + 1) for v in value.values()), default=level)
    if isinstance(value, list):
        return max((_depth(v, level + 1) for v in value), default=level)
    return level


def _no_constant(name):
    raise ValueError(f"{name} is not a JSON number")


_TOUCH_NUMBERS = {"x": (-1e6, 1e6), "y": (-1e6, 1e6), "t": (-1e12, 1e12), "pressure": (0.0, 1.0),
                  "force_n": (0.0, 50.0)}
_TOUCH_KEYS = frozenset(_TOUCH_NUMBERS) | {"type", "id", "phase", "view", "pointer", "pointer_type"}


def _touch_fast(data: dict, request_id) -> Message | None:
    """A touch whose every field is plainly right, checked in one pass (the messages that come a thousand a
    second); None sends anything else the general way, which says what is wrong."""
    if len(data) > len(_TOUCH_KEYS) or not _TOUCH_KEYS.issuperset(data) or data.get("phase") not in PHASES:
        return None
    fields = {"phase": data["phase"]}
    for key, (low, high) in _TOUCH_NUMBERS.items():
        value = data.get(key)
        if value is None:
            if key in ("x", "y"):
                return None
            continue
        if type(value) is not float and type(value) is not int or not low <= value <= high:  # (NaN fails too)
            return None
        fields[key] = float(value)
    pointer = data.get("pointer")
    if pointer is not None:
        if type(pointer) is not int or not -2**31 <= pointer < 2**31:
            return None
        fields["pointer"] = pointer
    for key in ("view", "pointer_type"):
        value = data.get(key)
        if value is not None:
            if type(value) is not str or not 1 <= len(value) <= (MAX_NAME if key == "view" else 16) \
                    or not value.isprintable():
                return None
            fields[key] = value
    return Message("touch", request_id, fields)


def parse(text: str | bytes, extra: dict | None = None) -> Message:
    """One message's text to a checked :class:`Message`; :class:`ProtocolError` with one line otherwise.
    ``extra``: more message types, as :data:`SPECS` gives them (a service's own, such as a participant's answers)."""
    if isinstance(text, bytes):
        raise ProtocolError(BAD_MESSAGE, "messages are JSON text frames, not binary ones")
    try:
        data = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as error:
        raise ProtocolError(BAD_MESSAGE, f"not JSON: {str(error).splitlines()[0][:200]}") from None
    if not isinstance(data, dict):
        raise ProtocolError(BAD_MESSAGE, "a message is a JSON object with a 'type'")
    request_id = data.get("id")
    if request_id is not None and not (isinstance(request_id, str) and len(request_id) <= MAX_NAME
                                       or isinstance(request_id, int) and not isinstance(request_id, bool)
                                       and abs(request_id) < 2**53):
        raise ProtocolError(BAD_MESSAGE, f"'id' must be a string of at most {MAX_NAME} characters or an integer")
    kind = data.get("type")
    spec = None
    if isinstance(kind, str):
        spec = SPECS[kind] if kind in SPECS else (extra or {}).get(kind)
    if spec is None:
        shown = repr(kind)[:60]
        raise ProtocolError(BAD_MESSAGE, f"unknown message type {shown}; known: {', '.join([*SPECS, *(extra or {})])}",
                            request_id)
    if kind == "touch":
        fast = _touch_fast(data, request_id)
        if fast is not None:
            return fast
    if kind != "texture.load" and len(text) > MAX_SMALL_MESSAGE_BYTES:
        raise ProtocolError(TOO_BIG, f"a {kind} message may have at most {MAX_SMALL_MESSAGE_BYTES} bytes",
                            request_id)
    if text.count("[") + text.count("{") > MAX_DEPTH and _depth(data) > MAX_DEPTH:
        raise ProtocolError(BAD_MESSAGE, f"the message nests deeper than {MAX_DEPTH} levels", request_id)
    unknown = sorted(set(data) - set(spec) - {"type", "id"})
    if unknown:
        raise ProtocolError(BAD_MESSAGE, f"{kind}: unknown field(s) {', '.join(repr(k)[:40] for k in unknown[:5])}",
                            request_id)
    fields = {}
    for key, (check, required) in spec.items():
        if key not in data or data[key] is None and key != "effects":
            if required:
                raise ProtocolError(BAD_MESSAGE, f"{kind}: '{key}' is missing", request_id)
            continue
        try:
            fields[key] = check(data[key], key)
        except ValueError as error:
            raise ProtocolError(BAD_MESSAGE, f"{kind}: {error}", request_id) from None
    return Message(kind, request_id, fields)


def reply(message_id, **fields) -> dict:
    """A request's answer: ``{"type": "ok", "id": ..., ...}``."""
    return {"type": "ok", "id": message_id, **fields}


def error_reply(code: str, text: str, message_id=None) -> dict:
    """A refusal: ``{"type": "error", "id": ..., "code": ..., "message": one line}``."""
    return {"type": "error", "id": message_id, "code": code, "message": " ".join(str(text).split())[:600]}
