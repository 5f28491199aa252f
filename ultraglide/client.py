"""A client of ``ultraglide serve``: place textures as sprites, send touches, watch what the plate renders.

One call per message of the protocol (``docs/service.md``), in two flavours: :class:`Client` (plain calls, for
a script or a PsychoPy experiment) and :class:`AsyncClient` (the same calls awaited, for asyncio programs).
A refusal is raised as a :class:`Refused` subclass named by its code (:class:`ReadOnly`, :class:`Unknown`, ...);
a connection that fails or is lost as :class:`ConnectionFailed`. Light: no numpy, no pygame.

Example::

    from ultraglide.client import Client

    with Client("ws://127.0.0.1:8765/ws") as plate:          # the first line `ultraglide serve` printed
        plate.set_view("main", 1920, 1080, units="px", width_mm=344, height_mm=194)
        plate.load_texture("wood", library="wood-grain")
        plate.place_sprite("panel", "wood", x=100, y=100, width=800, height=400)
        plate.touch(300, 300, "down")                          # in the view's units
        plate.touch(320, 300, "move")
        plate.touch(340, 300, "up")
        plate.move_sprite("panel", x=200, y=100)               # the friction follows the sprite
"""

from __future__ import annotations

import base64
import collections
import contextlib
import itertools
import json
import os
import threading
import time

from ultraglide.errors import UltraglideError

PROTOCOL_VERSION = 1
DEFAULT_TIMEOUT_S = 30.0
MAX_EVENTS = 4096  # pushes kept for events() (older ones are dropped), and messages the socket's reader holds: a
# program that reads them seldom still answers the service's pings (past 10 s unanswered, the service lets it go)


class ServiceError(UltraglideError):
    """Anything the service client raises.

    Examples
    --------
    Every error of the client is one, and an :class:`~ultraglide.UltraglideError`:

    >>> from ultraglide import UltraglideError
    >>> issubclass(Busy, ServiceError), issubclass(ConnectionFailed, ServiceError)
    (True, True)
    >>> issubclass(ServiceError, UltraglideError)
    True
    """


class ConnectionFailed(ServiceError, ConnectionError):
    """The service could not be reached, refused the handshake (origin, token), or the connection was lost.

    Examples
    --------
    Nothing listens on the port (one refused connection on this machine's loopback):

    >>> import socket
    >>> with socket.socket() as probe:
    ...     probe.bind(("127.0.0.1", 0)); port = probe.getsockname()[1]
    >>> try:
    ...     Client(f"ws://127.0.0.1:{port}", timeout_s=5.0)
    ... except ConnectionFailed as error:
    ...     print(type(error).__name__, isinstance(error, ConnectionError))
    ConnectionFailed True
    """


class Refused(ServiceError, ValueError):
    """The service refused a message: ``code`` (docs/service.md) and its one-line ``message``.

    Parameters
    ----------
    message : str
        What was refused and why, one line.
    code : str, optional
        The service's error code (docs/service.md); the class's own by default.

    Examples
    --------
    A code this client does not know is a plain Refused, its code kept:

    >>> error = refusal({"type": "error", "code": "new-code", "message": "refused for a new reason"})
    >>> type(error).__name__, error.code, str(error)
    ('Refused', 'new-code', 'refused for a new reason')
    """

    code = "refused"

    def __init__(self, message: str, code: str | None = None):
        super().__init__(message)
        if code is not None:
            self.code = code


class BadMessage(Refused):
    """A message that is not JSON, not an object, of an unknown type or field, or with a field missing,
    of the wrong type or out of range (``bad-message``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "bad-message", "message": "hello: unknown field 'colour'"})
    >>> isinstance(error, BadMessage), isinstance(error, Refused), error.code
    (True, True, 'bad-message')
    """

    code = "bad-message"


class TooBig(Refused):
    """A message over 64 KiB (all but ``texture.load``) (``too-big``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "too-big", "message": "message over 64 KiB"})
    >>> isinstance(error, TooBig), isinstance(error, Refused), error.code
    (True, True, 'too-big')
    """

    code = "too-big"


class RateLimited(Refused):
    """More than 2000 messages a second (``rate``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "rate", "message": "more than 2000 messages a second"})
    >>> isinstance(error, RateLimited), isinstance(error, Refused), error.code
    (True, True, 'rate')
    """

    code = "rate"


class NoHello(Refused):
    """A message before ``hello`` (``no-hello``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "no-hello", "message": "say hello first"})
    >>> isinstance(error, NoHello), isinstance(error, Refused), error.code
    (True, True, 'no-hello')
    """

    code = "no-hello"


class Busy(Refused):
    """Another client controls the plate.

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "busy", "message": "another client controls the plate"})
    >>> isinstance(error, Busy), isinstance(error, Refused), error.code
    (True, True, 'busy')
    """

    code = "busy"


class ReadOnly(Refused):
    """This client observes: it may not change anything.

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "read-only", "message": "an observer may not change anything"})
    >>> isinstance(error, ReadOnly), isinstance(error, Refused), error.code
    (True, True, 'read-only')
    """

    code = "read-only"


class Unknown(Refused):
    """No texture, view or sprite of that name.

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "unknown", "message": "no texture 'wood'"})
    >>> isinstance(error, Unknown), isinstance(error, Refused), error.code
    (True, True, 'unknown')
    """

    code = "unknown"


class TextureRefused(Refused):
    """The texture could not be loaded: the file, the image (``texture``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "texture", "message": "wood.png: not an image"})
    >>> isinstance(error, TextureRefused), isinstance(error, Refused), error.code
    (True, True, 'texture')
    """

    code = "texture"


class LimitReached(Refused):
    """Too many textures, sprites or views, or a texture of too many pixels (``limit``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "limit", "message": "at most 64 textures"})
    >>> isinstance(error, LimitReached), isinstance(error, Refused), error.code
    (True, True, 'limit')
    """

    code = "limit"


class EngineRefused(Refused):
    """The engine refused it, e.g. an effects description (``engine``).

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "engine", "message": "effects: unknown type 'saw'"})
    >>> isinstance(error, EngineRefused), isinstance(error, Refused), error.code
    (True, True, 'engine')
    """

    code = "engine"


ERRORS = {cls.code: cls for cls in (BadMessage, TooBig, RateLimited, NoHello, Busy, ReadOnly, Unknown,
                                    TextureRefused, LimitReached, EngineRefused)}


def refusal(reply: dict) -> Refused:
    """The exception for an ``error`` reply: the class of its code (docs/service.md), :class:`Refused` for an
    unknown one.

    Parameters
    ----------
    reply : dict
        The reply: its ``code`` and one-line ``message``.

    Returns
    -------
    Refused

    Examples
    --------
    >>> error = refusal({"type": "error", "code": "busy", "message": "another client controls"})
    >>> type(error).__name__, str(error), error.code
    ('Busy', 'another client controls', 'busy')
    """
    code = str(reply.get("code", "refused"))
    return ERRORS.get(code, Refused)(str(reply.get("message", "refused")), code)


def _png_field(png) -> str:
    if isinstance(png, bytes | bytearray):
        return base64.b64encode(bytes(png)).decode("ascii")
    with open(os.fspath(png), "rb") as stream:
        return base64.b64encode(stream.read()).decode("ascii")


def _encoded(message: dict) -> str:
    """The message as JSON text; a number that is not finite is refused here (JSON has none)."""
    try:
        return json.dumps(message, separators=(",", ":"), allow_nan=False)
    except ValueError:
        raise BadMessage(f"{message.get('type')}: every number must be finite", "bad-message") from None
    except TypeError as error:
        raise BadMessage(f"{message.get('type')}: {error}", "bad-message") from None


def _clean(**fields) -> dict:
    return {key: value for key, value in fields.items() if value is not None}


_PHASE_TEXT = {phase: f'"{phase}"' for phase in ("down", "move", "up", "cancel")}


def _number_text(value) -> str | None:
    """A plain finite float or int as ``json.dumps`` writes it (its ``repr``); None for anything else (a bool, a
    numpy number, NaN, an infinity), which the general encoder then handles or refuses."""
    kind = type(value)
    if kind is float:
        return float.__repr__(value) if value - value == 0.0 else None
    if kind is int:
        return int.__repr__(value)
    return None


def touch_text(x, y, phase: str, pointer, t, pressure=None, force_n=None) -> str | None:
    """The usual ``touch`` message as JSON text, character for character what the general encoder writes, in a
    fraction of its time; None when a field is not a plain finite number or a known phase (the general path then).

    A pointer event is the one message sent a thousand times a second, and on a machine where a program sleeps
    between events its code runs cold: ``json.dumps`` of a touch took 0.1 ms there, this 0.01 ms (``docs/
    performance.md``, the service's section).

    Parameters
    ----------
    x, y : float
        Where, in the view's units.
    phase : str
        ``down``, ``move``, ``up`` or ``cancel``.
    pointer : int
        The pointer's id.
    t : float
        When, the program's ``time.perf_counter()`` s.
    pressure, force_n : float, optional
        The pointer's pressure (0-1) and force (N).

    Returns
    -------
    str or None

    Examples
    --------
    >>> touch_text(20.5, 50, "move", 0, 12.25)
    '{"type":"touch","x":20.5,"y":50,"phase":"move","pointer":0,"t":12.25}'
    >>> import json
    >>> touch_text(1e-7, -0.0, "down", 3, 5.0, pressure=0.5) == json.dumps({"type": "touch", "x": 1e-7, "y": -0.0,
    ...     "phase": "down", "pointer": 3, "pressure": 0.5, "t": 5.0}, separators=(",", ":"))
    True
    >>> print(touch_text(float("nan"), 1.0, "move", 0, 1.0), touch_text(1.0, 1.0, "hover", 0, 1.0))
    None None
    """
    texts = [_number_text(x), _number_text(y), _PHASE_TEXT.get(phase), _number_text(pointer), _number_text(t)]
    if None in texts:
        return None
    middle = ""
    if pressure is not None:
        number = _number_text(pressure)
        if number is None:
            return None
        middle += ',"pressure":' + number
    if force_n is not None:
        number = _number_text(force_n)
        if number is None:
            return None
        middle += ',"force_n":' + number
    x_text, y_text, phase_text, pointer_text, t_text = texts
    return (f'{{"type":"touch","x":{x_text},"y":{y_text},"phase":{phase_text},"pointer":{pointer_text}{middle},'
            f'"t":{t_text}}}')


class _Messages:
    """The protocol's messages, one method each; ``_request`` (answered) and ``_post`` (not) send them."""

    def load_texture(self, texture: str, *, library: str | None = None, file: str | os.PathLike | None = None,
                     png: bytes | str | os.PathLike | None = None, width_mm: float | None = None,
                     height_mm: float | None = None, name: str | None = None, material: str | int | None = None):
        """Load a texture under the id ``texture``: a ``library`` name, a ``file`` on the server's machine, or
        ``png`` (bytes, or a local file sent as bytes); ``width_mm``/``height_mm`` size a plain image. Returns
        its description (id, name, size mm, pixels, notes)."""
        return self._request("texture.load", texture=texture, library=library,
                             file=None if file is None else os.fspath(file),
                             png=None if png is None else _png_field(png), width_mm=width_mm, height_mm=height_mm,
                             name=name, material=material)

    def load_material(self, texture: str, scene: str | os.PathLike, material: str | int | None = None, *,
                      width_mm: float | None = None, name: str | None = None):
        """Load a glTF scene's haptic material as the texture ``texture``.

        Parameters
        ----------
        texture : str
            The texture's id in the session.
        scene : str or path-like
            A ``.glb`` or ``.gltf`` file on the service's machine.
        material : str or int, optional
            The haptic material: its name, or its index in ``MPEG_haptic_material``; by default the first with a
            friction texture (as ``ultraglide texture import``).
        width_mm : float, optional
            The friction map's width, mm, where the scene does not say it (its height follows the UV mapping).
        name : str, optional
            The texture's name (default: the material's).

        Returns
        -------
        dict
            The reply: ``texture``, ``name``, ``width_mm``, ``height_mm``, ``cols``, ``rows``, ``notes``.

        Raises
        ------
        TextureRefused
            No such material, no friction texture, a size that cannot be known, a bad file (one line).

        Examples
        --------
        >>> plate.load_material("wood", "scene.glb", "oak")          # doctest: +SKIP
        """
        return self._request("texture.load", texture=texture, file=os.fspath(scene), material=material,
                             width_mm=width_mm, name=name)

    def unload_texture(self, texture: str):
        return self._request("texture.unload", texture=texture)

    def set_view(self, view: str, width: float, height: float, *, units: str = "px", width_mm: float | None = None,
                 height_mm: float | None = None, background_ratio: float | None = None):
        """Make or change a view: ``width`` × ``height`` in ``units`` (``px`` with the screen's size in mm, or
        ``mm``); ``background_ratio``: the friction ratio where no sprite is (1: bare glass)."""
        return self._request("view.set", view=view, width=width, height=height, units=units, width_mm=width_mm,
                             height_mm=height_mm, background_ratio=background_ratio)

    def remove_view(self, view: str):
        return self._request("view.remove", view=view)

    def place_sprite(self, sprite: str, texture: str, x: float, y: float, width: float, height: float, *,
                     view: str | None = None, rotation_deg: float | None = None, z: float | None = None,
                     visible: bool | None = None):
        """Place (or replace) a sprite: ``texture`` stretched over the rectangle (view's units, top-left corner,
        before rotation), rotated clockwise about its centre; the larger ``z`` on top."""
        return self._request("sprite.set", sprite=sprite, texture=texture, x=x, y=y, width=width, height=height,
                             view=view, rotation_deg=rotation_deg, z=z, visible=visible)

    def update_sprite(self, sprite: str, **fields):
        """Change some of a sprite's fields (texture, view, x, y, width, height, rotation_deg, z, visible)."""
        return self._request("sprite.set", sprite=sprite, **fields)

    def move_sprite(self, sprite: str, x: float, y: float):
        return self._request("sprite.set", sprite=sprite, x=x, y=y)

    def resize_sprite(self, sprite: str, width: float, height: float):
        return self._request("sprite.set", sprite=sprite, width=width, height=height)

    def rotate_sprite(self, sprite: str, rotation_deg: float):
        return self._request("sprite.set", sprite=sprite, rotation_deg=rotation_deg)

    def reorder_sprite(self, sprite: str, z: float):
        return self._request("sprite.set", sprite=sprite, z=z)

    def show_sprite(self, sprite: str, visible: bool = True):
        return self._request("sprite.set", sprite=sprite, visible=visible)

    def hide_sprite(self, sprite: str):
        return self._request("sprite.set", sprite=sprite, visible=False)

    def remove_sprite(self, sprite: str):
        return self._request("sprite.remove", sprite=sprite)

    def touch(self, x: float, y: float, phase: str = "move", *, pointer: int = 0, view: str | None = None,
              pressure: float | None = None, force_n: float | None = None, t: float | None = None,
              pointer_type: str | None = None):
        """A pointer event in the view's units: ``phase`` down, move, up or cancel; ``t`` this program's
        ``time.perf_counter()`` when it happened (default: now). Not answered (refusals come as errors later)."""
        return self._post("touch", x=x, y=y, phase=phase, pointer=pointer, view=view, pressure=pressure,
                          force_n=force_n, t=time.perf_counter() if t is None else t, pointer_type=pointer_type)

    def set_effects(self, effects: dict | None):
        """The temporal effects to play (``textures.effects.to_json``'s description; None: none)."""
        return self._request("effects.set", effects=effects)

    def trigger(self, name: str):
        """Play the effects bound to the event ``name``; the reply's ``played`` says whether any is."""
        return self._request("effect.trigger", name=name)

    def stop_effects(self):
        return self._request("effect.stop")

    def attach_effects(self, sprite: str, *, effect=None, effects: dict | None = None,
                       file: str | os.PathLike | None = None, release_s: float | None = None):
        """Effects that play while the finger is on ``sprite`` (where it is shown and uncovered) and stop when it
        leaves; replaces what was attached to it before.

        Parameters
        ----------
        sprite : str
            A sprite of the session.
        effect : dict or Effect, optional
            One effect (``textures.effects``: an ``Effect``, or its description as ``effect_to_dict`` gives).
        effects : dict, optional
            An effects description (``textures.effects.to_json``): every binding's effect plays on the sprite,
            its own trigger set aside.
        file : str or path-like, optional
            An effects file on the service's machine: ours (``.json``), or a designer's ``.ahap``, ``.haptic``,
            ``.hjif`` or ``.haps``.
        release_s : float, optional
            The fade when the finger leaves the sprite, s (default: each binding's own, 0.02 s for ``effect``).

        Returns
        -------
        dict
            The reply: ``sprite``, ``effects`` (how many), ``regions`` (the rectangles they play over in the view
            rendered), ``notes`` (what a designer's file loses, effects that could not be placed).

        Raises
        ------
        Unknown
            No such sprite.
        EngineRefused
            A bad effect or file (one line).
        LimitReached
            The sprite's shape needs more bindings than the engine has left.

        Examples
        --------
        >>> plate.attach_effects("button", effect={"type": "sine", "frequency_hz": 80, "depth": 0.3})  # doctest: +SKIP
        """
        if effect is not None and not isinstance(effect, dict):
            from ultraglide.textures.effects import effect_to_dict

            effect = effect_to_dict(effect)
        return self._request("effects.attach", sprite=sprite, effect=effect, effects=effects,
                             file=None if file is None else os.fspath(file), release_s=release_s)

    def detach_effects(self, sprite: str):
        """The effects attached to ``sprite`` no longer play (:class:`Unknown` if none are)."""
        return self._request("effects.detach", sprite=sprite)

    def set_drives(self, drives: str):
        """Which pointer the plate renders when two or more are down: ``first`` (the first down, until it lifts),
        ``latest`` (the newest down takes over; when it lifts, the newest still down) or ``none`` (with two down,
        none: the plate rests until one is left), as a rig's ``[touch] drives``."""
        return self._request("touches.set", drives=drives)

    def subscribe(self, *, status: float | bool | None = None, output: float | bool | None = None,
                  touch: bool | None = None, scene: bool | None = None):
        """Pushes to receive (:meth:`events`): ``status`` (True: 2 Hz, or a rate in Hz), ``output`` (the
        rendered friction and amplitude; True: 100 rows/s, or a rate), ``touch`` (the touch as the engine saw it),
        ``scene`` (the views, sprites and textures whenever they change)."""
        return self._request("subscribe", status=status, output=output, touch=touch, scene=scene)

    def state(self):
        """The views, sprites and textures as the service has them; ``scene_version`` counts the changes to the
        view the engine renders, ``rendered_version`` the last of them the engine renders now."""
        return self._request("state")


def _masking():
    """websockets' masking function and its OPEN state, or None where this version of websockets has not the same."""
    try:
        from websockets.protocol import OPEN
        try:
            from websockets.speedups import apply_mask
        except ImportError:
            from websockets.utils import apply_mask
    except ImportError:
        return None
    return apply_mask, OPEN


def _frame_parts(ws) -> tuple | None:
    """What :meth:`Client._write_text` needs of a websockets connection (its masking function, its OPEN state, its
    lock), or None where this version of websockets has not the same (the general path then)."""
    masking = _masking()
    mutex = getattr(ws, "protocol_mutex", None)
    if masking is None or mutex is None or not all(hasattr(ws, name)
                                                   for name in ("protocol", "socket", "send_in_progress")):
        return None
    return (*masking, mutex)


def _async_frame_parts(ws) -> tuple | None:
    """What :meth:`AsyncClient._write_text` needs of a websockets asyncio connection (its masking function, its
    OPEN state), or None where this version of websockets has not the same (its ``protocol``, ``transport``,
    ``send_in_progress`` and flow control's ``paused``: the general path then)."""
    masking = _masking()
    if masking is None or not all(hasattr(ws, name) for name in ("protocol", "transport", "send_in_progress",
                                                                  "paused")):
        return None
    return masking


class _Frames:
    """A client's own WebSocket frames for short texts (the short path of a touch)."""

    _masks = b""
    _mask_at = 0

    def _frame(self, text: str, apply_mask) -> bytes | None:
        """``text`` as one masked text frame (RFC 6455 5.2: a client's frames are masked, each with 4 bytes of its
        own from the OS's random source); None if it is longer than 125 bytes (its length takes more header bytes:
        the general path then)."""
        payload = text.encode()
        if len(payload) > 125:
            return None
        if self._mask_at + 4 > len(self._masks):
            self._masks, self._mask_at = os.urandom(4096), 0
        mask = self._masks[self._mask_at:self._mask_at + 4]
        self._mask_at += 4
        return bytes((0x81, 0x80 | len(payload))) + mask + apply_mask(payload, mask)  # FIN, text; masked, length


class Client(_Frames, _Messages):
    """A connection to ``ultraglide serve`` (see the module docstring). ``url``: ``ws://HOST:PORT/ws[?token=...]``
    as the server printed, or ``ws+unix:PATH``; ``role``: ``control`` (one client at a time) or ``observe``.
    Use from one thread; pushes arrive in :meth:`events`.

    Parameters
    ----------
    url : str
        ``ws://HOST:PORT/ws[?token=...]`` as the server printed, or ``ws+unix:PATH``.
    role : {"control", "observe"}
        ``control`` (one client at a time) or ``observe`` (read only).
    name : str
        How the service names this client.
    timeout_s : float
        How long (s) to wait for the connection and each answer.
    origin : str, optional
        The ``Origin`` header to send, for a server that checks it.

    Raises
    ------
    ConnectionFailed
        The service could not be reached or refused the handshake (origin, token).
    Refused
        The service refused the hello (:class:`Busy` when another client controls).

    Examples
    --------
    A script connects to the address ``ultraglide serve --device null --unix PATH`` prints. Here the same service
    runs in this process (its engine on the null device: no plate, no sound), on a Unix socket in a temporary
    folder:

    >>> import asyncio, pathlib, tempfile, threading
    >>> from websockets.asyncio.server import unix_serve
    >>> from ultraglide.apps.service.server import Service
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.engine import Engine, EngineConfig
    >>> folder = tempfile.TemporaryDirectory()
    >>> socket_path = str(pathlib.Path(folder.name) / "plate.sock")
    >>> service = Service(None, load_profile("sim-plate"))
    >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
    ...                                            realtime_priority=False))
    >>> service.engine.wait_ready(60)
    >>> listening, stop = threading.Event(), threading.Event()
    >>> async def serve():
    ...     async with unix_serve(service.handle, socket_path):
    ...         listening.set()
    ...         await asyncio.to_thread(stop.wait)
    >>> server = threading.Thread(target=asyncio.run, args=(serve(),))
    >>> server.start(); listening.wait(10)
    True

    The client: a 2 mm grating over the whole default view (160 × 100 mm), rendered, then a swipe across it:

    >>> with Client("ws+unix:" + socket_path) as plate:
    ...     _ = plate.load_texture("g", library="grating-2mm")
    ...     _ = plate.place_sprite("panel", "g", x=0, y=0, width=160, height=100)    # the view's units: mm
    ...     state = plate.wait_rendered()
    ...     plate.touch(40, 50, "down"); plate.touch(60, 50, "move"); plate.touch(60, 50, "up")
    >>> plate.welcome["role"], plate.welcome["device"]
    ('control', 'null')
    >>> state["rendered_version"] == state["scene_version"] == 1, [sprite["sprite"] for sprite in state["sprites"]]
    (True, ['panel'])

    Stopped as ``serve`` stops, the engine last:

    >>> stop.set(); server.join(10); service.worker.shutdown(); final = service.engine.stop(); folder.cleanup()
    >>> final.state, final.faults
    ('stopped', [])
    """

    def __init__(self, url: str, *, role: str = "control", name: str = "python", timeout_s: float = DEFAULT_TIMEOUT_S,
                 origin: str | None = None):
        from websockets.exceptions import InvalidHandshake, InvalidURI
        from websockets.sync.client import connect, unix_connect

        self.timeout_s = timeout_s
        self._ids = itertools.count(1)
        self.pending_events: collections.deque = collections.deque(maxlen=MAX_EVENTS)
        self.errors: collections.deque = collections.deque(maxlen=MAX_EVENTS)  # refusals of unanswered messages
        self._lock = threading.Lock()
        try:
            if url.startswith("ws+unix:"):
                self._ws = unix_connect(url[len("ws+unix:"):], open_timeout=timeout_s, max_size=None,
                                        compression=None, max_queue=MAX_EVENTS).__enter__()
            else:  # never through a proxy: the service is on this machine
                self._ws = connect(url, open_timeout=timeout_s, max_size=None, compression=None, origin=origin,
                                   proxy=None, max_queue=MAX_EVENTS).__enter__()
        except (OSError, InvalidHandshake, InvalidURI, TimeoutError) as error:
            raise ConnectionFailed(f"cannot connect to {url}: {error}") from None
        self._frame_parts = _frame_parts(self._ws)
        try:
            self.welcome = self._request("hello", protocol=PROTOCOL_VERSION, role=role, client=name)
        except BaseException:
            self._ws.close()
            raise

    def _send(self, message: dict) -> None:
        from websockets.exceptions import ConnectionClosed

        text = _encoded(message)
        try:
            self._ws.send(text)
        except (ConnectionClosed, OSError) as error:
            raise ConnectionFailed(f"the connection to the service was lost: {error}") from None

    def _post(self, kind: str, **fields) -> None:
        self._send({"type": kind, **_clean(**fields)})

    def touch(self, x: float, y: float, phase: str = "move", *, pointer: int = 0, view: str | None = None,
              pressure: float | None = None, force_n: float | None = None, t: float | None = None,
              pointer_type: str | None = None) -> None:
        """A pointer event, sent at once and not answered (a refusal comes later, in :attr:`errors`).

        The usual event (plain numbers, no ``view`` or ``pointer_type``) takes a short path: its JSON written by
        :func:`touch_text` and its WebSocket frame by this client, straight onto the socket under the connection's
        lock; anything else, or a connection that is not open, takes the general one (same bytes on the wire but
        the mask, same errors).

        Parameters
        ----------
        x, y : float
            Where, in the view's units.
        phase : {"down", "move", "up", "cancel"}
            The pointer's phase.
        pointer : int
            The pointer's id (several may be down at once).
        view : str, optional
            The view (default: the one the engine renders).
        pressure : float, optional
            The pointer's pressure, 0-1.
        force_n : float, optional
            The finger's force, N.
        t : float, optional
            When it happened, this program's ``time.perf_counter()`` s (default: now).
        pointer_type : str, optional
            ``touch``, ``pen`` or ``mouse``.

        Raises
        ------
        BadMessage
            A number that is not finite (nothing is sent).
        ConnectionFailed
            The connection was lost.

        Examples
        --------
        A service in this process, as ``ultraglide serve --device null --unix PATH`` runs one (see :class:`Client`):

        >>> import asyncio, pathlib, tempfile, threading
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))
        >>> listening, stop = threading.Event(), threading.Event()
        >>> async def serve():
        ...     async with unix_serve(service.handle, socket_path):
        ...         listening.set(); await asyncio.to_thread(stop.wait)
        >>> server = threading.Thread(target=asyncio.run, args=(serve(),)); server.start(); listening.wait(10)
        True

        A swipe in the view's units (mm here), then a request, answered once every message before it is taken:

        >>> with Client("ws+unix:" + socket_path) as plate:
        ...     plate.touch(40, 50, "down"); plate.touch(60, 50, "move", pressure=0.5); plate.touch(60, 50, "up")
        ...     _ = plate.state()
        >>> service.touches                                    # the three rendered, in their order
        3
        >>> stop.set(); server.join(10); service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        if t is None:
            t = time.perf_counter()
        if view is None and pointer_type is None and self._frame_parts is not None:
            text = touch_text(x, y, phase, pointer, t, pressure, force_n)
            if text is not None and self._write_text(text):
                return None
        return self._post("touch", x=x, y=y, phase=phase, pointer=pointer, view=view, pressure=pressure,
                          force_n=force_n, t=t, pointer_type=pointer_type)

    def _write_text(self, text: str) -> bool:
        """``text`` as one masked text frame (:meth:`_frame`), written onto the socket under the connection's lock,
        as websockets writes its own; False (nothing written) if the connection is not open or the message is
        long."""
        apply_mask, open_state, mutex = self._frame_parts
        frame = self._frame(text, apply_mask)
        if frame is None:
            return False
        ws = self._ws
        with mutex:
            if ws.protocol.state is not open_state or ws.send_in_progress:
                return False
            try:
                ws.socket.sendall(frame)
            except OSError:
                return False  # the general path meets the same failure and closes the connection as it should
        return True

    def _request(self, kind: str, **fields) -> dict:
        request_id = next(self._ids)
        self._send({"type": kind, "id": request_id, **_clean(**fields)})
        deadline = time.monotonic() + self.timeout_s
        while True:
            message = self._receive(deadline - time.monotonic())
            if message is None:
                raise ConnectionFailed(f"no answer to {kind} within {self.timeout_s:g} s")
            if message.get("id") == request_id and message.get("type") in ("ok", "error"):
                if message["type"] == "error":
                    raise refusal(message)
                return {k: v for k, v in message.items() if k not in ("id",)}
            self._keep(message)

    def _keep(self, message: dict) -> None:
        if message.get("type") == "error":
            self.errors.append(refusal(message))
        else:
            self.pending_events.append(message)

    def _receive(self, timeout_s: float) -> dict | None:
        from websockets.exceptions import ConnectionClosed

        try:
            text = self._ws.recv(timeout=max(0.0, timeout_s))
        except TimeoutError:
            return None
        except (ConnectionClosed, OSError) as error:
            raise ConnectionFailed(f"the connection to the service was lost: {error}") from None
        return json.loads(text)

    def wait_rendered(self, timeout_s: float = 10.0) -> dict:
        """Wait until the engine renders the scene as it is now (every change made so far); the state then.

        Parameters
        ----------
        timeout_s : float
            How long to wait, s.

        Returns
        -------
        dict
            The state (:meth:`state`), once ``rendered_version`` has reached ``scene_version``.

        Raises
        ------
        ConnectionFailed
            Not rendered within ``timeout_s``, or the connection lost.

        Examples
        --------
        A service in this process, as ``ultraglide serve --device null --unix PATH`` runs one (see :class:`Client`):

        >>> import asyncio, pathlib, tempfile, threading
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))
        >>> listening, stop = threading.Event(), threading.Event()
        >>> async def serve():
        ...     async with unix_serve(service.handle, socket_path):
        ...         listening.set(); await asyncio.to_thread(stop.wait)
        >>> server = threading.Thread(target=asyncio.run, args=(serve(),)); server.start(); listening.wait(10)
        True

        >>> with Client("ws+unix:" + socket_path) as plate:
        ...     _ = plate.load_texture("g", library="grating-2mm")
        ...     _ = plate.place_sprite("panel", "g", x=0, y=0, width=160, height=100)
        ...     state = plate.wait_rendered()
        >>> state["scene_version"], state["rendered_version"]              # one change, rendered
        (1, 1)
        >>> stop.set(); server.join(10); service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        deadline = time.monotonic() + timeout_s
        while True:
            state = self.state()
            if state["rendered_version"] >= state["scene_version"]:
                return state
            if time.monotonic() > deadline:
                raise ConnectionFailed(f"the scene was not rendered within {timeout_s:g} s")
            time.sleep(0.005)

    def events(self, timeout_s: float = 0.0):
        """Pushes received (status, output, touch.seen, notice), oldest first: those already here, then those
        arriving within ``timeout_s``.

        Parameters
        ----------
        timeout_s : float
            How long to wait for more, s (0: only those already here).

        Yields
        ------
        dict
            Each push, as the service sent it.

        Examples
        --------
        A service in this process, as ``ultraglide serve --device null --unix PATH`` runs one (see :class:`Client`):

        >>> import asyncio, pathlib, tempfile, threading
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))
        >>> listening, stop = threading.Event(), threading.Event()
        >>> async def serve():
        ...     async with unix_serve(service.handle, socket_path):
        ...         listening.set(); await asyncio.to_thread(stop.wait)
        >>> server = threading.Thread(target=asyncio.run, args=(serve(),)); server.start(); listening.wait(10)
        True

        >>> with Client("ws+unix:" + socket_path) as plate:
        ...     _ = plate.subscribe(scene=True)
        ...     _ = plate.load_texture("g", library="grating-2mm")
        ...     _ = plate.place_sprite("panel", "g", x=0, y=0, width=160, height=100)
        ...     scenes = (event for event in plate.events(timeout_s=10.0) if event["type"] == "scene")
        ...     placed = next(scene for scene in scenes if scene["sprites"])      # pushed as the scene changed
        >>> [sprite["sprite"] for sprite in placed["sprites"]], [texture["texture"] for texture in placed["textures"]]
        (['panel'], ['g'])
        >>> stop.set(); server.join(10); service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        deadline = time.monotonic() + timeout_s
        while True:
            while self.pending_events:
                yield self.pending_events.popleft()
            left = deadline - time.monotonic()
            if left <= 0:
                message = self._receive(0.0)
                if message is None:
                    return
            else:
                message = self._receive(left)
                if message is None:
                    return
            self._keep(message)

    def close(self) -> None:
        """Close the connection (a finger still down is lifted by the service).

        Examples
        --------
        A service in this process, as ``ultraglide serve --device null --unix PATH`` runs one (see :class:`Client`):

        >>> import asyncio, pathlib, tempfile, threading
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))
        >>> listening, stop = threading.Event(), threading.Event()
        >>> async def serve():
        ...     async with unix_serve(service.handle, socket_path):
        ...         listening.set(); await asyncio.to_thread(stop.wait)
        >>> server = threading.Thread(target=asyncio.run, args=(serve(),)); server.start(); listening.wait(10)
        True

        >>> plate = Client("ws+unix:" + socket_path)
        >>> plate.close()
        >>> plate.state()
        Traceback (most recent call last):
        ...
        ultraglide.client.ConnectionFailed: the connection to the service was lost: ...
        >>> stop.set(); server.join(10); service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        self._ws.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class AsyncClient(_Frames, _Messages):
    """:class:`Client` for asyncio: ``client = await AsyncClient.connect(url)``; every call is awaited but
    :meth:`touch`, which sends at once and returns None. Pushes come through :meth:`next_event`.

    Examples
    --------
    A program connects to the address ``ultraglide serve --device null --unix PATH`` prints. Here the same service
    runs in this process, in the program's own event loop (its engine on the null device: no plate, no sound):

    >>> import asyncio, pathlib, tempfile
    >>> from websockets.asyncio.server import unix_serve
    >>> from ultraglide.apps.service.server import Service
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.engine import Engine, EngineConfig
    >>> folder = tempfile.TemporaryDirectory()
    >>> socket_path = str(pathlib.Path(folder.name) / "plate.sock")
    >>> service = Service(None, load_profile("sim-plate"))
    >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
    ...                                            realtime_priority=False))
    >>> service.engine.wait_ready(60)
    >>> async def session():
    ...     async with unix_serve(service.handle, socket_path):
    ...         async with await AsyncClient.connect("ws+unix:" + socket_path) as plate:
    ...             await plate.load_texture("g", library="grating-2mm")
    ...             await plate.place_sprite("panel", "g", x=0, y=0, width=160, height=100)    # mm
    ...             plate.touch(40, 50, "down")                                             # sent, not awaited
    ...             return plate.welcome, await plate.wait_rendered()
    >>> welcome, state = asyncio.run(session())
    >>> welcome["role"], welcome["scene_version"], state["scene_version"], state["rendered_version"]
    ('control', 0, 1, 1)
    >>> service.worker.shutdown(); final = service.engine.stop(); folder.cleanup()
    >>> final.state, final.faults
    ('stopped', [])
    """

    def __init__(self):
        self._ws = None
        self._ids = itertools.count(1)
        self._waiting: dict = {}
        self._events = None
        self.errors: collections.deque = collections.deque(maxlen=MAX_EVENTS)
        self._reader = None
        self.welcome: dict = {}
        self.timeout_s = DEFAULT_TIMEOUT_S
        self._frame_parts = None  # (the short path's: _async_frame_parts)
        self._posting = 0  # messages handed to a task of the general path and not yet written
        self._last_post = None  # the last of those tasks

    @classmethod
    async def connect(cls, url: str, *, role: str = "control", name: str = "python-asyncio",
                      timeout_s: float = DEFAULT_TIMEOUT_S, origin: str | None = None) -> AsyncClient:
        """Connect to ``ultraglide serve`` and say hello; the connected client.

        Parameters
        ----------
        url : str
            ``ws://HOST:PORT/ws[?token=...]`` as the server printed, or ``ws+unix:PATH``.
        role : {"control", "observe"}
            ``control`` (one client at a time) or ``observe`` (read only).
        name : str
            How the service names this client.
        timeout_s : float
            How long (s) to wait for the connection and each answer.
        origin : str, optional
            The ``Origin`` header to send, for a server that checks it.

        Returns
        -------
        AsyncClient

        Raises
        ------
        ConnectionFailed
            The service could not be reached or refused the handshake (origin, token).
        Refused
            The service refused the hello (``busy`` when another client controls).

        Examples
        --------
        A service in this process, in the program's own event loop, as ``ultraglide serve --device null --unix PATH``
        runs one (see :class:`AsyncClient`):

        >>> import asyncio, pathlib, tempfile
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))

        >>> async def hello():
        ...     async with unix_serve(service.handle, socket_path):
        ...         async with await AsyncClient.connect("ws+unix:" + socket_path, role="observe") as plate:
        ...             return plate.welcome
        >>> welcome = asyncio.run(hello())
        >>> welcome["role"], welcome["device"], welcome["profile"]
        ('observe', 'null', 'sim-plate')
        >>> service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        import asyncio

        from websockets.asyncio.client import connect, unix_connect
        from websockets.exceptions import InvalidHandshake, InvalidURI

        self = cls()
        self.timeout_s = timeout_s
        self._events = asyncio.Queue(maxsize=MAX_EVENTS)
        try:
            if url.startswith("ws+unix:"):
                self._ws = await unix_connect(url[len("ws+unix:"):], open_timeout=timeout_s, max_size=None,
                                              compression=None)
            else:
                self._ws = await connect(url, open_timeout=timeout_s, max_size=None, compression=None, origin=origin,
                                         proxy=None)
        except (OSError, InvalidHandshake, InvalidURI, TimeoutError) as error:
            raise ConnectionFailed(f"cannot connect to {url}: {error}") from None
        self._frame_parts = _async_frame_parts(self._ws)
        self._reader = asyncio.ensure_future(self._read())
        try:
            self.welcome = await self._request("hello", protocol=PROTOCOL_VERSION, role=role, client=name)
        except BaseException:
            await self.close()
            raise
        return self

    async def _read(self) -> None:
        import asyncio

        try:
            async for text in self._ws:
                message = json.loads(text)
                future = self._waiting.pop(message.get("id"), None) if message.get("type") in ("ok", "error") \
                    else None
                if future is not None and not future.done():
                    future.set_result(message)
                elif message.get("type") == "error":
                    self.errors.append(refusal(message))
                else:
                    if self._events.full():
                        self._events.get_nowait()
                    self._events.put_nowait(message)
        except Exception:  # noqa: BLE001 - the connection ended: every waiting call learns it below
            pass
        finally:
            for future in self._waiting.values():
                if not future.done():
                    future.set_exception(ConnectionFailed("the connection to the service was lost"))
            self._waiting.clear()
            with __import__("contextlib").suppress(asyncio.QueueFull):
                self._events.put_nowait(None)

    def touch(self, x: float, y: float, phase: str = "move", *, pointer: int = 0, view: str | None = None,
              pressure: float | None = None, force_n: float | None = None, t: float | None = None,
              pointer_type: str | None = None) -> None:
        """A pointer event, on its way when the call returns (not awaited, not answered: a refusal comes later,
        in :attr:`errors`).

        The usual event (plain numbers, no ``view`` or ``pointer_type``) takes a short path, as
        :meth:`Client.touch`'s: its JSON written by :func:`touch_text` and its WebSocket frame by this client,
        straight into the connection's transport. Anything else, a connection that is not open or whose writes
        are held back (its transport's buffer full: websockets' flow control), or a touch behind one still
        waiting on those, takes the general path: a task that sends it with websockets' ``send``, in order. (A
        request not yet awaited is not yet sent: a touch made after it goes first.)

        Parameters
        ----------
        x, y : float
            Where, in the view's units.
        phase : {"down", "move", "up", "cancel"}
            The pointer's phase.
        pointer : int
            The pointer's id (several may be down at once).
        view : str, optional
            The view (default: the one the engine renders).
        pressure : float, optional
            The pointer's pressure, 0-1.
        force_n : float, optional
            The finger's force, N.
        t : float, optional
            When it happened, this program's ``time.perf_counter()`` s (default: now).
        pointer_type : str, optional
            ``touch``, ``pen`` or ``mouse``.

        Raises
        ------
        BadMessage
            A number that is not finite (nothing is sent).
        ConnectionFailed
            The connection has ended.

        Examples
        --------
        A service in this process, in the program's own event loop, as ``ultraglide serve --device null --unix PATH``
        runs one (see :class:`AsyncClient`):

        >>> import asyncio, pathlib, tempfile
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))

        A swipe in the view's units (mm here), then a request, answered once every message before it is taken:

        >>> async def swipe():
        ...     async with unix_serve(service.handle, socket_path):
        ...         async with await AsyncClient.connect("ws+unix:" + socket_path) as plate:
        ...             plate.touch(40, 50, "down"); plate.touch(60, 50, "move", pressure=0.5)
        ...             plate.touch(60, 50, "up")
        ...             await plate.state()
        >>> asyncio.run(swipe())
        >>> service.touches                                    # the three rendered, in their order
        3
        >>> service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        if t is None:
            t = time.perf_counter()
        if view is None and pointer_type is None and self._frame_parts is not None and not self._posting:
            text = touch_text(x, y, phase, pointer, t, pressure, force_n)
            if text is not None and self._write_text(text):
                return None
        return self._post("touch", x=x, y=y, phase=phase, pointer=pointer, view=view, pressure=pressure,
                          force_n=force_n, t=t, pointer_type=pointer_type)

    def _write_text(self, text: str) -> bool:
        """``text`` as one masked text frame (:meth:`_frame`), written into the connection's transport, as
        websockets writes its own (the loop is this thread: nothing of websockets' runs in between); False
        (nothing written) if the connection is not open, a fragmented message is being sent, its writes are held
        back (flow control), or the message is long."""
        apply_mask, open_state = self._frame_parts
        ws = self._ws
        if ws.protocol.state is not open_state or ws.send_in_progress is not None or ws.paused \
                or ws.transport.is_closing():
            return False
        frame = self._frame(text, apply_mask)
        if frame is None:
            return False
        ws.transport.write(frame)
        return True

    def _post(self, kind: str, **fields) -> None:
        import asyncio

        message = {"type": kind, **_clean(**fields)}
        _encoded(message)  # refused here, not in a task nobody awaits
        if self._reader is not None and self._reader.done():
            raise ConnectionFailed("the connection to the service was lost")
        self._posting += 1
        self._last_post = asyncio.ensure_future(self._send(message))
        self._last_post.add_done_callback(self._posted)

    def _posted(self, task) -> None:
        """A message of :meth:`_post` written (or not: the connection ended, which the reader learns and the next
        call says)."""
        self._posting -= 1
        if not task.cancelled():
            task.exception()  # retrieved: a send that failed is the connection's end, not an error left unseen

    async def _send(self, message: dict) -> None:
        from websockets.exceptions import ConnectionClosed

        text = _encoded(message)
        try:
            await self._ws.send(text)
        except (ConnectionClosed, OSError) as error:
            raise ConnectionFailed(f"the connection to the service was lost: {error}") from None

    async def _request(self, kind: str, **fields) -> dict:
        import asyncio

        request_id = next(self._ids)
        future = asyncio.get_running_loop().create_future()
        self._waiting[request_id] = future
        last = self._last_post
        if self._posting and not last.done():  # touches made before it and handed to tasks go first: once the last
            with contextlib.suppress(Exception):  # has been sent, every one before it has been written
                await asyncio.shield(last)
        await self._send({"type": kind, "id": request_id, **_clean(**fields)})
        try:
            message = await asyncio.wait_for(future, self.timeout_s)
        except TimeoutError:
            self._waiting.pop(request_id, None)
            raise ConnectionFailed(f"no answer to {kind} within {self.timeout_s:g} s") from None
        if message["type"] == "error":
            raise refusal(message)
        return {k: v for k, v in message.items() if k != "id"}

    async def wait_rendered(self, timeout_s: float = 10.0) -> dict:
        """Wait until the engine renders the scene as it is now (every change made so far); the state then.

        Parameters
        ----------
        timeout_s : float
            How long to wait, s.

        Returns
        -------
        dict
            The state, once ``rendered_version`` has reached ``scene_version``.

        Raises
        ------
        ConnectionFailed
            Not rendered within ``timeout_s``, or the connection lost.

        Examples
        --------
        A service in this process, in the program's own event loop, as ``ultraglide serve --device null --unix PATH``
        runs one (see :class:`AsyncClient`):

        >>> import asyncio, pathlib, tempfile
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))

        >>> async def session():
        ...     async with unix_serve(service.handle, socket_path):
        ...         async with await AsyncClient.connect("ws+unix:" + socket_path) as plate:
        ...             await plate.load_texture("g", library="grating-2mm")
        ...             await plate.place_sprite("panel", "g", x=0, y=0, width=160, height=100)
        ...             return await plate.wait_rendered()
        >>> state = asyncio.run(session())
        >>> state["scene_version"], state["rendered_version"]
        (1, 1)
        >>> service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        import asyncio

        deadline = time.monotonic() + timeout_s
        while True:
            state = await self.state()
            if state["rendered_version"] >= state["scene_version"]:
                return state
            if time.monotonic() > deadline:
                raise ConnectionFailed(f"the scene was not rendered within {timeout_s:g} s")
            await asyncio.sleep(0.005)

    async def next_event(self, timeout_s: float | None = None) -> dict | None:
        """The next push (status, output, touch.seen, notice); None once the connection has ended or after
        ``timeout_s``.

        Parameters
        ----------
        timeout_s : float, optional
            How long to wait, s (None: until one comes or the connection ends).

        Returns
        -------
        dict or None

        Examples
        --------
        A service in this process, in the program's own event loop, as ``ultraglide serve --device null --unix PATH``
        runs one (see :class:`AsyncClient`):

        >>> import asyncio, pathlib, tempfile
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))

        >>> async def session():
        ...     async with unix_serve(service.handle, socket_path):
        ...         async with await AsyncClient.connect("ws+unix:" + socket_path) as plate:
        ...             await plate.subscribe(scene=True)
        ...             await plate.load_texture("g", library="grating-2mm")
        ...             return await plate.next_event(timeout_s=10.0)
        >>> event = asyncio.run(session())
        >>> event["type"], [texture["texture"] for texture in event["textures"]]
        ('scene', ['g'])
        >>> service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        import asyncio

        try:
            return await asyncio.wait_for(self._events.get(), timeout_s)
        except TimeoutError:
            return None

    async def close(self) -> None:
        """Close the connection and wait for the reader to end (a finger still down is lifted by the service).

        Examples
        --------
        A service in this process, in the program's own event loop, as ``ultraglide serve --device null --unix PATH``
        runs one (see :class:`AsyncClient`):

        >>> import asyncio, pathlib, tempfile
        >>> from websockets.asyncio.server import unix_serve
        >>> from ultraglide.apps.service.server import Service
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> folder = tempfile.TemporaryDirectory(); socket_path = str(pathlib.Path(folder.name) / "plate.sock")
        >>> service = Service(None, load_profile("sim-plate"))
        >>> service.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="null",
        ...                                            realtime_priority=False))

        >>> async def session():
        ...     async with unix_serve(service.handle, socket_path):
        ...         plate = await AsyncClient.connect("ws+unix:" + socket_path)
        ...         await plate.close()
        ...         return await plate.next_event(timeout_s=10.0)          # None: the connection has ended
        >>> print(asyncio.run(session()))
        None
        >>> service.worker.shutdown(); _ = service.engine.stop(); folder.cleanup()
        """
        if self._ws is not None:
            await self._ws.close()
        if self._reader is not None:
            await self._reader

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()
