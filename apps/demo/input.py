"""The demo's input: keys, toolbar presses and gallery taps become actions; touches and the held mouse button
become the finger that drives the plate.

Touches reach the demo as SDL finger events, each at normalised panel coordinates (0..1 across the panel). The
rig's touch panel (:class:`ultraglide.devices.rig.TouchPanel`, ``--rig``) maps them onto the display: turned,
flipped and placed on its active area in mm, then to pixels; without a rig the panel covers the window. Which
finger drives the plate when two are down is the panel's ``drives``: the first down (the default), the latest
down, or none (the plate rests until one lifts); the others are drawn. A held mouse button counts as a finger,
and SDL's mouse events synthesised from touches are ignored so nothing counts twice. Touch pressure × the
panel's pressure full scale sets the force where the panel reports a pressure, the arrow keys otherwise.
"""

from __future__ import annotations

import collections
import time

from ultraglide.apps.demo.options import FORCE_RANGE_N, PRESSURE_FULL_SCALE_N
from ultraglide.devices.rig import TouchPanel

DEFAULT_PANEL = TouchPanel(pressure_full_scale_n=PRESSURE_FULL_SCALE_N)  # the whole window, first finger drives

MOUSE = -1  # the driving "finger" when it is the mouse


class Input:
    """Turns pygame events into the app's actions (``app.act``) and the driving finger's touches (``driver``)."""

    def __init__(self, app, driver: FingerDriver, panel: TouchPanel | None = None):
        self.app = app
        self.pg = app.pg
        self.driver = driver
        self.panel = panel or DEFAULT_PANEL
        self.fingers: dict[int, tuple[float, float]] = {}  # every finger down, px
        self.driving: int | None = None  # the finger (or MOUSE) that drives the plate
        self.keys = {self.pg.K_ESCAPE: "quit", self.pg.K_q: "quit", self.pg.K_g: "gallery", self.pg.K_t: "texture",
                     self.pg.K_w: "widgets", self.pg.K_LEFT: "prev", self.pg.K_RIGHT: "next",
                     self.pg.K_DOWN: "force-", self.pg.K_UP: "force+", self.pg.K_m: "model",
                     self.pg.K_SPACE: "pause", self.pg.K_h: "help",
                     self.pg.K_r: "restart"}

    def handle(self, event) -> None:
        pg, app = self.pg, self.app
        w, h = app.screen.get_size()
        if event.type == pg.QUIT:
            app.running = False
        elif event.type in (pg.WINDOWEXPOSED, pg.VIDEOEXPOSE, pg.WINDOWRESTORED):
            app.redraw.everything()
        elif event.type == pg.KEYDOWN:
            if event.key == pg.K_ESCAPE and app.show_help:
                app.act("help")
            elif event.key in self.keys:
                app.act(self.keys[event.key])
        elif event.type in (pg.FINGERDOWN, pg.FINGERMOTION, pg.FINGERUP):
            self._finger(event, *self.panel_px(event.x, event.y))
        elif event.type in (pg.MOUSEBUTTONDOWN, pg.MOUSEMOTION, pg.MOUSEBUTTONUP):
            if not getattr(event, "touch", False):  # SDL's copy of a touch: the finger events already count it
                self._mouse(event, *event.pos)

    def panel_px(self, u: float, v: float) -> tuple[float, float]:
        """A touch at normalised panel coordinates as pixels of the screen, through the panel's mapping."""
        w, h = self.app.screen.get_size()
        mm_per_px = self.app.mm_per_px
        x_mm, y_mm = self.panel.to_mm(u, v, full_area_mm=(w * mm_per_px, h * mm_per_px))
        return x_mm / mm_per_px, y_mm / mm_per_px

    def _finger(self, event, x: float, y: float) -> None:
        pg = self.pg
        self.app.redraw.area()
        pressure = getattr(event, "pressure", None)
        drives = self.panel.drives
        if event.type == pg.FINGERUP:
            self.fingers.pop(event.finger_id, None)
            if event.finger_id == self.driving:
                self.driving = None
                self.driver.drive(x, y, False)
                if drives == "latest" and self.fingers:  # the newest finger still down takes over
                    self._start(next(reversed(self.fingers)), *self.fingers[next(reversed(self.fingers))], None)
            if drives == "none" and len(self.fingers) == 1 and self.driving is None:  # one left: it drives
                finger, (x_left, y_left) = next(iter(self.fingers.items()))
                self._start(finger, x_left, y_left, None)
            return
        self.fingers[event.finger_id] = (x, y)
        if event.type == pg.FINGERDOWN:
            if drives == "none" and len(self.fingers) > 1:  # two down: none drives, the plate rests
                if self.driving is not None and self.driving != MOUSE:
                    self.driver.drive(*self.fingers.get(self.driving, (x, y)), False)
                    self.driving = None
                return
            takes_over = drives == "latest" and self.driving not in (None, MOUSE)
            if (self.driving is None or takes_over) and not self.press(x, y):
                if takes_over:
                    self.driver.drive(*self.fingers.get(self.driving, (x, y)), False)
                self._start(event.finger_id, x, y, pressure)
        elif event.finger_id == self.driving:
            self.driver.drive(x, y, True, pressure)

    def _mouse(self, event, x: float, y: float) -> None:
        pg = self.pg
        if event.type == pg.MOUSEBUTTONDOWN and event.button == 1 and self.driving is None:
            if not self.press(x, y):
                self._start(MOUSE, x, y, None)
        elif event.type == pg.MOUSEMOTION and self.driving == MOUSE:
            self.driver.drive(x, y, True)
        elif event.type == pg.MOUSEBUTTONUP and event.button == 1 and self.driving == MOUSE:
            self.driving = None
            self.driver.drive(x, y, False)

    def _start(self, finger: int, x: float, y: float, pressure: float | None) -> None:
        self.driving = finger
        self.driver.trace.clear()
        self.driver.drive(x, y, True, pressure)

    def press(self, x_px: float, y_px: float) -> bool:
        """Toolbar buttons, gallery tiles and closing the help; True when the press was for the interface."""
        app = self.app
        if app.show_help:
            app.act("help")
            return True
        button = app.layout.button_at(x_px, y_px)
        if button is not None:
            app.act(button.action)
            return True
        if app.scenes.scene == "gallery":
            tile = app.layout.tile_at(x_px, y_px)
            if tile is not None:
                app.show("texture", tile)
                return True
        app.flip_toggle_at(x_px, y_px)
        return False


def newest_motions(events: list, pg) -> list:
    """``events`` with each burst of motions of one pointer (a finger, or the mouse) cut to its newest: a loop
    that fell behind reads where the finger is now. Handled one by one, the older ones would be stamped now
    too: a jump of millimetres in a millisecond, which the renderer rightly blurs over a wide footprint."""
    motions = (pg.FINGERMOTION, pg.MOUSEMOTION)
    kept, newer = [], set()  # pointers with a newer motion in the burst (walking back from the newest)
    for event in reversed(events):
        pointer = (event.type in (pg.FINGERDOWN, pg.FINGERMOTION, pg.FINGERUP), getattr(event, "finger_id", None),
                   getattr(event, "touch", False))  # SDL's mouse copies of touches apart from a real mouse
        if event.type in motions:
            if pointer in newer:
                continue
            newer.add(pointer)
        elif event.type in (pg.FINGERDOWN, pg.FINGERUP, pg.MOUSEBUTTONDOWN, pg.MOUSEBUTTONUP):
            newer.discard(pointer)  # the motion before a press or a lift is kept
        kept.append(event)
    return kept[::-1]


class FingerDriver:
    """The driving finger's positions to the engine (mm on the texture, a force) and to the recording;
    a finger that lifts or leaves the texture area rests the plate. Counts touches sent and touches made
    before the engine was ready (drawn, not felt)."""

    def __init__(self, app):
        self.app = app
        self.trace: collections.deque = collections.deque()  # (perf_counter s, x px, y px) of the driving finger
        self.pushed = 0
        self.unfelt = 0  # touches made before the engine was ready: drawn, not felt
        self.pressure_seen = False  # set once the panel reports a pressure other than 0 or 1
        self.underruns_at_first_touch: int | None = None

    def drive(self, x_px: float, y_px: float, down: bool, pressure: float | None = None) -> None:
        app = self.app
        now = time.perf_counter()
        app.redraw.activity(now)
        link = app.link
        if link is None:  # the engine is still starting: the touch is drawn, counted, not felt
            self.unfelt += down
            return
        where = app.scenes.to_mm(x_px, y_px) if down else None
        if where is None:
            link.touch(now, 0.0, 0.0, down=False)
            link.pause(True)
            if app.recorder is not None:
                app.recorder.lift(now)
            return
        force = self.force_from(pressure)
        if self.underruns_at_first_touch is None:
            self.underruns_at_first_touch = link.status(0.0).underruns
        link.pause(app.user_paused)
        link.touch(now, where[0], where[1], force)
        self.pushed += 1
        self.trace.append((now, x_px, y_px))
        if app.recorder is not None:
            area = app.layout.area
            geometry = {"screen_px": list(app.screen.get_size()), "mm_per_px": app.mm_per_px,
                        "texture_area_px": [area.left, area.top, area.width, area.height]}
            app.recorder.touch(now, where[0], where[1], app.force_n if force is None else force,
                               app.scenes.current.name, geometry)

    def force_from(self, pressure: float | None) -> float | None:
        """The force for a touch: from the panel's pressure once it has shown it measures one, else None."""
        if pressure is None:
            return None
        if 0.0 < pressure < 1.0:
            self.pressure_seen = True
        if not self.pressure_seen:
            return None  # panels without a sensor report 1.0 (or 0): the arrow keys' force applies
        force = self.app.input.panel.force_n(pressure)
        if force is None:
            return None  # the rig's panel has no pressure scale: the arrow keys' force applies
        return max(FORCE_RANGE_N[0], min(force, FORCE_RANGE_N[1]))

    def fade(self, now: float, span_s: float) -> list[tuple[float, float]]:
        """The trace's points of the last ``span_s`` (older ones dropped), px."""
        while self.trace and now - self.trace[0][0] > span_s:
            self.trace.popleft()
        return [(x, y) for _, x, y in self.trace]
