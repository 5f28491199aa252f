"""The service: a local WebSocket server in front of the real-time engine (``ultraglide serve``).

One asyncio loop, on the command's main thread, serves every client; the engine runs in its own process
(:mod:`render.engine`) and is reached through its two doors: touches go into its shared-memory ring from the
loop itself (never waits), everything else (a view's composed texture, effects, a trigger) over its pipe from
one worker thread, so a texture being composed or sent never holds up the touches. The protocol is
:mod:`apps.service.protocol`'s; ``docs/service.md`` describes it.

Safety and security, where each lives:

* the handshake (:meth:`Service.process_request`): a path other than ``/ws`` (or the page's, with ``--page``)
  is 404; a wrong or missing token, where one is needed, 401; a browser's ``Origin`` other than the served
  page's is 403 (``origins`` of :func:`websockets.asyncio.server.serve`): a page elsewhere cannot drive the
  plate through ``localhost``;
* each message: its size (the socket closes on more than :data:`protocol.MAX_MESSAGE_BYTES`; messages but a
  texture's more than 64 KiB are refused), its rate (a token bucket per client), its fields (typed, ranged);
  every refusal is one ``error`` reply and the engine never sees the message;
* one controlling client; the others observe (read-only);
* a client that goes (its socket closed, even by SIGKILL) while its finger is down lifts it at once: the
  engine ramps the plate to rest;
* a client that does not read its replies or its subscriptions: its queue is bounded; subscriptions are
  dropped (counted) and a client that lets :data:`MAX_QUEUED_REPLIES` replies pile up has its socket dropped;
* the plate's limit is the engine's (the limiter in its output stage): nothing a client sends reaches past it.
"""

from __future__ import annotations

import asyncio
import base64
import collections
import contextlib
import json
import math
import os
import secrets
import struct
import tempfile
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from urllib.parse import parse_qs, urlsplit

from ultraglide.apps.service import protocol as p
from ultraglide.apps.service.scene import MAX_SIDE_PX, Sprite, View, compose_view, sprite_at, sprite_regions

from ultraglide import __version__
from ultraglide.errors import UltraglideError, describe

RATE_PER_S = 2000.0  # messages a client may send a second, sustained (a pointer at 1000 Hz and more)
RATE_BURST = 2000.0
MAX_QUEUED_REPLIES = 256  # replies waiting for a client that does not read: past this it is disconnected
MAX_QUEUED_PUSHES = 64  # subscription messages waiting: older ones are dropped
MAX_CLIENTS = 16
MAX_TEXTURES = 32
MAX_SPRITES = 256
MAX_VIEWS = 16
MAX_POINTERS = 10  # pointers down at once that are followed (a hand's)
MAX_TEXTURE_PIXELS = 4_000_000
PRESSURE_FULL_SCALE_N = 1.0  # a pointer's pressure 1 is this force, unless the rig says (a mouse's: none, the default)
MIN_PRESSED_FORCE_N = 0.05  # the least force a pressed pointer gives
DEFAULT_VIEW = "main"
DEFAULT_VIEW_MM = (160.0, 100.0)
HTML = "text/html; charset=utf-8"
PAGE_FILES = {"/": ("index.html", HTML), "/index.html": ("index.html", HTML),
              "/ultraglide.js": ("ultraglide.js", "text/javascript; charset=utf-8"),
              "/page.js": ("page.js", "text/javascript; charset=utf-8")}
LOOPBACK_HOSTS = ("127.0.0.1", "::1", "localhost")
SCENE_TYPES = frozenset({"texture.unload", "view.set", "view.remove", "sprite.set", "sprite.remove"})


class ServiceError(UltraglideError, RuntimeError):
    """The service could not start (an address in use, a bad option); one line."""


_SHORT_PATH = None


def short_path_connection():
    """websockets' ``ServerConnection`` (for ``serve(..., create_connection=...)``) whose text messages go to the
    service as websockets reads them, when none waits before them, rather than through its queue and the connection
    handler's task one turn of the loop later.

    That turn released the interpreter (the loop's ``select``) to any thread of the service waiting for it, and cost
    a cold run through websockets' queue and the task's wake-up: on a loaded machine the time from websockets' read
    to the handler's was 0.18 ms at p50 and 1.5-20 ms at p99 (``docs/performance.md``, the service's section). Every
    message takes the same checks (:meth:`Service._receive`: the rate, the size, the fields, the role); a message
    behind another still queued, a fragmented one, or one on a connection closing takes websockets' own path, so
    their order is kept.

    Returns
    -------
    type
        The connection class (one, made at the first call).

    Examples
    --------
    >>> from websockets.asyncio.server import ServerConnection
    >>> issubclass(short_path_connection(), ServerConnection), short_path_connection() is short_path_connection()
    (True, True)
    """
    global _SHORT_PATH
    if _SHORT_PATH is None:
        from websockets.asyncio.server import ServerConnection
        from websockets.frames import Opcode

        class ShortPathConnection(ServerConnection):
            on_text = None  # set by Service.handle: (text, received_s) -> whether it was taken

            def process_event(self, event) -> None:
                on_text = self.on_text
                if on_text is not None and event.opcode is Opcode.TEXT and event.fin:
                    waiting = getattr(self.recv_messages, "frames", None)
                    if waiting is not None and not len(waiting):
                        received_s = time.perf_counter()
                        try:
                            text = str(event.data, "utf-8")
                        except UnicodeDecodeError:
                            text = None  # websockets refuses it, as ever
                        if text is not None and on_text(text, received_s):
                            return
                super().process_event(event)

        _SHORT_PATH = ShortPathConnection
    return _SHORT_PATH


def needs_token(host: str | None) -> bool:
    """Whether a server bound to ``host`` asks for a token: every address but the usual loopback ones (even
    another loopback address such as 127.0.0.2: caution costs nothing); a Unix socket (None) never."""
    return host is not None and host not in LOOPBACK_HOSTS


@dataclass(eq=False)
class Finger:
    """A pointer down: whose, its id, on which view, where it was last (mm), its force (N, or None: the default).
    The one that drives is the finger the engine renders."""

    session: Session
    pointer: int
    view: str
    x_mm: float
    y_mm: float
    force_n: float | None


@dataclass(eq=False)
class Session:
    """One client's connection: its role, its clock's offset, its rate bucket, what it subscribed to."""

    connection: object
    number: int
    role: str | None = None  # None until its hello
    client: str = ""
    clock_offset_s: float | None = None  # our perf_counter minus its clock, the least seen (the quickest delivery)
    tokens: float = RATE_BURST  # the bucket refilled by the client's own pace (Session.allow)
    read_tokens: float = RATE_BURST  # the bucket refilled by the time its messages are read
    bucket_s: float = field(default_factory=time.perf_counter)  # the bucket is refilled up to this time (ours)
    read_s: float = field(default_factory=time.perf_counter)  # when its last message was read
    client_s: float | None = None  # the last message's own time (its ``t``, its clock), None before one came
    client_bucket_s: float = 0.0  # bucket_s at that message
    rate_refusals: int = 0
    touch_refusals: int = 0
    status_hz: float = 0.0
    output_hz: float = 0.0
    touch_seen: bool = False
    scene: bool = False  # pushed the views, sprites and textures whenever they change
    next_status_s: float = 0.0
    next_output_s: float = 0.0  # when its output rows are next read
    output_from_s: float = 0.0  # the last block looked at
    output_kept_s: float = -math.inf  # the last block sent
    last_seen: tuple | None = None  # the touch as last pushed
    queue: collections.deque = field(default_factory=collections.deque)
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    replies_queued: int = 0
    pushes_dropped: int = 0
    closing: bool = False

    def engine_time(self, client_t: float | None, received_s: float) -> float:
        """The client's timestamp on our clock: shifted by the least offset seen so far (a clock's constant
        offset cancels; a slow delivery does not pull it later); never after the message arrived."""
        if client_t is None:
            return received_s
        offset = received_s - client_t
        if self.clock_offset_s is None or offset < self.clock_offset_s:
            self.clock_offset_s = offset
        return min(client_t + self.clock_offset_s, received_s)

    def may_send(self, received_s: float, short: bool) -> bool:
        """Whether a message read at ``received_s`` could be given a token (:meth:`allow`) at all: one that could
        not is refused unparsed, so a flood costs no parsing. ``short``: it could be a touch (whose own time may
        refill the bucket up to the read time)."""
        return (self.read_tokens + (received_s - self.read_s) * RATE_PER_S >= 1.0
                or self.tokens + (received_s - (self.read_s if not short else self.bucket_s)) * RATE_PER_S >= 1.0)

    def allow(self, received_s: float, client_t: float | None = None) -> bool:
        """A token for a message read at ``received_s`` (``perf_counter`` s), if its client is within its rate.

        Two buckets of :data:`RATE_BURST` tokens, :data:`RATE_PER_S` a second, every message taken spending one
        of each; a message is refused when both are empty. One is refilled by the time the messages are read
        (the rate as read). The other by the time that passed *at the client* between them, by its own clock
        (``client_t``: a touch's ``t``, since its last touch that had one; else the time between reads), never
        beyond the time they were read and never back: the rate as sent. A steady 1000 touches a second is not
        refused when the service, late (descheduled, stalled), reads seconds of them in one burst: as read that
        is a flood, as sent it is not. A flood still is one: the time each bucket is refilled by never passes the
        read time, so whatever times a client claims, it is given at most :data:`RATE_BURST` and
        :data:`RATE_PER_S` a second of reading; and a client whose own times are closer than 1/:data:`RATE_PER_S`,
        or that gives none, is refused past the burst whenever its messages are also read faster than that (read
        slower, they are all taken: no more than the rate passes either way).

        Parameters
        ----------
        received_s : float
            When the message was read, ``perf_counter`` s.
        client_t : float, optional
            Its own time (the client's clock, s), if it has one.

        Returns
        -------
        bool
            Whether it may be taken (a token of each bucket spent).

        Examples
        --------
        A client connects at 0 s; the service reads nothing of it until 5 s, then 4000 touches it sent 1 ms apart
        (each stamped with its ``t``): all are taken. 6000 sent 0.3 ms apart (3333 a second), read the same way,
        are taken while the burst and the 1.8 s they span last, at most 2000 + 1.8 s × 2000 = 5600:

        >>> steady = Session(None, 1, bucket_s=0.0, read_s=0.0)
        >>> sum(steady.allow(5.0, 1.0 + 0.001 * k) for k in range(4000))
        4000
        >>> flood = Session(None, 2, bucket_s=0.0, read_s=0.0)
        >>> sum(flood.allow(5.0, 1.0 + 0.0003 * k) for k in range(6000))
        5599

        Times a client claims do not refill it faster than it is read: 6000 touches claiming to be a second
        apart, all read within 1 ms of its connecting, get the burst and what that millisecond refills:

        >>> liar = Session(None, 3, bucket_s=0.0, read_s=0.0)
        >>> sum(liar.allow(1e-3 * k / 6000, float(k)) for k in range(6000))
        2001
        """
        self.read_tokens = min(RATE_BURST, self.read_tokens + (received_s - self.read_s) * RATE_PER_S)
        if client_t is None:
            sent_s = self.bucket_s + (received_s - self.read_s)  # no time of its own: the pace it is read at
        elif self.client_s is None:
            sent_s = self.bucket_s  # its first time: nothing to pace it by yet
        else:
            sent_s = self.client_bucket_s + (client_t - self.client_s)  # its own pace since its last time
        sent_s = min(max(sent_s, self.bucket_s), received_s)
        self.tokens = min(RATE_BURST, self.tokens + (sent_s - self.bucket_s) * RATE_PER_S)
        self.bucket_s, self.read_s = sent_s, received_s
        if client_t is not None:
            self.client_s, self.client_bucket_s = client_t, sent_s
        if self.tokens < 1.0 and self.read_tokens < 1.0:
            return False
        self.tokens -= 1.0
        self.read_tokens -= 1.0
        return True

    def send(self, message: dict, push: bool = False) -> None:
        """Queue a message for this client's sender; pushes beyond the bound drop the oldest push."""
        if self.closing:
            return
        if push:
            pushes = sum(1 for kind, _ in self.queue if kind)
            if pushes >= MAX_QUEUED_PUSHES:
                for index, (kind, _) in enumerate(self.queue):
                    if kind:
                        del self.queue[index]
                        self.pushes_dropped += 1
                        break
        else:
            self.replies_queued += 1
        self.queue.append((push, message))
        self.wake.set()


class Service:
    """The server's state and its handlers. ``engine``: a started :class:`render.engine.Engine`; ``profile``: the
    plate's; ``token``: what clients must give (None: no token); ``page``: serve the page and its module;
    ``pressure_full_scale_n``: the force a client's pressure 1.0 stands for (a rig's ``[touch]``)."""

    def __init__(self, engine, profile, *, token: str | None = None, page: bool = False,
                 view_mm: tuple[float, float] = DEFAULT_VIEW_MM, drives: str = "first",
                 pressure_full_scale_n: float = PRESSURE_FULL_SCALE_N):
        self.engine = engine
        self.pressure_full_scale_n = pressure_full_scale_n  # a client's pressure 1 (a rig's [touch] scale, N)
        self.profile = profile
        self.token = token
        self.page = page
        self.textures: dict = {}
        self.views: dict[str, View] = {DEFAULT_VIEW: View(DEFAULT_VIEW, view_mm[0], view_mm[1], "mm", *view_mm)}
        self.sprites: dict[str, Sprite] = {}
        self.samplers: dict = {}
        self.active_view = DEFAULT_VIEW
        self.controller: Session | None = None
        self.sessions: set[Session] = set()
        self.finger: Finger | None = None  # the pointer the engine renders
        self.pointers: dict[int, Finger] = {}  # every pointer down, by id, in the order they came down
        self.drives = drives  # which pointer drives when two are down: first, latest or none
        self.effects = None  # the session's effects description (None: none)
        self.attached: dict[str, tuple] = {}  # sprite -> the bindings whose effects play while the finger is on it
        self._effects_sent: object = None  # the description the engine plays (the worker's)
        self._regions_sent: dict[str, int] = {}  # sprite -> how many rectangles its effects play over
        self.worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ultraglide-service")
        self._numbers = 0
        self._order = 0
        self._scene_version = 0
        self._composed_version = -1
        self._composing: asyncio.Task | None = None
        self._scene_push_due = False
        self.touches = 0
        self.touches_ignored = 0
        self.messages_read = 0  # every client's messages read (taken or refused)
        self.rate_refusals = 0  # of them, refused by their client's rate
        self.status_reads = 0  # the engine's status read by the publisher (for its subscribers)
        self.publisher_wake = threading.Event()  # a subscription changed: the publisher looks again at once
        self.origins: list = [None]
        self.priority = "normal"  # the loop thread's scheduling, in words
        self.arrivals: list | None = None  # a list to note each touch's times in (a bench's), or None
        self.page_files = PAGE_FILES  # the page's files (path -> (file, content type)) in ``page_package``
        self.page_package = "ultraglide.apps.service.page"
        self.extra_specs: dict | None = None  # message types of a service built on this one (protocol.parse's extra)
        self.touch_panel: str | None = None  # the panel the engine reads itself (serve --touch-panel): clients' touches
        # are refused

    # ---- start-up --------------------------------------------------------------------------------------
    def place_startup_textures(self, specs: list[str]) -> None:
        """The textures named on the command line, loaded and placed side by side filling the default view
        (each a column of equal width); the view's first composition is the engine's first texture."""
        view = self.views[DEFAULT_VIEW]
        for index, spec in enumerate(specs):
            texture_id = f"t{index + 1}"
            self.textures[texture_id] = _load_named(spec)
            width = view.width / len(specs)
            self._order += 1
            self.sprites[f"s{index + 1}"] = Sprite(f"s{index + 1}", DEFAULT_VIEW, texture_id, index * width, 0.0,
                                                   width, view.height, order=self._order)

    def first_texture(self):
        """The default view composed now (before the engine starts: its first texture)."""
        self._composed_version = self._scene_version
        return compose_view(self.views[self.active_view], self.sprites.values(), self.textures, self.samplers)

    # ---- the handshake ---------------------------------------------------------------------------------
    def process_request(self, connection, request):
        """Before the WebSocket handshake: the page's files with ``--page``; the token; anything else 404."""
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        url = urlsplit(request.path)
        query = parse_qs(url.query)
        if self.page and url.path in self.page_files:  # the page's own files are public: the token is in its address
            name, kind = self.page_files[url.path]
            body = resources.files(self.page_package).joinpath(name).read_bytes()
            return Response(200, "OK", Headers([("Content-Type", kind), ("Content-Length", str(len(body))),
                                                ("Cache-Control", "no-store"),
                                                ("Content-Security-Policy", "default-src 'self'; connect-src 'self' "
                                                 "ws: ; img-src 'self' data:; style-src 'self' 'unsafe-inline'"),
                                                ("X-Frame-Options", "DENY")]), body)
        if self.token is not None:
            given = (query.get("token") or [""])[0]
            if not secrets.compare_digest(given.encode(), self.token.encode()):
                return connection.respond(401, "a token is needed: give ?token=... as printed by ultraglide serve\n")
        if url.path == "/ws":
            return None
        if self.page and url.path.startswith("/texture/") and url.path.endswith(".png"):
            texture_id = url.path[len("/texture/"):-len(".png")]
            texture = self.textures.get(texture_id)
            if texture is not None:
                body = _png_of(texture)
                return Response(200, "OK", Headers([("Content-Type", "image/png"), ("Content-Length", str(len(body))),
                                                    ("Cache-Control", "no-store")]), body)
        return connection.respond(404, "not found: the service's WebSocket is at /ws\n")

    # ---- a client --------------------------------------------------------------------------------------
    async def handle(self, connection) -> None:
        """One client, from its handshake to its going."""
        if len(self.sessions) >= MAX_CLIENTS:
            await connection.close(1013, f"at most {MAX_CLIENTS} clients at once; try again later")
            return
        self._numbers += 1
        session = Session(connection, self._numbers)
        self.sessions.add(session)
        if isinstance(connection, short_path_connection()):
            connection.on_text = lambda text, received_s: self._receive_now(session, text, received_s)
        sender = asyncio.create_task(self._sender(session))
        try:
            async for text in connection:
                received_s = time.perf_counter()
                if session.closing:
                    break
                self._receive(session, text, received_s)
        except Exception as error:  # noqa: BLE001 - a connection's failure ends that connection, never the service
            if not _is_connection_closed(error):
                session.closing = True
                import sys

                print(f"ultraglide serve: client {session.number}'s connection failed: {type(error).__name__}: "
                      f"{' '.join(str(error).split())[:300]}", file=sys.stderr, flush=True)
        finally:
            self._leave(session)
            session.closing = True
            session.wake.set()
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender

    async def _sender(self, session: Session) -> None:
        connection = session.connection
        while True:
            await session.wake.wait()
            session.wake.clear()
            while session.queue:
                push, message = session.queue.popleft()
                if not push:
                    session.replies_queued -= 1
                try:
                    await connection.send(json.dumps(message, allow_nan=False, separators=(",", ":")))
                except Exception:  # noqa: BLE001 - the client went: its handler ends
                    session.closing = True
                    return

    def _receive_now(self, session: Session, text: str, received_s: float) -> bool:
        """A message taken as websockets read it (:func:`short_path_connection`), as :meth:`handle` would take it;
        False (not taken: the handler will) once the session is closing. A failure ends the connection, as there."""
        if session.closing:
            return False
        try:
            self._receive(session, text, received_s)
        except Exception as error:  # noqa: BLE001 - a connection's failure ends that connection, never the service
            session.closing = True
            import sys

            print(f"ultraglide serve: client {session.number}'s connection failed: {type(error).__name__}: "
                  f"{' '.join(str(error).split())[:300]}", file=sys.stderr, flush=True)
            session.connection.transport.abort()  # its handler ends, and the finger lifts (_leave)
        return True

    def _leave(self, session: Session) -> None:
        """A client went: its finger lifts at once (the plate ramps to rest), its control passes."""
        self.sessions.discard(session)
        if self.finger is not None and self.finger.session is session or \
                any(f.session is session for f in self.pointers.values()):
            self._lift(time.perf_counter(), session)
        if self.controller is session:
            self.controller = None

    def _receive(self, session: Session, text, received_s: float) -> None:
        self.messages_read += 1
        message = refused = None
        if session.may_send(received_s, len(text) <= p.MAX_TOUCH_CHARS):  # else refused unread
            try:
                message = p.parse(text, self.extra_specs)
            except p.ProtocolError as error:
                refused = error
        client_t = message.fields.get("t") if message is not None and message.type == "touch" else None
        if not session.allow(received_s, client_t):
            session.rate_refusals += 1
            self.rate_refusals += 1
            if session.rate_refusals == 1 or session.rate_refusals % 1000 == 0:  # one line, not one per message
                session.send(p.error_reply(p.RATE, f"more than {RATE_PER_S:g} messages a second: "
                                           f"{session.rate_refusals} refused so far; send fewer"))
            return
        if refused is not None:
            session.send(p.error_reply(refused.code, str(refused), refused.request_id))
            return
        if session.queue and session.replies_queued >= MAX_QUEUED_REPLIES:
            # it does not read what it is sent: it goes at once, its socket dropped (a closing handshake would
            # wait on the very buffers it does not empty)
            session.closing = True
            self._leave(session)
            session.queue.clear()
            session.connection.transport.abort()
            return
        try:
            self._dispatch(session, message, received_s)
        except p.ProtocolError as error:
            if message.type == "touch" and message.id is None:  # unanswered: the first refusal says it, not each
                session.touch_refusals += 1
                if session.touch_refusals > 1:
                    return
            session.send(p.error_reply(error.code, str(error), message.id))
        except (UltraglideError, OSError, ValueError) as error:
            session.send(p.error_reply(p.BAD_MESSAGE, describe(error), message.id))

    # ---- messages --------------------------------------------------------------------------------------
    def _dispatch(self, session: Session, message: p.Message, received_s: float) -> None:
        kind = message.type
        if kind == "hello":
            session.send(self._hello(session, message))
            return
        if session.role is None:
            raise p.ProtocolError(p.NO_HELLO, "say hello first: {\"type\": \"hello\", \"protocol\": 1}")
        if kind in p.CONTROL_TYPES and session is not self.controller:
            raise p.ProtocolError(p.READ_ONLY, "this client observes: another controls the plate (hello with "
                                  "role control once it has gone)")
        if kind == "touch":
            self._touch(session, message, received_s)
            return
        handler = getattr(self, "_on_" + kind.replace(".", "_"))
        result = handler(session, message)
        if kind in SCENE_TYPES:
            self._scene_pushed_soon()
            result = {**(result or {}), "scene_version": self._scene_version}
        if asyncio.iscoroutine(result):
            asyncio.ensure_future(self._answer_later(session, message, result))
        else:
            session.send(p.reply(message.id, **(result or {})))

    async def _answer_later(self, session: Session, message: p.Message, pending) -> None:
        try:
            fields = await pending
        except p.ProtocolError as error:
            session.send(p.error_reply(error.code, str(error), message.id))
        except (UltraglideError, OSError, ValueError) as error:
            session.send(p.error_reply(p.ENGINE if type(error).__name__ == "EngineError" else p.TEXTURE,
                                       describe(error), message.id))
        else:
            session.send(p.reply(message.id, **(fields or {})))

    def _hello(self, session: Session, message: p.Message) -> dict:
        if message["protocol"] != p.PROTOCOL_VERSION:
            raise p.ProtocolError(p.BAD_MESSAGE, f"this server speaks protocol {p.PROTOCOL_VERSION}, not "
                                  f"{message['protocol']}")
        role = message.get("role", "control")
        if role == "control" and self.controller not in (None, session):
            raise p.ProtocolError(p.BUSY, "another client controls the plate; hello with role observe to watch")
        if session.role == "control" and role == "observe" and self.controller is session:
            self.controller = None
            self._lift(time.perf_counter(), session)
        session.role = role
        session.client = message.get("client", "")
        if role == "control":
            self.controller = session
        limit = self.profile.max_amplitude_um_pp
        return p.reply(message.id, protocol=p.PROTOCOL_VERSION, server=f"ultraglide {__version__}",
                       role=role, device=self.engine.config.device, profile=self.profile.name,
                       limit_um_pp=limit, default_force_n=self.engine.config.default_force_n, drives=self.drives,
                       touch_panel=self.touch_panel,
                       limits={"message_bytes": p.MAX_MESSAGE_BYTES, "small_message_bytes": p.MAX_SMALL_MESSAGE_BYTES,
                               "messages_per_s": RATE_PER_S, "textures": MAX_TEXTURES, "sprites": MAX_SPRITES,
                               "views": MAX_VIEWS, "texture_pixels": MAX_TEXTURE_PIXELS},
                       **self._state())

    def _state(self) -> dict:
        return {"scene_version": self._scene_version, "rendered_version": self._composed_version,
                "views": [_view_dict(v) for v in self.views.values()],
                "sprites": [_sprite_dict(s) for s in self.sprites.values()],
                "textures": [_texture_dict(k, t) for k, t in self.textures.items()]}

    def _on_touches_set(self, session, message) -> dict:
        """Which pointer drives when two or more are down, from now on (those down keep their roles until one
        lifts or comes down)."""
        self.drives = message["drives"]
        return {"drives": self.drives}

    def _on_state(self, session, message) -> dict:
        return self._state()

    def _on_subscribe(self, session: Session, message: p.Message) -> dict:
        if "status" in message.fields:
            session.status_hz = 2.0 if message["status"] < 0 else message["status"]
        if "output" in message.fields:
            session.output_hz = 100.0 if message["output"] < 0 else message["output"]
            session.output_from_s = time.perf_counter()
        if "touch" in message.fields:
            session.touch_seen = message["touch"]
        if "scene" in message.fields:
            session.scene = message["scene"]
        self.publisher_wake.set()
        return {"status": session.status_hz, "output": session.output_hz, "touch": session.touch_seen,
                "scene": session.scene}

    async def _on_texture_load(self, session: Session, message: p.Message) -> dict:
        texture_id = message["texture"]
        if texture_id not in self.textures and len(self.textures) >= MAX_TEXTURES:
            raise p.ProtocolError(p.LIMIT, f"at most {MAX_TEXTURES} textures: unload one first")
        sources = [key for key in ("library", "file", "png") if key in message.fields]
        if len(sources) != 1:
            raise p.ProtocolError(p.BAD_MESSAGE, "texture.load: give one of 'library', 'file' or 'png'")
        texture, notes = await asyncio.get_running_loop().run_in_executor(self.worker, _load_texture, message)
        self.textures[texture_id] = texture
        self.samplers.pop(texture_id, None)
        self._scene_pushed_soon()
        if any(s.texture == texture_id and s.visible for s in self.sprites.values()):
            self._changed()
        return {**_texture_dict(texture_id, texture), "notes": notes, "scene_version": self._scene_version}

    def _on_texture_unload(self, session, message) -> dict:
        texture_id = message["texture"]
        self._texture(texture_id)
        used = [s.name for s in self.sprites.values() if s.texture == texture_id]
        if used:
            raise p.ProtocolError(p.BAD_MESSAGE, f"texture {texture_id} is on sprite(s) {', '.join(used[:5])}: "
                                  "remove them first")
        del self.textures[texture_id]
        self.samplers.pop(texture_id, None)
        return {}

    def _on_view_set(self, session, message) -> dict:
        name = message["view"]
        old = self.views.get(name)
        if old is None and len(self.views) >= MAX_VIEWS:
            raise p.ProtocolError(p.LIMIT, f"at most {MAX_VIEWS} views")
        units = message.get("units", old.units if old else "px")
        width, height = message["width"], message["height"]
        if units == "mm":
            width_mm, height_mm = message.get("width_mm", width), message.get("height_mm", height)
            if (width_mm, height_mm) != (width, height):
                raise p.ProtocolError(p.BAD_MESSAGE, "view.set: a view in mm is width × height mm; leave out "
                                      "width_mm and height_mm")
            if max(width, height) > 2000:
                raise p.ProtocolError(p.BAD_MESSAGE, "view.set: a view is at most 2000 mm a side")
        else:
            if "width_mm" not in message.fields or "height_mm" not in message.fields:
                raise p.ProtocolError(p.BAD_MESSAGE, "view.set: a view in px needs its physical size, width_mm "
                                      "and height_mm (the screen's)")
            if max(width, height) > MAX_SIDE_PX:
                raise p.ProtocolError(p.BAD_MESSAGE, f"view.set: a view is at most {MAX_SIDE_PX} px a side")
            width_mm, height_mm = message["width_mm"], message["height_mm"]
        view = View(name, width, height, units, width_mm, height_mm,
                    message.get("background_ratio", old.background_ratio if old else 1.0))
        if old is not None and (old.width, old.height) != (width, height):  # its sprites keep their share of it
            sx, sy = width / old.width, height / old.height
            for sprite in list(self.sprites.values()):
                if sprite.view == name:
                    self.sprites[sprite.name] = sprite.with_(x=sprite.x * sx, y=sprite.y * sy,
                                                             width=sprite.width * sx, height=sprite.height * sy)
        self.views[name] = view
        if name == self.active_view:
            self._changed()
        return {"view": _view_dict(view)}

    def _on_view_remove(self, session, message) -> dict:
        name = message["view"]
        self._view(name)
        if len(self.views) == 1:
            raise p.ProtocolError(p.BAD_MESSAGE, "the last view stays: set it instead")
        for sprite in [s for s in self.sprites.values() if s.view == name]:
            del self.sprites[sprite.name]
            self.attached.pop(sprite.name, None)
        del self.views[name]
        if self.active_view == name:
            self.active_view = next(iter(self.views))
            self._changed()
        return {}

    def _on_sprite_set(self, session, message) -> dict:
        name = message["sprite"]
        old = self.sprites.get(name)
        fields = dict(message.fields)
        del fields["sprite"]
        if old is None:
            if len(self.sprites) >= MAX_SPRITES:
                raise p.ProtocolError(p.LIMIT, f"at most {MAX_SPRITES} sprites")
            if "texture" not in fields:
                raise p.ProtocolError(p.UNKNOWN, f"no sprite {name!r}: place it with texture, x, y, width and height")
            missing = [key for key in ("x", "y", "width", "height") if key not in fields]
            if missing:
                raise p.ProtocolError(p.BAD_MESSAGE, f"sprite.set: a new sprite needs {', '.join(missing)}")
            self._order += 1
            view = fields.pop("view", DEFAULT_VIEW if DEFAULT_VIEW in self.views else next(iter(self.views)))
            sprite = Sprite(name, view, **fields, order=self._order)
        else:
            if "z" in fields:  # reordered: among equal z, the latest placed on top
                self._order += 1
                fields["order"] = self._order
            sprite = old.with_(**fields)
        self._view(sprite.view)
        self._texture(sprite.texture)
        self.sprites[name] = sprite
        if sprite.view == self.active_view or (old is not None and old.view == self.active_view):
            self._changed()
        return {"sprite": _sprite_dict(sprite)}

    def _on_sprite_remove(self, session, message) -> dict:
        sprite = self.sprites.pop(message["sprite"], None)
        if sprite is None:
            raise p.ProtocolError(p.UNKNOWN, f"no sprite {message['sprite']!r}")
        detached = self.attached.pop(sprite.name, None) is not None
        if sprite.view == self.active_view:
            self._changed()
        elif detached:
            self._effects_changed()
        return {}

    async def _on_effects_set(self, session, message) -> dict:
        description = message["effects"]
        if description is not None:
            _session_bindings(description)  # refused here, in one line, before anything changes
        previous, self.effects = self.effects, description
        try:
            notes = await self._apply_effects(force=True)
        except (UltraglideError, ValueError):
            self.effects = previous
            raise
        return {"notes": notes}

    async def _on_effect_trigger(self, session, message) -> dict:
        played = await asyncio.get_running_loop().run_in_executor(self.worker, self.engine.trigger, message["name"])
        return {"played": played}

    async def _on_effect_stop(self, session, message) -> dict:
        """Every effect playing stops: the effects are set again (their voices start afresh, silent)."""
        await self._apply_effects(force=True)
        return {}

    async def _on_effects_attach(self, session, message) -> dict:
        """Effects that play while the finger is on a sprite (its shown, uncovered part) and stop when it leaves:
        each becomes a ``while`` binding over the rectangles :func:`scene.sprite_regions` gives."""
        name = message["sprite"]
        if name not in self.sprites:
            raise p.ProtocolError(p.UNKNOWN, f"no sprite {name!r}; place it with sprite.set first")
        sources = [key for key in ("effect", "effects", "file") if message.get(key) is not None]
        if len(sources) != 1:
            raise p.ProtocolError(p.BAD_MESSAGE, "effects.attach: give one of 'effect' (an effect object), 'effects' "
                                  "(an effects description) or 'file' (.json, .ahap, .haptic, .hjif or .haps)")
        loop = asyncio.get_running_loop()
        bindings, notes = await loop.run_in_executor(self.worker, _attached_bindings, message)
        if name not in self.sprites:  # removed while its effects were read
            raise p.ProtocolError(p.UNKNOWN, f"no sprite {name!r}: it was removed")
        previous = self.attached.get(name)
        self.attached[name] = bindings
        try:
            notes += await self._apply_effects(strict=name)
        except (UltraglideError, ValueError):
            if previous is None:
                del self.attached[name]
            else:
                self.attached[name] = previous
            with contextlib.suppress(UltraglideError, OSError, ValueError):  # the refusal is what is said
                await self._apply_effects()
            raise
        return {"sprite": name, "effects": len(bindings), "regions": self._regions_sent.get(name, 0),
                "notes": notes}

    async def _on_effects_detach(self, session, message) -> dict:
        name = message["sprite"]
        if self.attached.pop(name, None) is None:
            raise p.ProtocolError(p.UNKNOWN, f"no effects attached to sprite {name!r}")
        await self._apply_effects()
        return {"sprite": name}

    async def _apply_effects(self, force: bool = False, strict: str | None = None) -> list[str]:
        """The session's effects and the sprites' (as the scene is now) to the engine, on the worker."""
        state = (self.views[self.active_view], list(self.sprites.values()), self.effects, dict(self.attached))
        return await asyncio.get_running_loop().run_in_executor(self.worker, self._set_effects, state, force, strict)

    def _effects_changed(self) -> None:
        """The sprites' effects changed without the view's friction (a sprite of another view removed)."""
        async def apply():
            with contextlib.suppress(UltraglideError, OSError, ValueError):
                await self._apply_effects()
        asyncio.ensure_future(apply())

    def _set_effects(self, state, force: bool = False, strict: str | None = None) -> list[str]:
        """(On the worker.) The engine's effects for ``state`` (view, sprites, session's description, attached),
        sent when they changed (``force``: always, their voices start afresh). ``strict``: a sprite whose
        effects must all be placed (else ProtocolError, nothing sent)."""
        description, notes, regions = _effects_description(*state)
        if strict is not None and any(note.startswith(f"sprite {strict!r}") for note in notes):
            raise p.ProtocolError(p.LIMIT, next(n for n in notes if n.startswith(f"sprite {strict!r}")))
        if force or description != self._effects_sent:
            self.engine.set_effects(description)
            self._effects_sent = description
        self._regions_sent = regions
        return notes

    # ---- touches ---------------------------------------------------------------------------------------
    def _touch(self, session: Session, message: p.Message, received_s: float) -> None:
        """A pointer event. Every pointer down is followed; which one the engine renders is :attr:`drives`'s rule
        (``first``: the first down until it lifts; ``latest``: the newest down takes over, and when it lifts the
        newest still down; ``none``: with two or more down, none, the plate at rest, until one is left)."""
        if self.touch_panel is not None:
            raise p.ProtocolError(p.TOUCH_PANEL, f"the engine reads the touch panel itself (serve --touch-panel "
                                  f"{self.touch_panel}): clients place sprites; their touches are not taken")
        view = self._view(message.get("view", self.active_view))
        x_mm, y_mm = view.to_mm(message["x"], message["y"])
        force = message.get("force_n")
        if force is None and message.get("pressure", 0.0) > 0 and message.get("pointer_type", "touch") != "mouse":
            force = max(MIN_PRESSED_FORCE_N, message["pressure"] * self.pressure_full_scale_n)
        self.pointer(session, view.name, message.get("pointer", 0), message["phase"], x_mm, y_mm, force,
                     message.get("t"), received_s)

    def pointer(self, session: Session, view_name: str, pointer: int, phase: str, x_mm: float, y_mm: float,
                force: float | None, source_t: float | None, received_s: float) -> None:
        """A pointer event, from a client's ``touch`` or the touch panel (:mod:`apps.service.panel`), followed and
        rendered by the :attr:`drives` rule.

        Parameters
        ----------
        session : Session
            Whose pointer it is (the panel's feed has a session of its own).
        view_name : str
            The view it is on (an existing one).
        pointer : int
            The pointer's id (a client's ``pointer``, a panel's slot).
        phase : str
            ``down``, ``move``, ``up`` or ``cancel``.
        x_mm, y_mm : float
            Where, mm from the view's top-left corner.
        force : float or None
            The finger's force, N (None: the engine's default).
        source_t : float or None
            When it happened on its source's clock, s (None: when it arrived), shifted onto ours by ``session``'s
            least offset.
        received_s : float
            When it arrived, ``perf_counter`` s.
        """
        pointers = self.pointers
        known = pointers.get(pointer)
        new = known is None
        if new:
            if phase != "down":
                return  # a pointer hovering, or a move after a lift: nothing to feel
            if len(pointers) >= MAX_POINTERS:
                self.touches_ignored += 1
                return
        t = session.engine_time(source_t, received_s)
        if known is None:
            known = pointers[pointer] = Finger(session, pointer, view_name, x_mm, y_mm, force)
        else:
            known.view, known.x_mm, known.y_mm, known.force_n = view_name, x_mm, y_mm, force
        driving = self.finger
        if phase in ("up", "cancel"):
            del pointers[pointer]
            if driving is known:
                self._count(source_t, received_s)
                self.engine.touch(t, x_mm, y_mm, force, down=False)
                self.finger = None
                if self.drives == "latest" and pointers:  # the newest still down takes over
                    self._drive(next(reversed(pointers.values())), t)
            else:
                self.touches_ignored += 1
            if self.drives == "none" and self.finger is None and len(pointers) == 1:  # one left: it drives
                self._drive(next(iter(pointers.values())), t)
            return
        if driving is known:
            self._count(source_t, received_s)
            self._drive(known, t)
            return
        if new:  # a pointer down beside the one that drives, or none
            if self.drives == "none" and len(pointers) > 1:
                if driving is not None:  # two down: none drives, the plate rests
                    self.finger = None
                    self.engine.touch(t, driving.x_mm, driving.y_mm, driving.force_n, down=False)
            elif driving is None or self.drives == "latest":
                if driving is not None:
                    self.engine.touch(t, driving.x_mm, driving.y_mm, driving.force_n, down=False)
                self._count(source_t, received_s)
                self._drive(known, t)
                return
        self.touches_ignored += 1  # a pointer that does not drive: followed, not rendered

    def _count(self, source_t: float | None, received_s: float) -> None:
        self.touches += 1
        if self.arrivals is not None:  # (bench/bench_service.py) the client's time, when it came, when it went in
            self.arrivals.append((source_t, received_s, time.perf_counter()))

    def _drive(self, finger: Finger, t: float) -> None:
        """``finger`` drives the plate: the engine renders it, down where it is now."""
        if finger.view != self.active_view:
            self.active_view = finger.view
            self._changed()
        self.finger = finger
        self.engine.touch(t, finger.x_mm, finger.y_mm, finger.force_n, down=True)

    def _lift(self, now_s: float, session: Session | None = None) -> None:
        """The driving finger lifts (the plate ramps to rest); the pointers of ``session`` (all, if None) are
        forgotten."""
        finger = self.finger
        for key in [k for k, f in self.pointers.items() if session is None or f.session is session]:
            del self.pointers[key]
        if finger is not None and (session is None or finger.session is session):
            self.finger = None
            self.engine.touch(now_s, finger.x_mm, finger.y_mm, finger.force_n, down=False)

    # ---- the scene -------------------------------------------------------------------------------------
    def _changed(self) -> None:
        """The active view changed: compose it again and hand it to the engine (on the worker, coalesced)."""
        self._scene_version += 1
        if self._composing is None or self._composing.done():
            self._composing = asyncio.ensure_future(self._compose())

    async def _compose(self) -> None:
        loop = asyncio.get_running_loop()
        while self._composed_version != self._scene_version:
            version = self._scene_version
            view = self.views[self.active_view]
            sprites = list(self.sprites.values())
            textures = dict(self.textures)
            effects_state = (view, sprites, self.effects, dict(self.attached))
            try:
                notes = await loop.run_in_executor(self.worker, self._set_scene, view, sprites, textures, effects_state)
            except (UltraglideError, OSError, ValueError) as error:
                notes = [f"the view could not be rendered: {describe(error)}"]
            for note in notes:
                for session in list(self.sessions):
                    session.send({"type": "notice", "message": note}, push=True)
            self._composed_version = version

    def _set_scene(self, view, sprites, textures, effects_state) -> list[str]:
        texture = compose_view(view, sprites, textures, self.samplers)
        self.engine.set_texture(texture)
        return self._set_effects(effects_state)

    def _scene_pushed_soon(self) -> None:
        """The scene to its subscribers once this turn of the loop is over (a burst of changes: one push; a texture
        still loading: pushed again when it has)."""
        if not self._scene_push_due:
            self._scene_push_due = True
            asyncio.get_running_loop().call_later(0.005, self._push_scene)

    def _push_scene(self) -> None:
        self._scene_push_due = False
        state = None
        for session in list(self.sessions):
            if session.scene and session.role:
                state = state or {"type": "scene", **self._state()}
                session.send(state, push=True)

    def _view(self, name: str) -> View:
        view = self.views.get(name)
        if view is None:
            raise p.ProtocolError(p.UNKNOWN, f"no view {name!r}; views: {', '.join(self.views)}")
        return view

    def _texture(self, name: str):
        texture = self.textures.get(name)
        if texture is None:
            raise p.ProtocolError(p.UNKNOWN, f"no texture {name!r}; load it with texture.load first")
        return texture

    # ---- subscriptions ---------------------------------------------------------------------------------
    def publish(self, loop, stop) -> None:
        """Status, output and the touch as seen, to the clients that subscribed, each at its own rate: on a thread
        of its own (the engine's status takes 2-7 ms to read on a busy machine, which the loop must not wait),
        handing each message to the loop. Runs until ``stop`` (a threading.Event) is set, seen within
        :data:`PUBLISH_IDLE_S`.

        The engine's status is read only when a subscriber is due (:func:`_due`): every read holds the
        interpreter's lock for about a millisecond of Python, which the loop, woken by a touch, waits for; it was
        read every 10 ms for a page's status at 2 Hz (100 reads a second, 2 needed). And the thread sleeps until the
        first subscriber is due (:func:`_next_due`; a subscription wakes it): each of its wake-ups takes the
        interpreter too, and it woke every 10 ms, as often as the touches came, whoever had subscribed."""
        wake = self.publisher_wake
        while not stop.is_set():
            now = time.perf_counter()
            sessions = [s for s in list(self.sessions) if s.role]
            wanted = [s for s in sessions if _due(s, now)]
            if wanted:
                self._publish_to(wanted, loop, now)
            first = min((_next_due(s) for s in sessions), default=math.inf)
            if wake.wait(min(max(first - time.perf_counter(), PUBLISH_S), PUBLISH_IDLE_S)):
                wake.clear()

    def _publish_to(self, wanted: list, loop, now: float) -> None:
        """One read of the engine's status, and each due subscriber's messages from it, handed to the loop.

        The history read reaches back to the oldest output subscriber's last block (with
        :data:`PUBLISH_HISTORY_S` to spare), as far as the engine's ring holds (about 5 s): a publisher woken
        late (a loaded machine did not run it for 0.15 s or more) loses no row; it read a fixed 0.25 s, and lost
        the rows older than that."""
        history_s = PUBLISH_HISTORY_S
        for session in wanted:
            if session.output_hz:
                history_s = max(history_s, now - session.output_from_s + PUBLISH_HISTORY_S)
        status = self.engine.status(history_s=history_s)
        self.status_reads += 1
        for session in wanted:
            if session.output_hz:
                session.next_output_s = now + min(1.0 / session.output_hz, OUTPUT_EVERY_S)
            messages = []
            if session.status_hz and now >= session.next_status_s:
                session.next_status_s = now + 1.0 / session.status_hz
                messages.append(self._status_message(status, session))
            if session.output_hz:
                message = _output_message(status.history, session)
                if message is not None:
                    messages.append(message)
            if session.touch_seen and status.last_touch is not None:
                x, y, force, down = status.last_touch
                seen = (x, y, down)
                if session.last_seen != seen:
                    session.last_seen = seen
                    view = self.views.get(self.active_view)
                    sprite = sprite_at(view, list(self.sprites.values()), x, y) if view and down else None
                    messages.append({"type": "touch.seen", "view": self.active_view, "x_mm": x, "y_mm": y,
                                     "force_n": None if math.isnan(force) else force, "down": bool(down),
                                     "sprite": sprite.name if sprite else None})
            for message in messages:
                loop.call_soon_threadsafe(session.send, message, True)

    def _status_message(self, status, session: Session) -> dict:
        return {"type": "status", "device": status.device, "state": status.state, "faults": list(status.faults),
                "limit_um_pp": self.profile.max_amplitude_um_pp, "limited_percent": status.limited_percent,
                "loop": status.loop, "blocks": status.blocks, "late_blocks": status.late_blocks,
                "underruns": status.underruns, "touches": self.touches, "touches_ignored": self.touches_ignored,
                "touches_dropped": status.touches_dropped, "texture": status.texture,
                "controller": self.controller is not None, "role": session.role, "clients": len(self.sessions),
                "pushes_dropped": session.pushes_dropped}


PUBLISH_S = 0.01  # the publisher's shortest sleep: a touch-as-seen subscriber is looked at this often
PUBLISH_IDLE_S = 0.25  # its longest: how soon it sees its stop
OUTPUT_EVERY_S = 0.1  # an output subscriber's rows are sent at least this often
PUBLISH_HISTORY_S = 0.25  # a status read's history reaches this far before the oldest output subscriber's last row


def _due(session: Session, now: float) -> bool:
    """Whether ``session`` wants a push now: its status at its rate, its output rows at theirs (at least every
    :data:`OUTPUT_EVERY_S`), the touch as seen at every look (it is sent when it changed)."""
    return bool(session.touch_seen or session.status_hz and now >= session.next_status_s
                or session.output_hz and now >= session.next_output_s)


def _next_due(session: Session) -> float:
    """When ``session`` next wants a push, ``perf_counter`` s (its status, its output rows; the touch as seen: at
    every look, -inf); +inf for none.

    Examples
    --------
    >>> _next_due(Session(None, 1, status_hz=2.0, next_status_s=10.5, output_hz=20.0, next_output_s=10.2))
    10.2
    >>> _next_due(Session(None, 2)), _next_due(Session(None, 3, touch_seen=True))
    (inf, -inf)
    """
    if session.touch_seen:
        return -math.inf
    due = math.inf
    if session.status_hz:
        due = min(due, session.next_status_s)
    if session.output_hz:
        due = min(due, session.next_output_s)
    return due


def _output_message(history, session: Session) -> dict | None:
    """The blocks rendered since the last output message, at most ``output_hz`` rows a second."""
    import numpy as np

    times = history.time_s
    index = np.flatnonzero(times > session.output_from_s)
    if not len(index):
        return None
    session.output_from_s = float(times[index[-1]])
    keep = []
    for k in index:
        if times[k] - session.output_kept_s >= 1.0 / session.output_hz * 0.999:
            keep.append(k)
            session.output_kept_s = float(times[k])
    if not keep:
        return None
    rows = np.asarray(keep)
    return {"type": "output", "t": [round(float(v), 6) for v in times[rows]],
            "ratio": [round(float(v), 5) for v in history.target_ratio[rows]],
            "amplitude_um_pp": [round(float(v), 5) for v in history.commanded_um_pp[rows]],
            "plate_um_pp": [round(float(v), 5) for v in history.plate_um_pp[rows]]}


def _is_connection_closed(error: BaseException) -> bool:
    from websockets.exceptions import ConnectionClosed

    return isinstance(error, ConnectionClosed)


def _view_dict(view: View) -> dict:
    return {"view": view.name, "width": view.width, "height": view.height, "units": view.units,
            "width_mm": view.width_mm, "height_mm": view.height_mm, "background_ratio": view.background_ratio}


def _sprite_dict(sprite: Sprite) -> dict:
    return {"sprite": sprite.name, "view": sprite.view, "texture": sprite.texture, "x": sprite.x, "y": sprite.y,
            "width": sprite.width, "height": sprite.height, "rotation_deg": sprite.rotation_deg, "z": sprite.z,
            "visible": sprite.visible}


def _texture_dict(texture_id: str, texture) -> dict:
    return {"texture": texture_id, "name": texture.name, "width_mm": texture.width_mm,
            "height_mm": texture.height_mm, "cols": texture.cols, "rows": texture.rows, "kind": texture.kind}


def _load_named(spec: str):
    from ultraglide.textures.library import resolve_texture

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        texture = resolve_texture(spec)
    if texture.rows * texture.cols > MAX_TEXTURE_PIXELS:
        raise p.ProtocolError(p.LIMIT, f"{spec}: {texture.cols}×{texture.rows} pixels, more than a sprite's "
                              f"{MAX_TEXTURE_PIXELS:,}; make it smaller")
    return texture


def _load_texture(message: p.Message):
    """A texture from a library name, a file, or a PNG's bytes (base64); (texture, notes)."""
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if "png" in message.fields:
            texture = _from_png(message)
        elif "file" in message.fields and _is_scene(message["file"]) or "material" in message.fields:
            texture = _from_gltf(message)
        else:
            texture = _load_named(message.get("library") or message.get("file"))
    notes = [" ".join(str(w.message).split())[:300] for w in caught]
    if "name" in message.fields:
        texture = texture.with_(name=message["name"])
    return texture, notes


def _session_bindings(description) -> tuple:
    """The session's effects description (``effects.set``) as bindings; ProtocolError (``engine``) for a bad one."""
    from ultraglide.textures.effects import from_json
    from ultraglide.textures.errors import TextureError

    try:
        return from_json(description)
    except TextureError as error:
        raise p.ProtocolError(p.ENGINE, f"effects.set: {describe(error)}") from None


def _attached_bindings(message: p.Message) -> tuple[tuple, list[str]]:
    """(On the worker.) The bindings ``effects.attach`` names: one ``effect`` object, an ``effects`` description, or
    a ``file`` (ours, .json; a designer's .ahap, .haptic, .hjif or .haps, through ``textures.formats.effects_in``), with
    ``release_s`` for all when given; and the notes loading said (what a designer's file loses)."""
    from dataclasses import replace as replaced

    from ultraglide.textures.effects import Binding, Trigger, effect_from_dict, from_json, load_effects
    from ultraglide.textures.errors import TextureError

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if message.get("effect") is not None:
                bindings = (Binding(Trigger("while"), effect_from_dict(message["effect"])),)
            elif message.get("effects") is not None:
                bindings = from_json(message["effects"])
            else:
                bindings = load_effects(message["file"])
        except TextureError as error:
            raise p.ProtocolError(p.ENGINE, f"effects.attach: {describe(error)}") from None
    notes = [" ".join(str(w.message).split())[:300] for w in caught]
    if not bindings:
        raise p.ProtocolError(p.ENGINE, "effects.attach: no effect to attach" + (f" ({notes[0]})" if notes else ""))
    if message.get("release_s") is not None:
        bindings = tuple(replaced(b, release_s=message["release_s"]) for b in bindings)
    return tuple(bindings), notes


def _effects_description(view: View, sprites: list, session_description, attached: dict):
    """The engine's effects: the session's bindings, then each attached sprite's effects as ``while`` bindings over
    the rectangles where it is felt (:func:`scene.sprite_regions`, within what :data:`MAX_BINDINGS` leaves).
    (description or None, notes, {sprite: rectangles})."""
    from ultraglide.textures.effects import MAX_BINDINGS, Binding, Trigger, to_json

    bindings = list(_session_bindings(session_description)) if session_description is not None else []
    notes, regions = [], {}
    for name, sources in attached.items():
        sprite = next((s for s in sprites if s.name == name), None)
        if sprite is None or sprite.view != view.name:
            continue
        budget = (MAX_BINDINGS - len(bindings)) // len(sources)
        rectangles = sprite_regions(view, sprites, name, budget) if budget > 0 else None
        if rectangles is None:
            notes.append(f"sprite {name!r}'s effects are not played: {len(sources)} effect(s) over its shape need "
                         f"more than the {MAX_BINDINGS - len(bindings)} of {MAX_BINDINGS} bindings the engine has "
                         "left; attach fewer, or uncover or unturn it")
            continue
        regions[name] = len(rectangles)
        for source in sources:
            for rectangle in rectangles:
                bindings.append(Binding(Trigger("while", rectangle), source.effect, source.release_s,
                                        f"sprite {name}"))
    if session_description is None and not attached:
        return None, notes, regions
    return to_json(bindings), notes, regions


def _is_scene(path: str) -> bool:
    from ultraglide.textures.formats.gltf import is_gltf

    return is_gltf(path)


def _from_gltf(message: p.Message):
    """A glTF scene's haptic material (``material``: its name or index; by default the first with a friction
    texture) as a texture, as ``texture import`` reads it; ``width_mm`` its width where the scene does not say
    it (or to override it: its height follows the UV mapping's aspect)."""
    from ultraglide.textures.formats.gltf import load_friction_texture

    path = message.get("file")
    if path is None or not _is_scene(path):
        raise p.ProtocolError(p.BAD_MESSAGE, "texture.load: 'material' names a haptic material of a glTF scene: "
                              "give 'file' as a .gltf or .glb file")
    if "height_mm" in message.fields:
        raise p.ProtocolError(p.BAD_MESSAGE, "texture.load: a glTF material's size is its width_mm (its height "
                              "follows the scene's UV mapping); leave out height_mm")
    material = message.get("material")
    texture = load_friction_texture(path, material, message.get("width_mm"))
    if texture.rows * texture.cols > MAX_TEXTURE_PIXELS:
        raise p.ProtocolError(p.LIMIT, f"{path}: {texture.cols}×{texture.rows} pixels, more than a sprite's "
                              f"{MAX_TEXTURE_PIXELS:,}; make it smaller")
    return texture


def _from_png(message: p.Message):
    from ultraglide.textures.fileformat import load_texture

    try:
        data = base64.b64decode(message["png"], validate=True)
    except ValueError:
        raise p.ProtocolError(p.BAD_MESSAGE, "texture.load: 'png' must be base64") from None
    if data[:8] != b"\x89PNG\r\n\x1a\n" or len(data) < 24 or data[12:16] != b"IHDR":
        raise p.ProtocolError(p.TEXTURE, "texture.load: 'png' is not a PNG")
    cols, rows = struct.unpack(">II", data[16:24])
    if cols * rows > MAX_TEXTURE_PIXELS:
        raise p.ProtocolError(p.LIMIT, f"texture.load: {cols}×{rows} pixels, more than a sprite's "
                              f"{MAX_TEXTURE_PIXELS:,}; send a smaller image")
    with tempfile.TemporaryDirectory(prefix="ultraglide-serve-") as folder:
        path = os.path.join(folder, "texture.png")
        with open(path, "wb") as stream:
            stream.write(data)
        texture = load_texture(path)
    texture = texture.with_(source="sent by the client", name=texture.name if texture.name != "texture" else "sent")
    width_mm, height_mm = message.get("width_mm"), message.get("height_mm")
    if width_mm or height_mm:
        scale = (width_mm / texture.width_mm) if width_mm else (height_mm / texture.height_mm)
        texture = texture.with_(width_mm=width_mm or texture.width_mm * scale,
                                height_mm=height_mm or texture.height_mm * scale)
    return texture


def _png_of(texture) -> bytes:
    """The texture's friction map as an 8-bit grayscale PNG (for the page to draw)."""
    import io

    import numpy as np
    from PIL import Image

    values = np.clip(texture.ratio_map() * 255.0 + 0.5, 0, 255).astype(np.uint8)
    stream = io.BytesIO()
    Image.fromarray(values, mode="L").save(stream, format="PNG")
    return stream.getvalue()


def new_token() -> str:
    """A random token for clients beyond loopback (128 bits, URL-safe)."""
    return secrets.token_urlsafe(16)
