"""A participant in a browser: a design's trials on a page served by the service, felt through the engine.

:class:`BrowserResponder` is the participant-interface seam (:mod:`ultraglide.experiment.responders`) over
``ultraglide serve``'s service in a participant's mode (:mod:`ultraglide.apps.service.participant`): the engine
runs on the device; each trial's texture (every zone in place, plain glass between, as the window's) goes to the
engine, and the page draws the trial's zones at their size in mm, asks the question with the design's labels as
buttons (a number field for magnitude estimation) and sends the participant's touches as the service's ``touch``
messages (the same path as any client's: the friction under the finger is the trial's stimulus). The answer and
the reaction time come back as an :class:`~ultraglide.experiment.responders.Answer`.

The method of adjustment, as the window's (:mod:`ultraglide.apps.experiment.design_window`): the page's −/+ buttons
and keys step the second zone's contrast by :data:`ADJUST_STEP_DB` within the condition's range, its slider sets
it anywhere in the range; each level the page sets (``participant.adjust``) goes to the engine as the trial's
texture with that zone at that level (the presentation's ``texture_at``) before the page is answered, so the
finger on it feels each step; OK or Enter gives the level set, the answer's ``response``.

Reaction time: measured on the page with ``performance.now()`` from the trial's presentation (the first frame the
page draws with the trial's zones, as the window measures from its trial's first frame) to the button's press;
a page that reconnects mid-trial shows the trial again and its time starts again.

Esc on the page (``participant.stop``) stops the session as the window's Esc does: the trial shown (or the break)
gets no answer, the trials answered stay in ``trials.csv``, ``session.json`` says ``stopped``, and the command exits
1 with its summary (``--resume`` continues it). The page's words (its progress line, the keys' hint line, the OK
buttons, the end) are the design's ``[words]`` (English by default), its questions and labels the blocks'.

Lifecycle: a page that closes leaves the session waiting (said on standard error) until a page connects again
(the trial is shown again) or ``reconnect_timeout_s`` passes (the session stops: its files are complete, status
``stopped``). A stop signal (Ctrl-C, SIGTERM) while a trial or a break waits stops the session the same way and is
kept in :attr:`BrowserResponder.stopped` for the caller to raise once the plate is at rest (:meth:`close`).

Examples
--------
A participant at a browser answering a design of one's own (not run here: it waits for the participant)::

    from ultraglide.apps.experiment.browser import BrowserResponder
    from ultraglide.experiment import load_design, run

    design = load_design("two-textures.toml")
    with BrowserResponder(design, device="sim", port=8766) as page:
        print("open", page.page_url)
        session = run(design, "P01", out="p01/", responder=page)
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import math
import queue
import sys
import threading
import time

from ultraglide.experiment.responders import Answer

DEFAULT_RECONNECT_TIMEOUT_S = 300.0
ADJUST_STEP_DB = 1.0  # a button's or a key's step of the adjusted contrast, as the window's (design_window.py)
WAIT_S = 0.25  # the longest wait between looks at the engine while a trial waits for its answer
STOPPED = object()  # _wait's answer when the participant pressed Esc


def keys_hint(design, mode: str, answers: int) -> str:
    """The hint line's keys for a trial asked in ``mode`` with ``answers`` buttons, in the design's words.

    Parameters
    ----------
    design : Design
    mode : str
        How the page asks the trial (:func:`mode_of`).
    answers : int
        Its answer buttons (the last key named is at most 9).

    Returns
    -------
    str

    Examples
    --------
    >>> from ultraglide.experiment import design_from_dict
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
    ...     "conditions": [{"name": "c", "stimulus": "g"}], "blocks": [{"task": "rating", "conditions": ["c"]}],
    ...     "words": {"keys_rating": "Touches : 1–{last}."}})
    >>> keys_hint(design, "rating", 12), keys_hint(design, "choice", 3)
    ('Touches : 1–9.', 'Keys: 1–3 (or ← / →) answer.')
    """
    return design.word(f"keys_{mode}", last=min(answers, 9))


def mode_of(shown) -> str:
    """How the page asks a trial: ``choice`` (a button per zone), ``yes_no``, ``pair`` (same / different),
    ``rating`` (a button per point of the scale), ``magnitude`` (a number) or ``adjustment`` (−, + and a slider
    setting the second zone's contrast, OK giving it)."""
    task = shown.trial.task
    if task == "same_different":
        return "pair"
    if task in ("rating", "magnitude", "adjustment"):
        return task
    return "choice" if shown.intervals > 1 else "yes_no"


class BrowserResponder:
    """The engine on ``device``, the participant's page served at :attr:`page_url`; see the module docstring.

    Parameters
    ----------
    design : Design
        The design the session runs (its profile, model, force and zones; its trial count).
    device : str
        The engine's device URL (``sim``, ``serial:PORT``, ``audio``, ``null``...).
    host : str
        The address to listen on (default loopback; any other asks for the token).
    port : int
        The TCP port (0: a free one).
    token : str, optional
        The token clients must give; by default one is made when ``host`` is beyond loopback.
    envelope_csv : str, optional
        Record what the engine rendered there, as ``play --envelope-csv`` does.
    reconnect_timeout_s : float
        How long a session waits for a page that closed before it stops, s.
    say : callable, optional
        Where the console's lines go (default: standard error).

    Raises
    ------
    ServiceError
        The address cannot be listened on.
    """

    def __init__(self, design, *, device: str = "sim", host: str = "127.0.0.1", port: int = 8765,
                 token: str | None = None, envelope_csv=None,
                 reconnect_timeout_s: float = DEFAULT_RECONNECT_TIMEOUT_S, say=None):
        import numpy as np
        from ultraglide.apps.service.participant import ParticipantService
        from ultraglide.apps.service.server import needs_token, new_token
        from ultraglide.devices.rig import load_plate
        from ultraglide.render.engine import Engine, EngineConfig
        from ultraglide.textures.texture import Texture

        from ultraglide.experiment.design import plan
        from ultraglide.experiment.stimuli import Layout

        self.design = design
        self.total = len(plan(design))
        self.reconnect_timeout_s = float(reconnect_timeout_s)
        self.say = say or (lambda line: print(f"ultraglide experiment: {line}", file=sys.stderr, flush=True))
        self.stopped: BaseException | None = None
        self.token = token if token is not None else (new_token() if needs_token(host) else None)
        self.host, self.port = host, port
        profile = load_plate(design.profile)
        size = Layout(2, tuple(design.zone_mm), design.gap_mm).size_mm
        self.service = ParticipantService(None, profile, token=self.token, view_mm=size)
        rest = Texture(np.ones((2, 2), dtype=np.float32), *size, name="plain glass")  # until the first trial
        config = EngineConfig(texture=rest, model=design.model, profile=design.profile, device=device,
                              default_force_n=design.force_n, envelope_csv=None if envelope_csv is None else
                              str(envelope_csv))
        self.engine = Engine.start(config)
        self.service.engine = self.engine
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._closed = False
        self.connected = False
        self.ever_connected = False
        try:
            self.engine.wait_ready(120)
            self._listen()
        except BaseException:
            self.close()
            raise

    # ---- the service, on a thread of its own ---------------------------------------------------------------
    def _listen(self) -> None:
        started: concurrent.futures.Future = concurrent.futures.Future()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run_loop, args=(started,), name="ultraglide-participant",
                                        daemon=True)
        self._thread.start()
        urls = started.result(120)
        self.url, self.page_url = urls["url"], urls["page"]

    def _run_loop(self, started) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._serve(started))
        except BaseException as error:  # noqa: BLE001 - handed to the session's thread, which says it
            if not started.done():
                started.set_exception(error)
        finally:
            self._loop.close()

    async def _serve(self, started) -> None:
        from ultraglide.apps.commands.serve import _loop_in_real_time
        from ultraglide.apps.service.protocol import MAX_MESSAGE_BYTES
        from ultraglide.apps.service.server import ServiceError
        from websockets.asyncio.server import serve

        service = self.service
        self._stopping = asyncio.Event()
        options = {"max_size": MAX_MESSAGE_BYTES, "max_queue": 64, "write_limit": 256 * 1024,
                   "ping_interval": 5.0, "ping_timeout": 10.0, "compression": None}
        try:
            server = await serve(service.handle, self.host, self.port, process_request=service.process_request,
                                 origins=service.origins, **options)
        except OSError as error:
            raise ServiceError(f"cannot listen on {self.host}:{self.port}: {error.strerror or error}") from None
        async with server:
            port = server.sockets[0].getsockname()[1]
            host = f"[{self.host}]" if ":" in self.host else self.host
            query = f"?token={self.token}" if self.token else ""
            origins = [None, f"http://{host}:{port}"]
            if self.host == "127.0.0.1":
                origins.append(f"http://localhost:{port}")
            service.origins[:] = origins  # the list serve() checks each handshake against, as serve's
            service.priority = _loop_in_real_time(service)
            stop = threading.Event()
            publisher = threading.Thread(target=service.publish, args=(asyncio.get_running_loop(), stop),
                                         name="ultraglide-publisher", daemon=True)
            publisher.start()
            started.set_result({"url": f"ws://{host}:{port}/ws{query}", "page": f"http://{host}:{port}/{query}"})
            try:
                await self._stopping.wait()
                service.show({"type": "participant.end", "message": self.design.word("end")})  # said; the page stays
                deadline = time.monotonic() + 2.0
                while any(s.queue for s in service.sessions) and time.monotonic() < deadline:
                    await asyncio.sleep(0.01)  # its sender hands it over before the connections close
            finally:
                stop.set()
                for session in list(service.sessions):
                    service._leave(session)

    def _call(self, function, *args) -> None:
        """``function(*args)`` on the service's loop, waited for."""
        done: concurrent.futures.Future = concurrent.futures.Future()

        def call():
            try:
                done.set_result(function(*args))
            except BaseException as error:  # noqa: BLE001 - raised on the caller's thread
                done.set_exception(error)

        self._loop.call_soon_threadsafe(call)
        done.result(30)

    # ---- the seam ------------------------------------------------------------------------------------------
    def present(self, shown) -> Answer:
        """Put the trial's texture on the engine, show the trial on the page, and wait for its answer."""
        from ultraglide.apps.experiment.output import trial_friction

        try:
            mode = mode_of(shown)
            layout = shown.layout
            labels = list(shown.labels)
            question = shown.question
            words = self.design.word
            if mode == "magnitude":
                question = f"{question} {words('modulus', modulus=f'{shown.modulus:g}')}"
            zones = [{"x_mm": layout.zone_left_mm(i), "y_mm": layout.gap_mm, "width_mm": layout.zone_mm[0],
                      "height_mm": layout.zone_mm[1]} for i in range(layout.zones)]
            number = shown.trial.number
            screen = {"type": "participant.trial", "trial": number, "total": self.total, "mode": mode,
                      "question": question, "labels": labels, "size_mm": list(layout.size_mm), "zones": zones,
                      "numbered": mode in ("choice", "magnitude", "adjustment"),
                      "progress": words("progress", trial=number, total=self.total), "language": self.design.language,
                      "keys": f"{keys_hint(self.design, mode, len(labels))} {words('keys_stop')}",
                      "connection_lost": words("connection_lost")}
            if mode == "magnitude":
                screen["ok"] = words("ok")
            adjust = None
            if mode == "adjustment":
                screen.update(level=float(shown.level), range=[float(v) for v in shown.level_range],
                              step_db=ADJUST_STEP_DB)
                adjust = _Adjustment(self, shown)
            texture = shown.texture()
            self.service.worker.submit(self.engine.set_texture, texture).result()
            started = time.perf_counter()
            self._call(self.service.show, screen, tuple(layout.size_mm), ("answer", number))
            event = self._wait(("answer", number), f"trial {number}", adjust)
            if event is None or event is STOPPED:
                return Answer(-1, math.nan, quit=True)
            _, _, button, value, rt_s, _ = event
            if mode in ("magnitude", "adjustment"):
                response = float(value)
            elif mode == "yes_no":
                response = int(button == 0)  # Yes is the first button, and 1
            elif mode == "rating":
                response = shown.scale[0] + button
            else:
                response = button
            answer = Answer(response, rt_s)
            answer.friction = trial_friction(self.engine, started)
            self._call(self.service.show, {"type": "participant.wait", "message": ""})
            return answer
        except KeyboardInterrupt as stop:  # Ctrl-C, SIGTERM: the session stops, its files complete
            self.stopped = stop
            return Answer(-1, math.nan, quit=True)

    def take_break(self, trial: int, message: str = "") -> bool:
        """A break page with a button; False if the session stops instead (a stop signal, a page gone too long)."""
        try:
            words = self.design.word
            screen = {"type": "participant.break", "trial": trial, "message": message or self.design.break_message,
                      "label": words("ok"), "done": trial - 1, "total": self.total, "language": self.design.language,
                      "keys": f"{words('keys_break')} {words('keys_stop')}",
                      "connection_lost": words("connection_lost")}
            self._call(self.service.show, screen, None, ("continue", trial))
            return self._wait(("continue", trial), f"the break before trial {trial}") not in (None, STOPPED)
        except KeyboardInterrupt as stop:
            self.stopped = stop
            return False

    def _wait(self, awaited: tuple, what: str, adjust: _Adjustment | None = None):
        """The awaited event from the page, :data:`STOPPED` when the participant pressed Esc, or None when the page
        stayed away longer than the reconnect timeout; EngineLost if the engine died meanwhile. ``adjust``: an
        adjustment trial's, told each level the page sets."""
        from ultraglide.render.engine import EngineLost

        gone_since = None if self.connected or not self.ever_connected else time.monotonic()
        if not self.ever_connected:
            self.say(f"waiting for the participant's page: open {self.page_url}")
        while True:
            if self.engine.loss is not None:
                raise EngineLost(self.engine.loss)
            try:
                event = self.service.events.get(timeout=WAIT_S)
            except queue.Empty:
                event = None
            if event is not None:
                kind = event[0]
                if kind == "left":
                    self.connected = False
                    gone_since = time.monotonic()
                    self.say(f"the participant's page closed during {what}: waiting up to "
                             f"{self.reconnect_timeout_s:g} s for it to come back ({self.page_url})")
                elif kind == "back":
                    self.connected = True
                    gone_since = None
                    self.say(f"the participant's page is back: {what} shown again" if self.ever_connected else
                             "the participant's page connected")
                    self.ever_connected = True
                elif event[:2] == awaited:
                    return event
                elif kind == "stop" and event[1] == awaited[1]:
                    self.say(f"the participant pressed Esc during {what}: the session stops, its files complete")
                    return STOPPED
                elif kind == "adjust" and adjust is not None and event[1] == awaited[1]:
                    adjust.follow()
            if gone_since is not None and time.monotonic() - gone_since > self.reconnect_timeout_s:
                self.say(f"the participant's page stayed away more than {self.reconnect_timeout_s:g} s: the "
                         f"session stops at {what}, its files complete")
                return None

    # ---- the end -------------------------------------------------------------------------------------------
    def close(self):
        """Stop listening, then stop the engine (the plate ramps to rest); the engine's final status."""
        from ultraglide.apps.cli.signals import held

        if self._closed:
            return None
        self._closed = True
        with held():  # a stop signal arriving now waits until the plate is at rest
            if self._loop is not None and self._thread is not None and self._thread.is_alive():
                self._loop.call_soon_threadsafe(lambda: getattr(self, "_stopping", None) and self._stopping.set())
                self._thread.join(30)
            self.service.worker.shutdown(wait=True, cancel_futures=True)
            return self.engine.stop()

    def __enter__(self) -> BrowserResponder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _Adjustment:
    """An adjustment trial on the page: each level the page sets goes to the engine as the trial's texture with the
    adjusted zone at that level (the window's ``texture_at``), the latest only when several came meanwhile; the page's
    request is answered once the engine has it."""

    def __init__(self, responder: BrowserResponder, shown):
        self.responder, self.shown = responder, shown
        self.level = float(shown.level)  # what the engine plays

    def follow(self) -> None:
        responder = self.responder
        wanted = responder.service.adjusted
        if wanted is not None and wanted != self.level:
            texture = self.shown.texture_at(wanted)
            responder.service.worker.submit(responder.engine.set_texture, texture).result()
            self.level = wanted
        responder._call(responder.service.applied, self.level)


__all__ = ["BrowserResponder", "keys_hint", "mode_of"]
