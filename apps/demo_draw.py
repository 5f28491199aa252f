"""Drawing for the demo: friction maps at physical size, the finger trace, the strip chart."""

from __future__ import annotations

import numpy as np
import pygame
from ultraglide.textures.texture import Texture

BACKGROUND = (18, 20, 26)
PANEL = (32, 36, 46)
TEXT = (225, 228, 235)
DIM = (140, 146, 160)
ACCENT = (255, 170, 60)
TRACE = (255, 90, 90)
OTHER_FINGER = (120, 180, 255)
CHART_COLOURS = {"friction": (110, 200, 255), "amplitude": (255, 170, 60), "measured": (120, 230, 130)}


def friction_colours(ratio: np.ndarray) -> np.ndarray:
    """RGB for friction ratios: light = sticky (at rest), dark blue = slippery; (rows, cols, 3) uint8."""
    r = np.clip(ratio, 0.0, 1.0)[..., None]
    slippery = np.array([20, 40, 110], dtype=float)
    sticky = np.array([235, 228, 210], dtype=float)
    return (slippery + (sticky - slippery) * r).astype(np.uint8)


def texture_surface(texture: Texture, mm_per_px: float) -> pygame.Surface:
    """The friction map as a surface whose pixels match the screen's millimetres."""
    rgb = friction_colours(texture.ratio_map())
    surface = pygame.surfarray.make_surface(np.ascontiguousarray(rgb.transpose(1, 0, 2)))
    size = (max(1, round(texture.width_mm / mm_per_px)), max(1, round(texture.height_mm / mm_per_px)))
    return pygame.transform.smoothscale(surface, size)


def blit_texture(screen: pygame.Surface, surface: pygame.Surface, area: pygame.Rect, tiled: bool,
                 outside_colour) -> None:
    """Draw from the area's top-left corner: repeated if the texture tiles, once otherwise."""
    screen.fill(outside_colour, area)
    clip = screen.get_clip()
    screen.set_clip(area)
    if tiled:
        for y in range(area.top, area.bottom, surface.get_height()):
            for x in range(area.left, area.right, surface.get_width()):
                screen.blit(surface, (x, y))
    else:
        screen.blit(surface, area.topleft)
    screen.set_clip(clip)


def draw_chart(screen: pygame.Surface, font: pygame.font.Font, area: pygame.Rect, series: dict[str, np.ndarray],
               span_s: float, amplitude_max: float) -> None:
    """A strip chart: friction (0..1) and amplitudes (0..amplitude_max µm) over the last ``span_s``."""
    pygame.draw.rect(screen, PANEL, area)
    inner = area.inflate(-16, -24)
    inner.top = area.top + 18
    x = 10
    for name, colour in CHART_COLOURS.items():
        label = {"friction": "target friction (0-1)", "amplitude": f"commanded µm (0-{amplitude_max:g})",
                 "measured": "plate measured µm"}[name]
        rendered = font.render(label, True, colour)
        screen.blit(rendered, (area.left + x, area.top + 2))
        x += rendered.get_width() + 24
    for name, values in series.items():
        if len(values) < 2:
            continue
        t, v = values[:, 0], values[:, 1]
        scale = 1.0 if name == "friction" else amplitude_max
        px = inner.right - (t[-1] - t) / span_s * inner.width
        py = inner.bottom - np.clip(v / scale, 0, 1) * inner.height
        keep = px >= inner.left
        if keep.sum() >= 2:
            pygame.draw.lines(screen, CHART_COLOURS[name], False, np.column_stack((px[keep], py[keep])).tolist(), 2)


def draw_trace(screen: pygame.Surface, points: list[tuple[float, float]]) -> None:
    if len(points) >= 2:
        pygame.draw.lines(screen, TRACE, False, points, 3)
    if points:
        pygame.draw.circle(screen, TRACE, (int(points[-1][0]), int(points[-1][1])), 14, 3)
