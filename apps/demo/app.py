"""``ultraglide demo``: feel textures on the plate under a touch panel (pygame). The app and its loop.

Scenes (:mod:`~ultraglide.apps.demo.scenes`): a gallery of textures, one texture at its physical size, and
widgets laid out for the screen. Input (:mod:`~ultraglide.apps.demo.input`): the first finger down, or the
held mouse button, drives the plate; keys and the toolbar act.

The window comes first: the gallery is drawn, then the real-time engine (renderer and device in their
own process) starts from a thread and compiles its kernels while the gallery is on screen; touches
before it is ready are drawn, counted and not felt. The loop sleeps in SDL (``demo.wait``) and
redraws only what changed (:class:`Redraw`): the texture area while a finger moves or its trace fades,
the chart while the plate is active, the status line when its words change. All contact with the
renderer and the device goes through :class:`ultraglide.apps.demo.link.DemoLink`. With ``watch``, texture
files (and the images they were authored from) are polled every 200 ms and reloaded when they change.
Every way out rests the plate.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.signals import held
from ultraglide.apps.demo.felt import FeltContrast
from ultraglide.apps.demo.input import FingerDriver, Input, newest_motions
from ultraglide.apps.demo.layout import Layout
from ultraglide.apps.demo.link import DemoLink, LinkConfig, LinkStarter
from ultraglide.apps.demo.options import (
    FORCE_RANGE_N,
    START_FORCE_N,
    DemoOptions,
    load_textures,
    model_cycle,
    seconds_since_launch,
)
from ultraglide.apps.demo.painter import CHART_SPAN_S, Painter
from ultraglide.apps.demo.record import TouchRecorder
from ultraglide.apps.demo.scenes import Scenes
from ultraglide.apps.demo.stats import run_stats, write_stats
from ultraglide.apps.demo.status import status_words
from ultraglide.apps.window.screen import DEFAULT_MM_PER_PX, init_display
from ultraglide.apps.window.wait import EventWaiter
from ultraglide.render.physics.default_model import DEFAULT_MODEL

AREA_FRAME_S = 1 / 60  # the texture area while a finger moves or its trace fades
CHART_FRAME_S = 1 / 20  # the chart while the plate is active
STATUS_S = 0.25  # the status line's words are checked this often
IDLE_WAIT_S = 0.5  # the longest the loop sleeps when nothing moves


@dataclass
class Redraw:
    """What is due to be drawn again, and when (perf_counter s)."""

    all: bool = True  # the whole screen
    area_moved: bool = False
    active_until: float = 0.0  # the chart scrolls until then
    next_area: float = 0.0
    next_chart: float = 0.0
    next_status: float = 0.0

    def everything(self) -> None:
        self.all = True

    def area(self) -> None:
        self.area_moved = True

    def activity(self, now: float) -> None:
        """A touch: the texture area moves, the chart scrolls for its span."""
        self.active_until = now + CHART_SPAN_S + 0.2
        self.area_moved = True

    def drawn_all(self, now: float) -> None:
        self.all = False
        self.next_area, self.next_chart, self.next_status = now + AREA_FRAME_S, now + CHART_FRAME_S, now + STATUS_S


class DemoApp:
    """The demo's state and loop; ``step()`` handles pending events and redraws what is due."""

    def __init__(self, texture_specs=(), device_url="sim", profile="sim-plate", model=DEFAULT_MODEL,
                 screen_width_mm: float | None = None, windowed: bool = False, size=(1280, 800),
                 record: str | None = None, report_frames: bool = False, watch: bool = False,
                 closed_loop: bool = False, finger=None, effects: str | None = None, touch_panel=None):
        """``closed_loop``: the friction loop on the plate's force sensors; ``finger``: a FingerConfig for the
        simulated finger on ``sim`` (render.engine.finger_setup); ``effects``: a file of temporal effects the
        textures given play instead of their own; ``touch_panel``: the rig's
        :class:`~ultraglide.devices.rig.TouchPanel` (None: the panel covers the window, the first finger drives,
        pressure 1.0 is 2 N)."""
        self.options = DemoOptions(tuple(texture_specs), device_url, profile, model, screen_width_mm, windowed,
                                   tuple(size), record, report_frames, watch)
        self.options.check()
        # bad files fail here, before a window opens
        textures, self.texture_files = load_textures(texture_specs, effects)
        import pygame

        self.pg = pygame
        try:
            init_display(pygame)
            pygame.font.init()
            flags = 0 if windowed else pygame.FULLSCREEN
            self.screen = pygame.display.set_mode((0, 0) if not windowed else size, flags)
        except pygame.error as error:
            raise UsageError(f"cannot open a window ({error}); to render without a screen use "
                             "`ultraglide export`") from None
        pygame.display.set_caption("ultraglide demo")
        self.mm_per_px = screen_width_mm / self.screen.get_width() if screen_width_mm else DEFAULT_MM_PER_PX
        self.waiter = EventWaiter(pygame)
        self.model_name = model
        self.model_cycle = model_cycle(model)  # what the M key steps through
        self.force_n = START_FORCE_N
        self.user_paused = False
        self.show_help = False
        self.running = True
        self.watcher = None
        self.watch_errors: list[str] = []
        self._next_watch = 0.0
        self.link: DemoLink | None = None
        self.losses: list = []  # each engine lost over the run (render.engine.supervisor.EngineLoss), oldest first
        self.lost_status = None  # the lost engine's last status, for the run's report
        self.recorder: TouchRecorder | None = None
        self._closed = False
        self.final_status = None  # the engine's last status, once stopped
        self.redraw = Redraw()
        self.painter = Painter(self)
        self.layout = Layout(pygame, self.screen.get_size(), self.painter.font.get_linesize(), len(textures))
        self.scenes = Scenes(textures, self.layout.area, self.mm_per_px)
        if texture_specs:  # the user's own textures: the first is on screen at once, ready to feel and record
            self.scenes.show("texture", 0)
        self.driver = FingerDriver(self)
        self.felt = FeltContrast()  # the contrast a finger keeps at its speed, with a dynamic model
        self.input = Input(self, self.driver, touch_panel)
        self.painter.make_thumbnails()
        try:  # last, so that nothing above can leave a recording behind
            self.recorder = TouchRecorder(record) if record else None
        except OSError as error:
            raise UsageError(f"cannot write the recording {record}: {error.strerror}") from None
        self.painter.everything()  # the first frame, before anything heavy is imported
        self.redraw.drawn_all(time.perf_counter())
        self.link_config = LinkConfig(textures[0], model, profile, device_url, closed_loop, finger)
        self.starter: LinkStarter | None = LinkStarter(self.link_config)
        if watch:
            from ultraglide.apps.demo.watch import TextureWatcher

            self.watcher = TextureWatcher(self.texture_files)

    # ---- what tests and scripts read -------------------------------------------------------------
    @property
    def textures(self):
        return self.scenes.textures

    @property
    def scene(self) -> str:
        return self.scenes.scene

    @property
    def widgets(self):
        return self.scenes.widgets

    @property
    def area(self):
        return self.layout.area

    @property
    def buttons(self):
        return self.layout.buttons

    @property
    def tiles(self):
        return self.layout.tiles

    @property
    def font(self):
        return self.painter.font

    @property
    def fingers(self) -> dict:
        return self.input.fingers

    @property
    def driving(self) -> int | None:
        return self.input.driving

    @property
    def pushed(self) -> int:
        return self.driver.pushed

    @property
    def unfelt(self) -> int:
        return self.driver.unfelt

    def status_words(self) -> str:
        return status_words(self)

    # ---- the engine --------------------------------------------------------------------------------
    def wait_ready(self, timeout_s: float = 120.0) -> DemoLink:
        """Block until the engine runs (for scripts and tests); raises what starting it raised."""
        link = self.starter.wait(timeout_s)
        if link is None:
            raise TimeoutError(f"the engine did not start within {timeout_s:g} s")
        self._adopt(link)
        return link

    def _adopt(self, link: DemoLink) -> None:
        if self.link is None:
            self.link = link
            link.set_force(self.force_n)
            if self.model_name != link.model_name:
                link.set_model(self.model_name)
            if self.scenes.scene != "gallery" and self.scenes.current is not link.config.texture:
                link.set_texture(self.scenes.current)
            self.redraw.everything()  # the chart's scale and the status come from the device's profile now
            if self.options.report_frames:
                print(f"renderer ready {seconds_since_launch():.2f} s after launch "
                      f"({self.driver.unfelt} touches before it, not felt)", flush=True)

    def _check_link(self) -> None:
        if self.link is None and self.starter is not None and self.starter.ready.is_set():
            self._adopt(self.starter.wait())
        elif self.link is not None and self.link.loss is not None:  # its process died or froze
            # (the device is safe already: its supervisor saw to it); said, and a restart offered
            link, self.link, self.starter = self.link, None, None
            self.losses.append(link.loss)
            self.lost_status = link.stop()
            self.redraw.everything()
            for line in link.loss.lines(link.engine.started_s):
                print(f"ultraglide demo: {line}", flush=True)

    @property
    def engine_lost(self):
        """The engine's loss while no engine runs (the status line offers R to restart), else None."""
        return self.losses[-1] if self.losses and self.link is None and self.starter is None else None

    def restart_engine(self) -> None:
        """Start a new engine after a loss (R): the scene, model and force come back to it when it is ready."""
        if self.engine_lost is not None:
            self.starter = LinkStarter(self.link_config)
            self.redraw.everything()

    # ---- actions -----------------------------------------------------------------------------------
    def show(self, scene: str, index: int | None = None) -> None:
        self.scenes.show(scene, index)
        self.driver.trace.clear()
        self.redraw.everything()
        if scene != "gallery" and self.link is not None:
            self.link.set_texture(self.scenes.current)

    def flip_toggle_at(self, x_px: float, y_px: float) -> None:
        flipped = self.scenes.flip_toggle_at(x_px, y_px)
        if flipped is not None:
            old, new = flipped
            self.painter.forget(old)
            self.redraw.everything()
            if self.link is not None:
                self.link.set_texture(new)

    def act(self, action: str) -> None:
        """A key's or a toolbar button's action."""
        self.redraw.everything()
        if action in ("gallery", "texture", "widgets"):
            self.show(action)
        elif action in ("prev", "next"):
            self.show("texture", self.scenes.index + (1 if action == "next" else -1))
        elif action in ("force-", "force+"):
            force = self.force_n * (1.25 if action == "force+" else 0.8)
            self.force_n = min(max(force, FORCE_RANGE_N[0]), FORCE_RANGE_N[1])
            if self.link is not None:
                self.link.set_force(self.force_n)
        elif action == "model":
            cycle = self.model_cycle
            self.model_name = cycle[(cycle.index(self.model_name) + 1) % len(cycle)]
            if self.link is not None:
                self.link.set_model(self.model_name)
        elif action == "pause":
            self.user_paused = not self.user_paused
            if self.link is not None:
                self.link.pause(self.user_paused or self.input.driving is None)
        elif action == "help":
            self.show_help = not self.show_help
        elif action == "restart":
            self.restart_engine()
        elif action == "quit":
            self.running = False

    def _watch(self) -> None:
        """Every 200 ms with ``--watch``: reload the textures whose files changed; the plate feels the one shown."""
        now = time.perf_counter()
        if self.watcher is None or now < self._next_watch:
            return
        from ultraglide.apps.demo.watch import POLL_S

        self._next_watch = now + POLL_S
        reloaded = self.watcher.poll()
        self.watch_errors = self.watcher.errors
        for index, texture in reloaded:
            self.painter.replaced(index, self.scenes.replace(index, texture))
            self.redraw.everything()
            if self.link is not None and self.scenes.scene == "texture" and self.scenes.index == index:
                self.link.set_texture(texture)
            path = self.texture_files[index][0]
            print(f"ultraglide demo: reloaded {path} ({texture.name})", flush=True)  # in the editor's terminal too

    # ---- the loop --------------------------------------------------------------------------------
    def _area_moving(self) -> bool:
        return self.scenes.scene != "gallery" and bool(self.redraw.area_moved or self.driver.trace
                                                       or self.input.fingers)

    def frame(self) -> None:
        """Redraw what is due: everything after a change of scene, else only the parts that move."""
        redraw, painter = self.redraw, self.painter
        if redraw.all:
            painter.everything()
            redraw.drawn_all(time.perf_counter())
            return
        if self.show_help:
            return  # the panel covers the middle; everything is redrawn when it closes
        now = time.perf_counter()
        changed = []
        if self._area_moving() and now >= redraw.next_area:
            redraw.area_moved = False
            painter.area()
            changed.append(self.layout.area)
            redraw.next_area = now + AREA_FRAME_S
        if now < redraw.active_until and now >= redraw.next_chart:
            painter.chart()
            changed.append(self.layout.chart_rect)
            redraw.next_chart = now + CHART_FRAME_S
        if now >= redraw.next_status:
            if painter.status():
                changed.append(self.layout.status_rect)
            redraw.next_status = now + STATUS_S
        if changed:
            self.pg.display.update(changed)

    def _wait_s(self) -> float:
        """How long the loop may sleep waiting for an event before something is due."""
        now = time.perf_counter()
        due = [self.redraw.next_status]
        if self._area_moving():
            due.append(self.redraw.next_area)
        if now < self.redraw.active_until:
            due.append(self.redraw.next_chart)
        if self.link is None:
            due.append(now + 0.05)  # look for the engine having started
        if self.watcher is not None:
            due.append(self._next_watch)
        return min(max(min(due) - now, 0.001), IDLE_WAIT_S)

    def step(self, wait_s: float = 0.0) -> None:
        """Handle the events that arrive within ``wait_s`` (0: only those pending), then redraw what is due."""
        pg = self.pg
        self._check_link()
        self._watch()
        event = self.waiter.wait(wait_s) if wait_s > 0 else pg.event.poll()
        pending = []
        while event.type != pg.NOEVENT:
            pending.append(event)
            event = pg.event.poll()
        for event in newest_motions(pending, pg):
            self.input.handle(event)
        self.frame()

    def run(self) -> None:
        while self.running:
            self.step(self._wait_s())

    def close(self) -> None:
        """Rest the plate, finish the recording and close the window; safe to call more than once."""
        if self._closed:
            return
        self._closed = True
        try:
            link = self.link
            if link is None and getattr(self, "starter", None) is not None:
                self.starter.ready.wait(60)
                link = self.starter.link
            if link is not None:
                self.final_status = link.stop()
        finally:
            if self.recorder is not None:
                saved = self.recorder.close()
                print(f"recorded {self.recorder.rows} touches to {saved}" if saved else
                      "recorded fewer than two touches: no touch log written", file=sys.stderr)
            self.pg.display.quit()


def run(args) -> int:
    if args.stats and Path(args.stats).suffix.lower() != ".json":
        raise UsageError(f"--stats needs a .json file, got {args.stats}")
    from ultraglide.apps.commands.finger_options import finger_config
    from ultraglide.apps.commands.plate_choice import display_width_mm

    app = DemoApp(args.textures, args.device, args.profile, args.model, display_width_mm(args), args.windowed,
                  record=args.record, report_frames=args.report_frames, watch=args.watch,
                  closed_loop=args.closed_loop, finger=finger_config(args), effects=args.effects,
                  touch_panel=args.loaded_rig.touch if getattr(args, "loaded_rig", None) is not None else None)
    try:
        app.run()
    finally:
        with held():  # a second Ctrl-C or SIGTERM does not cut this short
            app.close()  # window closed, Escape, Ctrl-C or an exception: the plate comes to rest
    final = app.final_status or app.lost_status
    if args.stats:
        write_stats(args.stats, run_stats(app, final))
    return say_report(final, app.losses)


def say_report(final, losses=()) -> int:
    """What happened to a plate driver over the run, in words, if anything did, and each engine lost (its
    process died or froze); the exit status it earns."""
    from ultraglide.devices.serial.run_report import RunReport

    report = RunReport.from_dict((getattr(final, "device_status", None) or {}).get("report"))
    for loss in reversed(losses):
        report = report.with_lines(loss.lines(), loss.exit_status)
    if report.exit_status:
        for line in report.lines:
            print(line)
        print(f"ultraglide demo: {report.verdict}", file=sys.stderr)
    return report.exit_status
