"""The participant's guide during an on-plate calibration, in a window like the demo's.

It says what to do ("slide here at a steady press"), shows the press now against the one asked for (a bar in
newtons with the asked band, and "press lighter" / "press heavier" / "steady"), which press of how many, and
how far the plan has gone. Esc cancels. :class:`TextGuide` says the same on a terminal, a line a press, for
``--no-window`` runs (scripts, the simulated finger).
"""

from __future__ import annotations

import math
import os
import sys

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

BACKGROUND, AREA, AREA_EDGE = (24, 26, 30), (60, 64, 72), (150, 155, 165)
TEXT, GOOD, FAR, BAND = (230, 232, 236), (90, 190, 110), (230, 150, 60), (70, 110, 160)
BAND_SHARE = 0.25  # the press is "steady" within ±25 % of the asked force
BAR_FULL_N = 1.5


def advice(force_n: float, asked_n: float, sliding: bool) -> str:
    """What to tell the participant about the press now."""
    if math.isnan(force_n) or force_n < 0.05:
        return "put your finger on the plate and slide"
    if force_n < asked_n * (1 - BAND_SHARE):
        return "press heavier"
    if force_n > asked_n * (1 + BAND_SHARE):
        return "press lighter"
    return "steady: keep sliding" if sliding else "keep sliding"


class TextGuide:
    """The guide on a terminal: one line when the asked press changes, and at the end."""

    def __init__(self, participant: str, stream=None):
        self.participant = participant
        self.stream = stream or sys.stderr
        self._level = None

    def show(self, level: int, levels: int, asked_n: float, force_n: float, sliding: bool, done: float) -> bool:
        if level != self._level:
            self._level = level
            print(f"press {level + 1} of {levels}: slide at a steady {asked_n:g} N", file=self.stream, flush=True)
        return True

    def close(self) -> None:
        pass


class WindowGuide:
    """The guide in a window (full screen unless ``windowed``); :meth:`show` draws a frame and returns False once
    the participant pressed Esc or closed the window."""

    def __init__(self, participant: str, windowed: bool = False, size=(1280, 800)):
        import pygame
        from ultraglide.apps.cli.errors import UsageError
        from ultraglide.apps.window.screen import display_available, init_display

        if not display_available():
            raise UsageError("no display for the calibration's window (set DISPLAY or run under Xvfb); "
                             "with a simulated finger give --no-window")
        self.pg = pygame
        try:
            init_display(pygame)
            pygame.font.init()
            self.screen = pygame.display.set_mode(size if windowed else (0, 0), 0 if windowed else pygame.FULLSCREEN)
        except pygame.error as error:
            raise UsageError(f"cannot open a window ({error})") from None
        pygame.display.set_caption(f"ultraglide calibration: participant {participant}")
        self.participant = participant
        self.font = pygame.font.Font(None, 32)
        self.big = pygame.font.Font(None, 56)
        self.frames = 0
        self._shown = None  # what the last frame showed: drawn again only when it changes (the plate's threads
        # share this process)

    def show(self, level: int, levels: int, asked_n: float, force_n: float, sliding: bool, done: float) -> bool:
        pg = self.pg
        for event in pg.event.get():
            if event.type == pg.QUIT or (event.type == pg.KEYDOWN and event.key == pg.K_ESCAPE):
                return False
        shown = (level, round(asked_n, 3), None if math.isnan(force_n) else round(force_n, 2), sliding,
                 round(done, 2))
        if shown == self._shown:
            return True
        self._shown = shown
        screen = self.screen
        w, h = screen.get_size()
        screen.fill(BACKGROUND)
        area = pg.Rect(w // 10, h // 6, w * 8 // 10, h // 2)
        pg.draw.rect(screen, AREA, area, border_radius=12)
        pg.draw.rect(screen, AREA_EDGE, area, 2, border_radius=12)
        self._centre("slide here at a steady press", self.big, TEXT, area.center)
        words = advice(force_n, asked_n, sliding)
        colour = GOOD if words.startswith("steady") else FAR
        self._centre(words, self.font, colour, (area.centerx, area.bottom - 40))
        bar = pg.Rect(area.left, area.bottom + 40, area.width, 28)
        pg.draw.rect(screen, AREA, bar)
        scale = bar.width / BAR_FULL_N
        low, high = asked_n * (1 - BAND_SHARE), asked_n * (1 + BAND_SHARE)
        pg.draw.rect(screen, BAND, pg.Rect(bar.left + round(low * scale), bar.top, round((high - low) * scale),
                                           bar.height))
        if not math.isnan(force_n):
            x = bar.left + round(min(max(force_n, 0.0), BAR_FULL_N) * scale)
            pg.draw.rect(screen, colour, pg.Rect(x - 3, bar.top - 6, 6, bar.height + 12))
        force = "-" if math.isnan(force_n) else f"{force_n:.2f}"
        self._centre(f"press {level + 1} of {levels}: {force} N now, {asked_n:g} N asked", self.font, TEXT,
                     (area.centerx, bar.bottom + 30))
        progress = pg.Rect(area.left, bar.bottom + 60, round(area.width * done), 10)
        pg.draw.rect(screen, GOOD, progress)
        self._centre(f"participant {self.participant}; Esc cancels", self.font, AREA_EDGE, (w // 2, h - 30))
        pg.display.flip()
        self.frames += 1
        return True

    def _centre(self, text: str, font, colour, centre) -> None:
        surface = font.render(text, True, colour)
        self.screen.blit(surface, surface.get_rect(center=centre))

    def close(self) -> None:
        self.pg.display.quit()
