"""Drawing the demo's screen by parts: the gallery or the texture area, the chart, the status line, the
toolbar and the help panel. The drawing primitives are :mod:`ultraglide.apps.demo.draw`."""

from __future__ import annotations

import os
import time

import numpy as np
from ultraglide.apps.demo.draw import (
    ACCENT,
    BACKGROUND,
    DIM,
    LIMIT,
    OTHER_FINGER,
    PANEL,
    TEXT,
    blit_texture,
    dimmed,
    draw_chart,
    draw_help,
    draw_trace,
    fit_text,
    friction_colours,
    texture_surface,
    thumbnail,
)
from ultraglide.apps.demo.options import seconds_since_launch
from ultraglide.apps.demo.status import HELP as HELP_KEY
from ultraglide.apps.demo.status import SEPARATOR, status_lines

CHART_SPAN_S = 3.0
TRACE_S = 1.5  # the driving finger's trace fades over this
STATUS_MARGIN_PX = 8
HELP = [
    ("touch / mouse", "drag on a texture to feel it; tap a tile in the gallery to open it"),
    ("second finger", "shown; the first finger drives (a rig's [touch] drives: first, latest or none)"),
    ("pressure", "sets the force where the panel reports it (× the rig's pressure full scale; 2 N without)"),
    ("G  T  W", "gallery, texture, widgets"),
    ("Left  Right", "previous, next texture"),
    ("Up  Down", "force up, down (×1.25) when the panel reports no pressure"),
    ("M", "switch the friction model (stretched, squeeze-film, exponential, paper; with a dynamic model, each "
          "with its friction dynamics)"),
    ("Space", "pause: the plate rests"),
    ("R", "restart the engine after it was lost"),
    ("H", "this help"),
    ("Esc  Q", "quit (the plate ramps to rest)"),
]


class Painter:
    """Draws the app's state onto its screen; keeps the textures' surfaces and the gallery's thumbnails."""

    def __init__(self, app):
        self.app = app
        self.pg, self.screen = app.pg, app.screen
        self.font = self.pg.font.Font(None, 22)
        self.big_font = self.pg.font.Font(None, 30)
        self.frames_drawn = 0
        self.thumbs: list = []
        self._surfaces: dict[int, object] = {}
        self._status_words = ""

    def make_thumbnails(self) -> None:
        layout = self.app.layout
        self.thumbs = [thumbnail(texture, layout.thumbnail_size(i)) for i, texture in enumerate(self.app.textures)]

    def replaced(self, index: int, old) -> None:
        """The texture at ``index`` was reloaded: forget the old one's surface, make its thumbnail again."""
        self.forget(old)
        self.thumbs[index] = thumbnail(self.app.textures[index], self.app.layout.thumbnail_size(index))

    def forget(self, texture) -> None:
        self._surfaces.pop(id(texture), None)

    def _surface(self, texture):
        """The texture at the screen's pitch, and its dimmed copy for the repeats beyond its edge."""
        key = id(texture)
        if key not in self._surfaces:
            surface = texture_surface(texture, self.app.mm_per_px)
            self._surfaces[key] = surface, dimmed(surface) if texture.outside == "tile" else None
        return self._surfaces[key]

    def everything(self) -> None:
        """The whole screen, flipped; the first time, a line says how long the window took."""
        app = self.app
        self.screen.fill(BACKGROUND)
        if app.scenes.scene == "gallery":
            self.gallery()
        else:
            self.area()
        self.chart()
        self.status(force=True)
        self.toolbar()
        if app.show_help:
            draw_help(self.screen, self.font, self.big_font, HELP)
        self.pg.display.flip()
        self.frames_drawn += 1
        if self.frames_drawn == 1:
            cpu = os.times()
            print(f"ultraglide demo: first frame drawn {seconds_since_launch():.2f} s after launch "
                  f"({cpu.user + cpu.system:.2f} s of CPU)", flush=True)
        if app.options.report_frames:
            print(f"frame drawn: {app.scenes.scene}{' help' if app.show_help else ''}", flush=True)

    def gallery(self) -> None:
        pg, screen, layout = self.pg, self.screen, self.app.layout
        label_h = layout.label_h
        for texture, tile, thumb in zip(self.app.textures, layout.tiles, self.thumbs, strict=True):
            if tile.bottom > layout.area.bottom:
                break
            picture = pg.Rect(tile.left, tile.top, tile.width, tile.height - label_h)
            screen.blit(thumb, thumb.get_rect(center=picture.center))
            pg.draw.rect(screen, DIM, tile, 1)
            label = fit_text(self.font, texture.name, tile.width - 8)
            screen.blit(self.font.render(label, True, TEXT), (tile.left + 4, tile.bottom - label_h + 2))

    def area(self) -> None:
        app = self.app
        pg, screen, area = self.pg, self.screen, app.layout.area
        texture = app.scenes.current
        outside = friction_colours(np.array([[texture.outside_ratio]]))[0, 0].tolist()
        surface, repeat = self._surface(texture)
        blit_texture(screen, surface, area, texture.outside == "tile", outside, repeat)
        words = f"{texture.name}: {texture.width_mm:.4g} × {texture.height_mm:.4g} mm"
        if texture.description:
            words += f", {texture.description}"
        text = self.font.render(fit_text(self.font, words, area.width - 40), True, ACCENT)
        backing = text.get_rect(bottomleft=(area.left + 8, area.bottom - 6)).inflate(12, 8)
        pg.draw.rect(screen, PANEL, backing, border_radius=4)
        screen.blit(text, text.get_rect(center=backing.center))
        points = app.driver.fade(time.perf_counter(), TRACE_S)
        clip = screen.get_clip()
        screen.set_clip(area)
        draw_trace(screen, points)
        for finger, (x, y) in app.input.fingers.items():
            if finger != app.input.driving:
                pg.draw.circle(screen, OTHER_FINGER, (int(x), int(y)), 14, 2)
        screen.set_clip(clip)

    def chart(self) -> None:
        app = self.app
        if app.link is None:
            chart, limit, full_scale, measured = np.zeros((0, 5)), 6.0, 6.0, False
        else:
            status = app.link.status(CHART_SPAN_S)
            chart, limit, full_scale, measured = (status.chart, status.limit_um_pp, status.full_scale_um_pp,
                                                  status.plate_measured)
        series = {"friction": chart[:, [0, 1]], "commanded": chart[:, [0, 2]], "plate": chart[:, [0, 3]]}
        friction = chart[:, [0, 4]]
        friction = friction[np.isfinite(friction[:, 1])]
        if len(friction):  # the closed loop's: the friction the plate's sensors measure, beside the target
            series["measured"] = friction
        label = "plate measured µm p-p" if measured else "plate (model) µm p-p"
        draw_chart(self.screen, self.font, app.layout.chart_rect, series, CHART_SPAN_S, full_scale, limit, label)

    def status(self, force: bool = False) -> bool:
        """The status line's two lines, when their words changed (or ``force``); True when drawn."""
        rect = self.app.layout.status_rect
        first, second = status_lines(self.app, self.font, rect.width)
        words = (first, second)
        if words == self._status_words and not force:
            return False
        self._status_words = words
        self.pg.draw.rect(self.screen, PANEL, rect)
        line_h = self.font.get_linesize()
        for row, parts in enumerate(words):
            x, y = rect.left + STATUS_MARGIN_PX, rect.top + 5 + row * (line_h + 2)
            for i, (text, part) in enumerate(parts):
                if i:
                    x += self._blit(SEPARATOR, DIM, x, y)
                x += self._blit(text, LIMIT if part.warn else TEXT, x, y)
        help_text = self.font.render(HELP_KEY, True, ACCENT)
        self.screen.blit(help_text, help_text.get_rect(topright=(rect.right - STATUS_MARGIN_PX, rect.top + 5)))
        return True

    def _blit(self, text: str, colour, x: int, y: int) -> int:
        rendered = self.font.render(text, True, colour)
        self.screen.blit(rendered, (x, y))
        return rendered.get_width()

    def toolbar(self) -> None:
        pg, app = self.pg, self.app
        pg.draw.rect(self.screen, PANEL, app.layout.toolbar_rect)
        for button in app.layout.buttons:
            active = (button.action == app.scenes.scene or (button.action == "pause" and app.user_paused)
                      or (button.action == "help" and app.show_help))
            pg.draw.rect(self.screen, ACCENT if active else DIM, button.rect, 0 if active else 2, border_radius=8)
            label = fit_text(self.big_font, button.label, button.rect.width - 8)
            text = self.big_font.render(label, True, BACKGROUND if active else TEXT)
            self.screen.blit(text, text.get_rect(center=button.rect.center))
