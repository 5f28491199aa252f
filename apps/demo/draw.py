"""Drawing for the demo: friction maps at physical size, thumbnails, the finger trace, the chart, help."""

from __future__ import annotations

import numpy as np
import pygame
from ultraglide.textures.texture import Texture, gradient_ratio

BACKGROUND = (18, 20, 26)
PANEL = (32, 36, 46)
GRID = (58, 64, 80)
TEXT = (225, 228, 235)
DIM = (140, 146, 160)
ACCENT = (255, 170, 60)
TRACE = (255, 90, 90)
OTHER_FINGER = (120, 180, 255)
LIMIT = (235, 80, 80)
EDGE = ACCENT  # where a texture smaller than the screen ends
EDGE_PX = 2
REPEAT_VEIL = 110  # of 255: how far a tiled texture's repeats fade towards the background
CHART_COLOURS = {"friction": (110, 200, 255), "commanded": (255, 170, 60), "plate": (120, 230, 130),
                 "measured": (225, 120, 235)}
BAND_ALPHA = 0.35  # the opacity of a series' min-to-max band
ENVELOPE_COLUMNS = 5  # a band where a series swings within this many pixel columns (3 s on 1100 px: 13 ms, 75 Hz)
BAND_MIN_PX = 4  # and by at least this much


def _palette() -> np.ndarray:
    slippery = np.array([20, 40, 110], dtype=float)
    sticky = np.array([235, 228, 210], dtype=float)
    return (slippery + (sticky - slippery) * np.linspace(0.0, 1.0, 256)[:, None]).astype(np.uint8)


PALETTE = _palette()


def friction_colours(ratio: np.ndarray) -> np.ndarray:
    """RGB for friction ratios: light = sticky (at rest), dark blue = slippery; (rows, cols, 3) uint8.
    A 256-entry palette (ratios to 1/255) keeps this cheap on whole textures."""
    index = np.clip(ratio, 0.0, 1.0) * 255.0 + 0.5
    return PALETTE[index.astype(np.uint8)]


def box_reduce(values: np.ndarray, factor: int) -> np.ndarray:
    """Mean over ``factor`` × ``factor`` blocks: shrinking without aliasing fine patterns."""
    if factor <= 1:
        return values
    rows, cols = values.shape[0] // factor * factor, values.shape[1] // factor * factor
    blocks = values[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
    return blocks.mean(axis=(1, 3), dtype=np.float32)


def _surface_of(rgb: np.ndarray) -> pygame.Surface:
    return pygame.surfarray.make_surface(np.ascontiguousarray(rgb.transpose(1, 0, 2)))


def texture_surface(texture: Texture, mm_per_px: float) -> pygame.Surface:
    """The friction map as a surface whose pixels match the screen's millimetres."""
    surface = _surface_of(friction_colours(texture.ratio_map()))
    size = (max(1, round(texture.width_mm / mm_per_px)), max(1, round(texture.height_mm / mm_per_px)))
    return pygame.transform.smoothscale(surface, size)


def thumbnail(texture: Texture, size: tuple[int, int]) -> pygame.Surface:
    """The texture fitted into ``size`` px keeping its aspect, smooth-scaled (area-averaged, no aliasing)."""
    scale = min(size[0] / texture.width_mm, size[1] / texture.height_mm)
    fitted = (max(1, round(texture.width_mm * scale)), max(1, round(texture.height_mm * scale)))
    factor = max(1, min(texture.cols // fitted[0], texture.rows // fitted[1]))  # averaged down to about the tile
    values = box_reduce(texture.values, factor)
    if texture.kind == "gradient":  # under a left-to-right swipe, as Texture.ratio_map, on fewer pixels
        ratio = gradient_ratio(texture, np.gradient(values.astype(float), texture.pixel_mm[0] * factor, axis=1))
    else:
        ratio = values
    return pygame.transform.smoothscale(_surface_of(friction_colours(ratio)), fitted)


def fit_text(font: pygame.font.Font, text: str, width_px: int) -> str:
    """``text``, shortened with an ellipsis if it is wider than ``width_px``."""
    if font.size(text)[0] <= width_px:
        return text
    low, high = 0, len(text)
    while low < high:  # the longest prefix that fits with the ellipsis
        mid = (low + high + 1) // 2
        if font.size(text[:mid].rstrip() + "…")[0] <= width_px:
            low = mid
        else:
            high = mid - 1
    return text[:low].rstrip() + "…"


def blit_texture(screen: pygame.Surface, surface: pygame.Surface, area: pygame.Rect, tiled: bool,
                 outside_colour, repeat: pygame.Surface | None = None) -> pygame.Rect:
    """Draw from the area's top-left corner, outlined where it ends inside the area; beyond it, what the finger
    feels there: the texture's repeats (``repeat``: a dimmed copy, see :func:`dimmed`) when it tiles, else its
    outside colour. Returns the texture's own rectangle."""
    screen.fill(outside_colour, area)
    clip = screen.get_clip()
    screen.set_clip(area)
    own = pygame.Rect(area.topleft, surface.get_size())
    if tiled:
        for y in range(area.top, area.bottom, surface.get_height()):
            for x in range(area.left, area.right, surface.get_width()):
                screen.blit(repeat or surface, (x, y))
    screen.blit(surface, area.topleft)
    if own.right < area.right or own.bottom < area.bottom:  # its edge, just outside its own pixels
        pygame.draw.rect(screen, EDGE, own.inflate(2 * EDGE_PX, 2 * EDGE_PX), EDGE_PX)
    screen.set_clip(clip)
    return own


def dimmed(surface: pygame.Surface) -> pygame.Surface:
    """A copy of ``surface`` faded towards the background: a texture's repeats beyond its edge."""
    copy = surface.copy()
    veil = pygame.Surface(surface.get_size())
    veil.fill(BACKGROUND)
    veil.set_alpha(REPEAT_VEIL)
    copy.blit(veil, (0, 0))
    return copy


def _ticks(top: float, step: float) -> np.ndarray:
    return np.arange(0.0, top + step * 0.01, step)


def draw_chart(screen: pygame.Surface, font: pygame.font.Font, area: pygame.Rect, series: dict[str, np.ndarray],
               span_s: float, amplitude_max_um_pp: float, limit_um_pp: float, plate_label: str) -> pygame.Rect:
    """A strip chart with scales: target friction (ratio, left axis) and the commanded and plate amplitudes
    (µm p-p, right axis, with the profile's limit) over the last ``span_s``, time in ms up to now.

    ``series`` maps "friction", "commanded", "plate" (and, with the closed loop, "measured": the friction ratio the
    plate's force sensors measure, on the friction axis) to rows of (t_s, value); the newest time is 0 ms.
    Returns the plotting rectangle (inside the axes)."""
    pygame.draw.rect(screen, PANEL, area)
    line_h = font.get_linesize()
    plot = pygame.Rect(area.left + 64, area.top + line_h + 6, area.width - 64 - 70, area.height - 2 * line_h - 12)
    labels = {"friction": "target friction (ratio)", "commanded": "commanded µm p-p", "plate": plate_label,
              "measured": "measured friction (ratio)"}
    x = plot.left
    for name, colour in CHART_COLOURS.items():
        if name not in series:
            continue
        rendered = font.render(labels[name], True, colour)
        screen.blit(rendered, (x, area.top + 3))
        x += rendered.get_width() + 28
    screen.blit(font.render(f"limit {limit_um_pp:g} µm p-p", True, LIMIT), (x, area.top + 3))
    y_limit = round(plot.bottom - min(limit_um_pp / amplitude_max_um_pp, 1.0) * plot.height)
    for value in _ticks(1.0, 0.25):  # friction: left axis
        y = plot.bottom - value * plot.height
        if abs(y - y_limit) > 2:  # a gridline never runs along the limit's line, where it would look like it
            pygame.draw.line(screen, GRID, (plot.left, y), (plot.right, y), 1)
        text = font.render(f"{value:.2f}", True, CHART_COLOURS["friction"])
        screen.blit(text, text.get_rect(midright=(plot.left - 6, y)))
    step = 1.0 if amplitude_max_um_pp <= 6 else 2.0 if amplitude_max_um_pp <= 12 else 5.0
    for value in _ticks(amplitude_max_um_pp, step):  # amplitude: right axis
        y = plot.bottom - value / amplitude_max_um_pp * plot.height
        pygame.draw.line(screen, GRID, (plot.right, y), (plot.right + 4, y), 1)
        text = font.render(f"{value:g} µm", True, CHART_COLOURS["commanded"])
        screen.blit(text, text.get_rect(midleft=(plot.right + 8, y)))
    span_ms = span_s * 1000
    for ms in _ticks(span_ms, 500.0):  # time: bottom axis, now at the right
        x = plot.right - ms / span_ms * plot.width
        pygame.draw.line(screen, GRID, (x, plot.top), (x, plot.bottom + 3), 1)
        words = "now" if ms == 0 else f"−{ms:.0f} ms" if ms >= span_ms else f"−{ms:.0f}"
        text = font.render(words, True, DIM)
        screen.blit(text, text.get_rect(midtop=(x, plot.bottom + 4)))
    pygame.draw.rect(screen, DIM, plot, 1)
    latest = max((values[-1, 0] for values in series.values() if len(values)), default=0.0)
    columns = {}
    for name, values in series.items():
        scale = 1.0 if name in ("friction", "measured") else amplitude_max_um_pp
        envelope = column_envelope(values, latest, span_s, plot, scale)
        if envelope is not None:
            columns[name] = envelope
    for name, envelope in columns.items():
        draw_envelope(screen, plot, CHART_COLOURS[name], *envelope)
    for x0 in range(plot.left, plot.right, 12):  # the limit as a dashed line, over what reaches it
        pygame.draw.line(screen, LIMIT, (x0, y_limit), (min(x0 + 6, plot.right), y_limit), 1)
    return plot


def draw_envelope(screen: pygame.Surface, plot: pygame.Rect, colour, x: np.ndarray, low: np.ndarray,
                  high: np.ndarray, mean: np.ndarray) -> None:
    """One series from :func:`column_envelope`: where it swings within a few columns (a fine texture under a
    moving finger), a translucent band from its smallest to its largest value, outlined; elsewhere a line
    through the columns' means."""
    half = ENVELOPE_COLUMNS // 2
    padded_low = np.pad(low, half, mode="edge")
    padded_high = np.pad(high, half, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view
    low, high = windows(padded_low, ENVELOPE_COLUMNS).max(axis=1), windows(padded_high, ENVELOPE_COLUMNS).min(axis=1)
    wide = low - high >= BAND_MIN_PX
    if wide.any():
        rows = np.arange(plot.top, plot.bottom + 1)
        inside = (rows[None, :] >= high[wide, None]) & (rows[None, :] <= low[wide, None])
        pixels = pygame.surfarray.pixels3d(screen)  # (x, y, rgb), the screen locked while it lives
        region = pixels[x[wide], plot.top:plot.bottom + 1]
        region[inside] = (region[inside] * (1 - BAND_ALPHA) + np.array(colour) * BAND_ALPHA).astype(np.uint8)
        pixels[x[wide], plot.top:plot.bottom + 1] = region
        del pixels
    for run in _runs(wide):
        xs = x[run]
        if wide[run.start]:  # the band's outline: along its top, back along its bottom
            outline = np.concatenate((np.column_stack((xs, high[run])), np.column_stack((xs, low[run]))[::-1]))
            pygame.draw.lines(screen, colour, True, outline.tolist(), 1)
        elif len(xs) >= 2:
            pygame.draw.lines(screen, colour, False, np.column_stack((xs, mean[run])).tolist(), 2)
        else:
            pygame.draw.line(screen, colour, (xs[0], mean[run][0]), (xs[0], mean[run][0]), 2)


def _runs(flags: np.ndarray) -> list[slice]:
    """The runs of equal values in ``flags``, as slices."""
    edges = np.flatnonzero(np.diff(flags.astype(np.int8))) + 1
    bounds = np.concatenate(([0], edges, [len(flags)]))
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def column_envelope(values: np.ndarray, latest_s: float, span_s: float, plot: pygame.Rect,
                    scale: float) -> tuple[np.ndarray, ...] | None:
    """Rows of (t_s, value) as one entry per pixel column of ``plot`` (now at its right edge, ``span_s`` across,
    values over ``scale`` from the bottom): the columns' x and the rows (px) of their smallest, largest and mean
    value. Thousands of samples a column (a 1 mm grating under a finger) drawn as lines alias into a solid
    block; their envelope shows what they span, and the mean where they sit. None with nothing to draw."""
    if len(values) < 2:
        return None
    t, v = values[:, 0], values[:, 1]
    x = plot.right - (latest_s - t) / span_s * plot.width
    keep = x >= plot.left
    if keep.sum() < 2:
        return None
    column = np.minimum(np.floor(x[keep]).astype(np.int64), plot.right - 1)
    y = plot.bottom - np.clip(v[keep] / scale, 0.0, 1.0) * plot.height
    starts = np.concatenate(([0], np.flatnonzero(np.diff(column)) + 1))  # times rise: columns come in order
    counts = np.diff(np.append(starts, len(y)))
    high = np.minimum.reduceat(y, starts)  # rows grow downwards: the largest value is the smallest row
    low = np.maximum.reduceat(y, starts)
    mean = np.add.reduceat(y, starts) / counts
    return column[starts], low, high, mean


def draw_trace(screen: pygame.Surface, points: list[tuple[float, float]]) -> None:
    if len(points) >= 2:
        pygame.draw.lines(screen, TRACE, False, points, 3)
    if points:
        pygame.draw.circle(screen, TRACE, (int(points[-1][0]), int(points[-1][1])), 14, 3)


def draw_help(screen: pygame.Surface, font: pygame.font.Font, title_font: pygame.font.Font,
              lines: list[tuple[str, str]]) -> pygame.Rect:
    """A panel in the middle of the screen listing keys (or gestures) and what they do; returns its rect."""
    key_w = max(font.size(key)[0] for key, _ in lines)
    text_w = max(font.size(what)[0] for _, what in lines)
    line_h = font.get_linesize() + 4
    title = title_font.render("ultraglide demo: keys and gestures (H to close)", True, ACCENT)
    width = max(key_w + text_w + 60, title.get_width() + 40)
    panel = pygame.Rect(0, 0, width, len(lines) * line_h + title.get_height() + 40)
    panel.center = screen.get_rect().center
    pygame.draw.rect(screen, PANEL, panel, border_radius=10)
    pygame.draw.rect(screen, ACCENT, panel, 2, border_radius=10)
    screen.blit(title, (panel.left + 20, panel.top + 14))
    y = panel.top + title.get_height() + 26
    for key, what in lines:
        screen.blit(font.render(key, True, ACCENT), (panel.left + 20, y))
        screen.blit(font.render(what, True, TEXT), (panel.left + 40 + key_w, y))
        y += line_h
    return panel
