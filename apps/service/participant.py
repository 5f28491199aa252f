"""The service in a participant's mode: a design's trials presented on a page, answered with its buttons.

:class:`ParticipantService` is :class:`apps.service.server.Service` (the same handshake: the served page's origin
only, the token where one is needed; the same touches: a ``touch`` message goes through
:meth:`Service._touch` to the engine) with its own page (``/``: ``participant.html``) and three messages of
its own, and nothing else a participant's page could change: the scene is the trial's, set by the session.

Server to page (pushed to the controlling page, and again to a page that reconnects):

* ``participant.trial``: ``trial``, ``total``, ``mode`` (``choice``, ``yes_no``, ``pair``, ``rating``,
  ``magnitude`` or ``adjustment``), ``question``, ``labels``, ``size_mm`` (the plate's area, [w, h]), ``zones`` (each
  ``{x_mm, y_mm, width_mm, height_mm}`` from the area's top-left corner), ``numbered`` (zones show their number);
  an adjustment's also ``level`` (its start), ``range`` ([low, high], the levels it may be set to) and ``step_db``
  (a button's or a key's step, dB);
* ``participant.break``: ``trial`` (the next one), ``message``, ``label`` (the button's);
* ``participant.wait``: ``message`` (between trials, before the first);
* ``participant.end``: ``message``: the session is over (the page says it, and stops reconnecting).

Page to server:

* ``participant.answer``: ``trial``, ``button`` (the index of the button pressed, from 0) or ``value`` (the number
  typed, magnitude estimation; the level set, adjustment), ``rt_s`` (the page's reaction time, s); answered ``ok``,
  or an error naming what is wrong (a stale trial, a button that is not there, a level that is not the one set);
* ``participant.adjust``: ``trial``, ``level`` (within the trial's ``range``): the adjusted zone at that level,
  answered (``ok`` with ``trial`` and ``level``) once the engine plays it, or with the level a later adjustment
  set in its place.
* ``participant.continue``: ``trial``: the break's button.
* ``participant.stop``: ``trial`` (the one shown, or the next after a break): Esc, the session stops as at the
  window's Esc (its files complete, status ``stopped``).

The screens carry the participant's words from the design (``[words]``, English by default): a trial's
``progress`` and ``keys`` (the hint line), a magnitude estimate's ``ok`` (its button), a break's ``keys``, the end's
``message``; trials and breaks the design's ``language`` (the page's ``lang``).
"""

from __future__ import annotations

import asyncio
import queue
import time

from ultraglide.apps.service import protocol as p
from ultraglide.apps.service.server import DEFAULT_VIEW, HTML, Service

PARTICIPANT_FILES = {"/": ("participant.html", HTML), "/index.html": ("participant.html", HTML),
                     "/ultraglide.js": ("ultraglide.js", "text/javascript; charset=utf-8"),
                     "/participant.js": ("participant.js", "text/javascript; charset=utf-8")}
MAX_RT_S = 86400.0
PARTICIPANT_SPECS = {
    "participant.answer": {"trial": (p._integer(1, 10**9), True), "button": (p._integer(0, 1000), False),
                           "value": (p._number(0.0, 1e12), False), "rt_s": (p._number(0.0, MAX_RT_S, " s"), True)},
    "participant.continue": {"trial": (p._integer(1, 10**9), True)},
    "participant.adjust": {"trial": (p._integer(1, 10**9), True), "level": (p._number(0.0, 1e12), True)},
    "participant.stop": {"trial": (p._integer(1, 10**9), True)},
}
ALLOWED = frozenset({"hello", "touch", "subscribe", "state", *PARTICIPANT_SPECS})
LEFT, BACK, STOP = "left", "back", "stop"


class ParticipantService(Service):
    """The service of a session's participant page. ``events``: a thread-safe queue the session reads:
    ``("answer", trial, button or None, value or None, rt_s, received perf_counter s)``, ``("continue", trial)``,
    ``("adjust", trial)`` when the page set an adjustment's level (:attr:`adjusted`: the latest), ``("stop", trial)``
    when the participant pressed Esc,
    ``("left",)`` when the controlling page goes and ``("back",)`` when one takes control again."""

    def __init__(self, engine, profile, *, token: str | None = None, view_mm=(160.0, 100.0)):
        super().__init__(engine, profile, token=token, page=True, view_mm=tuple(view_mm))
        self.page_files = PARTICIPANT_FILES
        self.extra_specs = PARTICIPANT_SPECS
        self.events: queue.Queue = queue.Queue()
        self.screen: dict = {"type": "participant.wait", "message": ""}
        self.waiting_for: tuple[str, int] | None = None  # ("answer" | "continue", trial) while one is awaited
        self.adjusted: float | None = None  # an adjustment trial's level, the latest the page set
        self._adjust_waiters: list[asyncio.Future] = []  # adjust requests answered once their level plays

    # ---- what the session shows (called on the loop, through call_soon_threadsafe) -------------------------
    def show(self, screen: dict, view_mm: tuple[float, float] | None = None, awaited: tuple | None = None) -> None:
        """Show ``screen`` on the controlling page (and on any that connects later); ``view_mm``: the trial's area
        (the view the touches are in, mm); ``awaited``: what the session waits for now."""
        from ultraglide.apps.service.scene import View

        self._lift(time.perf_counter())
        if view_mm is not None:
            self.views[DEFAULT_VIEW] = View(DEFAULT_VIEW, view_mm[0], view_mm[1], "mm", view_mm[0], view_mm[1])
        self.screen = screen
        self.waiting_for = awaited
        self.adjusted = screen.get("level") if screen.get("mode") == "adjustment" else None
        self.applied(None)
        if self.controller is not None:
            self.controller.send(screen, push=True)

    # ---- messages ------------------------------------------------------------------------------------------
    def _dispatch(self, session, message: p.Message, received_s: float) -> None:
        if message.type not in ALLOWED:
            raise p.ProtocolError(p.READ_ONLY, f"{message.type}: a participant's page touches and answers; the "
                                  "session sets the scene")
        if message.type.startswith("participant.") and session is not self.controller:
            raise p.ProtocolError(p.READ_ONLY, "only the participant's page (the controlling client) answers")
        super()._dispatch(session, message, received_s)

    def _hello(self, session, message: p.Message) -> dict:
        had = self.controller
        welcome = super()._hello(session, message)
        if self.controller is session and had is not session:
            screen = self.screen  # an adjustment's at the level set last, which the plate plays
            if screen.get("mode") == "adjustment" and self.adjusted is not None:
                screen = {**screen, "level": self.adjusted}
            asyncio.get_running_loop().call_soon(session.send, screen, True)  # after the welcome
            self.events.put((BACK,))
        return welcome

    def _leave(self, session) -> None:
        was = self.controller is session
        super()._leave(session)
        if was:
            self.events.put((LEFT,))

    def _on_participant_answer(self, session, message: p.Message) -> dict:
        trial = message["trial"]
        if self.waiting_for != ("answer", trial):
            raise p.ProtocolError(p.BAD_MESSAGE, f"participant.answer: trial {trial} is not the one awaiting an "
                                  "answer")
        mode = self.screen.get("mode")
        button, value = message.get("button"), message.get("value")
        if mode == "adjustment":
            if value is None or button is not None or value != self.adjusted:
                raise p.ProtocolError(p.BAD_MESSAGE, f"participant.answer: an adjustment's answer is its 'value', "
                                      f"the level set last ({self.adjusted!r})")
        elif mode == "magnitude":
            if value is None or button is not None:
                raise p.ProtocolError(p.BAD_MESSAGE, "participant.answer: a magnitude estimate is a 'value' (a "
                                      "number from 0)")
        else:
            labels = self.screen.get("labels", [])
            if button is None or value is not None or button >= len(labels):
                raise p.ProtocolError(p.BAD_MESSAGE, f"participant.answer: give 'button', from 0 to "
                                      f"{len(labels) - 1}")
        self.waiting_for = None
        self._lift(time.perf_counter())
        self.events.put(("answer", trial, button, value, message["rt_s"], time.perf_counter()))
        return {"trial": trial}

    def _on_participant_adjust(self, session, message: p.Message):
        trial, level = message["trial"], message["level"]
        if self.waiting_for != ("answer", trial) or self.screen.get("mode") != "adjustment":
            raise p.ProtocolError(p.BAD_MESSAGE, f"participant.adjust: trial {trial} is not an adjustment awaiting "
                                  "its answer")
        low, high = self.screen["range"]
        if not low <= level <= high:
            raise p.ProtocolError(p.BAD_MESSAGE, f"participant.adjust: 'level' must be from {low:g} to {high:g}")
        self.adjusted = level
        waiter = asyncio.get_running_loop().create_future()
        self._adjust_waiters.append(waiter)
        self.events.put(("adjust", trial))
        return self._adjust_reply(trial, waiter)

    async def _adjust_reply(self, trial: int, waiter: asyncio.Future) -> dict:
        level = await waiter
        if level is None:
            raise p.ProtocolError(p.BAD_MESSAGE, f"participant.adjust: trial {trial} ended before its level played")
        return {"trial": trial, "level": level}

    def applied(self, level: float | None) -> None:
        """The engine plays the adjustment at ``level``: every adjust request waiting is answered with it (None: the
        trial is over, they are refused). Called on the loop."""
        waiters, self._adjust_waiters = self._adjust_waiters, []
        for waiter in waiters:
            if not waiter.done():
                waiter.set_result(level)

    def _on_participant_stop(self, session, message: p.Message) -> dict:
        trial = message["trial"]
        if self.waiting_for is None or self.waiting_for[1] != trial:
            raise p.ProtocolError(p.BAD_MESSAGE, f"participant.stop: trial {trial} (or the break before it) is not "
                                  "shown now")
        self.waiting_for = None
        self._lift(time.perf_counter())
        self.events.put((STOP, trial))
        return {"trial": trial}

    def _on_participant_continue(self, session, message: p.Message) -> dict:
        trial = message["trial"]
        if self.waiting_for != ("continue", trial):
            raise p.ProtocolError(p.BAD_MESSAGE, f"participant.continue: no break before trial {trial} now")
        self.waiting_for = None
        self.events.put(("continue", trial))
        return {"trial": trial}


__all__ = ["ParticipantService", "PARTICIPANT_SPECS"]
