"""The participant's window: zones side by side at their physical size, answer buttons, breaks.

Every zone is drawn the same plain grey with its number, so only the finger can tell them apart.
The first finger down (or the held mouse button) drives the plate; SDL's mouse copies of touches are
ignored. A tap on an answer button, or a key (1/2/3 in forced choice; Y/N in yes/no), answers; the
reaction time runs from the trial's first frame to the answer (perf_counter s). Esc stops the session
(its log is kept; ``--resume`` continues it).
"""

from __future__ import annotations

import os

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import math  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402

from ultraglide.apps.cli.errors import UsageError  # noqa: E402
from ultraglide.apps.window.screen import DEFAULT_MM_PER_PX, display_available, init_display  # noqa: E402
from ultraglide.apps.window.wait import EventWaiter  # noqa: E402

from ultraglide.experiment.responders import Answer  # noqa: E402

BACKGROUND, ZONE, ZONE_EDGE = (24, 26, 30), (96, 100, 108), (150, 155, 165)
TEXT, BUTTON = (230, 232, 236), (52, 90, 140)
WAIT_S = 0.1  # the longest sleep between looks at the window's events (an event ends it at once)
KEYS_YES, KEYS_NO = ("y",), ("n",)


class WindowResponder:
    """Presents trials in a pygame window and waits for the participant's answer."""

    def __init__(self, config, design, screen_width_mm: float | None = None, windowed: bool = False,
                 size=(1280, 800), output=None):
        import pygame

        self.pg = pygame
        if not display_available():
            raise UsageError("no display for the participant's window (set DISPLAY or run under Xvfb); "
                             "for a dry run give --observer sim:threshold=...")
        try:
            init_display(pygame)
            pygame.font.init()
            self.screen = pygame.display.set_mode(size if windowed else (0, 0), 0 if windowed else pygame.FULLSCREEN)
        except pygame.error as error:
            raise UsageError(f"cannot open a window ({error})") from None
        pygame.display.set_caption("ultraglide experiment")
        self.waiter = EventWaiter(pygame)
        self.config, self.design = config, design
        self.mm_per_px = screen_width_mm / self.screen.get_width() if screen_width_mm else DEFAULT_MM_PER_PX
        self.font = pygame.font.Font(None, 30)
        self.big_font = pygame.font.Font(None, 44)
        if output is None:
            from ultraglide.apps.experiment.output import open_output

            output = open_output(config.device, config.profile, config.model, config.force_n, config.closed_loop)
        self.output = output
        self.ready = threading.Event()  # set while a trial (or a break) waits for input: for tests and logs
        self.touched_s = math.inf  # perf_counter s of the shown trial's first touch on the texture (inf: none yet)
        self.showing: tuple[str, int] = ("", 0)
        self._layout()

    # ---- geometry ------------------------------------------------------------------------------------
    def _layout(self) -> None:
        pg = self.pg
        width_mm, height_mm = self.design.layout.size_mm
        w, h = self.screen.get_size()
        canvas = (round(width_mm / self.mm_per_px), round(height_mm / self.mm_per_px))
        self.canvas = pg.Rect((w - canvas[0]) // 2, max(70, (h - canvas[1]) // 2 - 60), *canvas)
        layout = self.design.layout
        self.zones = []
        for index in range(layout.zones):
            left = self.canvas.left + round(layout.zone_left_mm(index) / self.mm_per_px)
            top = self.canvas.top + round(layout.gap_mm / self.mm_per_px)
            self.zones.append(pg.Rect(left, top, round(layout.zone_mm[0] / self.mm_per_px),
                                      round(layout.zone_mm[1] / self.mm_per_px)))
        labels = [str(i + 1) for i in range(layout.zones)] if self.config.intervals > 1 else ["Yes", "No"]
        self.buttons = []
        top = self.canvas.bottom + 20
        if self.config.intervals > 1:
            for zone, label in zip(self.zones, labels, strict=True):
                self.buttons.append((label, pg.Rect(zone.centerx - 60, top, 120, 70)))
        else:
            centre = self.canvas.centerx
            self.buttons = [("Yes", pg.Rect(centre - 170, top, 150, 70)), ("No", pg.Rect(centre + 20, top, 150, 70))]

    def to_mm(self, x_px: float, y_px: float) -> tuple[float, float] | None:
        """Screen pixels to millimetres on the trial's texture, or None off it."""
        if not self.canvas.collidepoint(x_px, y_px):
            return None
        return (x_px - self.canvas.left) * self.mm_per_px, (y_px - self.canvas.top) * self.mm_per_px

    # ---- drawing -------------------------------------------------------------------------------------
    def _text(self, text: str, centre: tuple[int, int], font=None) -> None:
        surface = (font or self.font).render(text, True, TEXT)
        self.screen.blit(surface, surface.get_rect(center=centre))

    def _progress(self, trial: int, total: int) -> str:
        return f"Trial {trial} of {total}"

    def _draw_trial(self, trial: int) -> None:
        pg, screen = self.pg, self.screen
        screen.fill(BACKGROUND)
        total = self.config.total_trials
        self._text(self._progress(trial, total), (screen.get_width() // 2, 24))
        self._text(self.config.question, (screen.get_width() // 2, 56))
        for index, zone in enumerate(self.zones):
            pg.draw.rect(screen, ZONE, zone)
            pg.draw.rect(screen, ZONE_EDGE, zone, 2)
            if self.config.intervals > 1:
                self._text(str(index + 1), (zone.centerx, zone.top + 24), self.big_font)
        for label, rect in self.buttons:
            pg.draw.rect(screen, BUTTON, rect, border_radius=10)
            self._text(label, rect.center, self.big_font)
        pg.display.flip()

    def _draw_break(self, trial: int) -> None:
        self.screen.fill(BACKGROUND)
        centre = self.screen.get_rect().center
        self._text("Take a break", (centre[0], centre[1] - 40), self.big_font)
        self._text(f"{trial - 1} of {self.config.total_trials} trials done. Tap or press space to go on.",
                   (centre[0], centre[1] + 10))
        self.pg.display.flip()

    # ---- input ---------------------------------------------------------------------------------------
    def _events(self):
        """Pending events; when there are none, a sleep until one comes, so input reaches the plate at once and a
        window waiting for an answer takes next to no CPU (looking every millisecond took 2-3 % of a core)."""
        pg = self.pg
        events = pg.event.get()
        if not events:
            first = self.waiter.wait(WAIT_S)
            if first.type != pg.NOEVENT:
                events = [first, *pg.event.get()]
        if any(event.type in (pg.WINDOWEXPOSED, pg.VIDEOEXPOSE) for event in events):
            self._redraw()
        return events

    def _redraw(self) -> None:
        """Draw again what is shown: an X server without backing store keeps no copy of a window that was hidden,
        or mapped after its first frame was drawn (a busy machine), and asks for it with an expose event."""
        what, number = self.showing
        if what == "trial":
            self._draw_trial(number)
        elif what == "break":
            self._draw_break(number)

    def _point(self, event) -> tuple[str, float, float] | None:
        """(phase, x px, y px) of a finger or left-mouse event; None for anything else."""
        pg = self.pg
        w, h = self.screen.get_size()
        if event.type in (pg.FINGERDOWN, pg.FINGERMOTION, pg.FINGERUP):
            phase = {pg.FINGERDOWN: "down", pg.FINGERMOTION: "move", pg.FINGERUP: "up"}[event.type]
            return phase, event.x * w, event.y * h
        if event.type in (pg.MOUSEBUTTONDOWN, pg.MOUSEMOTION, pg.MOUSEBUTTONUP):
            if getattr(event, "touch", False):
                return None  # SDL's copy of a touch
            if event.type == pg.MOUSEMOTION:
                return ("move", *event.pos) if event.buttons[0] else None
            if getattr(event, "button", 1) != 1:
                return None
            return ("down" if event.type == pg.MOUSEBUTTONDOWN else "up", *event.pos)
        return None

    def _answer_for(self, x: float, y: float) -> int | None:
        for index, (_, rect) in enumerate(self.buttons):
            if rect.collidepoint(x, y):
                return index if self.config.intervals > 1 else int(index == 0)  # yes/no: Yes is 1
        return None

    def _key_answer(self, key) -> int | None:
        name = self.pg.key.name(key)
        if self.config.intervals > 1:
            if name.isdigit() and 1 <= int(name) <= self.config.intervals:
                return int(name) - 1
            return {"left": 0, "right": self.config.intervals - 1}.get(name)
        return 1 if name in KEYS_YES else 0 if name in KEYS_NO else None

    def present(self, trial: int, level: float, target: int, design) -> Answer:
        """Show the trial and wait for the answer; the answer carries what the trial played (target and measured
        friction, commanded amplitude, the friction loop's state) where the output says."""
        self.output.show(design.trial_texture(level, target), trial)
        answer = self._wait_answer(trial)
        friction = getattr(self.output, "trial_friction", None)
        if friction is not None and not answer.quit:
            answer.friction = friction(self.touched_s)
        return answer

    def _wait_answer(self, trial: int) -> Answer:
        pg = self.pg
        pg.event.clear()
        self._draw_trial(trial)
        shown = time.perf_counter()
        self.showing = ("trial", trial)
        self.touched_s = math.inf  # the trial's first touch on the texture: what it played is counted from there
        self.ready.set()
        finger_down = False
        try:
            while True:
                for event in self._events():
                    now = time.perf_counter()
                    if event.type == pg.QUIT or (event.type == pg.KEYDOWN and event.key == pg.K_ESCAPE):
                        self.output.touch(now, 0.0, 0.0, down=False)
                        return Answer(-1, now - shown, quit=True)
                    if event.type == pg.KEYDOWN:
                        answer = self._key_answer(event.key)
                        if answer is not None:
                            self.output.touch(now, 0.0, 0.0, down=False)
                            return Answer(answer, now - shown)
                    point = self._point(event)
                    if point is None:
                        continue
                    phase, x, y = point
                    if phase == "down":
                        answer = self._answer_for(x, y)
                        if answer is not None:
                            self.output.touch(now, 0.0, 0.0, down=False)
                            return Answer(answer, now - shown)
                        finger_down = True
                    if not finger_down:
                        continue
                    where = self.to_mm(x, y) if phase != "up" else None
                    if where is None:
                        self.output.touch(now, 0.0, 0.0, down=False)
                    else:
                        self.touched_s = min(self.touched_s, now)
                        self.output.touch(now, where[0], where[1])
                    if phase == "up":
                        finger_down = False
        finally:
            self.ready.clear()

    def take_break(self, trial: int) -> bool:
        """A pause screen until a tap, a click or space; False if Esc ends the session instead."""
        pg = self.pg
        pg.event.clear()
        self._draw_break(trial)
        self.showing = ("break", trial)
        self.ready.set()
        try:
            while True:
                for event in self._events():
                    if event.type == pg.QUIT or (event.type == pg.KEYDOWN and event.key == pg.K_ESCAPE):
                        return False
                    if event.type == pg.KEYDOWN and event.key == pg.K_SPACE:
                        return True
                    point = self._point(event)
                    if point is not None and point[0] == "down":
                        return True
        finally:
            self.ready.clear()

    def close(self) -> None:
        try:
            self.output.stop()
        finally:
            self.pg.display.quit()
