"""``ultraglide texture show``: a texture drawn for print or on screen.

Three panels: the friction map with millimetre axes and a colour bar, the vibration amplitude the
texture asks of the plate under a friction model, plate profile and normal force (µm p-p, with the
pixels the plate cannot reach marked), and the histogram of the friction ratio. The page is one IEEE
column (3.5 in) wide, or two (7.16 in), text 8 pt or more at that size; the maps are drawn at their
physical size (print the page at 100 %: 1 mm on the axes is 1 mm on paper) when they fit its width,
else scaled down, and the title gives the scale.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from ultraglide.apps.cli.errors import UsageError  # noqa: E402
from ultraglide.apps.cli.files import (  # noqa: E402
    atomic_path,
    model_file,
    profile_file,
    refuse_overlaps,
    texture_file,
)
from ultraglide.apps.cli.options import refuse_ignored  # noqa: E402
from ultraglide.apps.window.screen import display_available, init_display  # noqa: E402
from ultraglide.textures.texture import Texture  # noqa: E402

MM = 1 / 25.4  # inches per millimetre
FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
LEFT_MM, RIGHT_MM, GAP_MM, BAR_MM = 14.0, 17.0, 14.0, 3.0
HISTOGRAM_MM = 32.0
MAX_MAP_HEIGHT_MM = 110.0
TEXT = 8  # pt: the smallest text a printed figure may have
LINE_MM = 3.6  # a line of 8 pt text


@dataclass(frozen=True)
class AmplitudeMap:
    """The amplitude each pixel needs (µm p-p) and how many pixels the plate cannot reach."""

    amplitude_um_pp: np.ndarray
    clamped: int
    limit_um_pp: float
    description: str
    lags: bool = False  # the model has friction dynamics: the map is of settled ratios, not what the renderer sends


def amplitude_map(texture: Texture, model, limit_um_pp: float, force_n: float, model_name: str = "") -> AmplitudeMap:
    """The model's inverse over the whole friction map (a gradient texture: under a left-to-right swipe)."""
    ratio = texture.ratio_map()
    inversion = model.amplitude_um_pp(ratio.astype(float), force_n, limit_um_pp)
    return AmplitudeMap(np.asarray(inversion.amplitude_um_pp).reshape(ratio.shape), inversion.clamped, limit_um_pp,
                        model_name or model.describe(), getattr(model, "dynamics", None) is not None)


def _page_mm(width=None) -> float:
    from ultraglide.apps.figures.style import width_of

    return width_of(width) * 25.4


def _layout(texture: Texture, width=None) -> tuple[float, float, float]:
    """Figure width and height (mm) and the map scale (1 = physical size)."""
    page = _page_mm(width)
    room = page - LEFT_MM - RIGHT_MM
    scale = min(1.0, room / texture.width_mm, MAX_MAP_HEIGHT_MM / texture.height_mm)
    map_h = texture.height_mm * scale
    height = 2 * (_title_mm(page) + map_h + GAP_MM) + HISTOGRAM_MM + _title_mm(page) + GAP_MM
    return page, height, scale


def _title_mm(page_mm: float) -> float:
    return 4 * LINE_MM if page_mm < 120 else 2 * LINE_MM


def _wrap(text: str, page_mm: float) -> str:
    import textwrap

    return textwrap.fill(text, int((page_mm - LEFT_MM + 6) / 1.75))  # about 1.75 mm a character at 8 pt


def draw(texture: Texture, amplitude: AmplitudeMap, force_n: float, profile_name: str, width=None):
    """The figure (matplotlib) at the print ``width`` ("column", "page"); the caller saves or shows it."""
    width_mm, height_mm, scale = _layout(texture, width)
    figure = plt.figure(figsize=(width_mm * MM, height_mm * MM))
    map_w, map_h = texture.width_mm * scale, texture.height_mm * scale
    title_mm = _title_mm(width_mm)

    def axes_at(left_mm, top_mm, w_mm, h_mm):
        return figure.add_axes((left_mm / width_mm, 1 - (top_mm + h_mm) / height_mm, w_mm / width_mm, h_mm / height_mm))

    extent = (0, texture.width_mm, texture.height_mm, 0)
    scale_words = "at physical size (print at 100 %)" if scale == 1 else f"at 1:{1 / scale:.3g} of physical size"
    ratio = texture.ratio_map()
    top = title_mm
    friction_axes = axes_at(LEFT_MM, top, map_w, map_h)
    image = friction_axes.imshow(ratio, cmap="viridis", vmin=0, vmax=1, extent=extent, interpolation="nearest")
    kind = " (gradient texture: a left-to-right swipe)" if texture.kind == "gradient" else ""
    friction_axes.set_title(_wrap(f"{texture.name}: friction ratio µ/µ0 (1 = at rest){kind}, {scale_words}",
                                  width_mm), fontsize=TEXT, loc="left")
    friction_axes.set_xlabel("x (mm)", fontsize=TEXT)
    friction_axes.set_ylabel("y (mm)", fontsize=TEXT)
    bar = figure.colorbar(image, cax=axes_at(LEFT_MM + map_w + 2, top, BAR_MM, map_h))
    bar.set_label("µ/µ0", fontsize=TEXT)

    top += map_h + GAP_MM + title_mm
    amplitude_axes = axes_at(LEFT_MM, top, map_w, map_h)
    limit = amplitude.limit_um_pp
    image = amplitude_axes.imshow(amplitude.amplitude_um_pp, cmap="magma", vmin=0, vmax=limit, extent=extent,
                                  interpolation="nearest")
    unreachable = ""
    if amplitude.clamped:
        share = amplitude.clamped / ratio.size
        unreachable = f"; {share:.1%} of the map beyond reach, held at the limit"
    settled = ", each held until settled (the renderer plans against the finger's lag)" if amplitude.lags else ""
    amplitude_axes.set_title(_wrap(f"amplitude needed (µm p-p){unreachable}{settled}: {amplitude.description} model, "
                                   f"{force_n:g} N, plate {profile_name} (limit {limit:g} µm p-p)", width_mm),
                             fontsize=TEXT, loc="left")
    amplitude_axes.set_xlabel("x (mm)", fontsize=TEXT)
    amplitude_axes.set_ylabel("y (mm)", fontsize=TEXT)
    bar = figure.colorbar(image, cax=axes_at(LEFT_MM + map_w + 2, top, BAR_MM, map_h))
    bar.set_label("µm p-p", fontsize=TEXT)

    top += map_h + GAP_MM + title_mm
    histogram_axes = axes_at(LEFT_MM, top, width_mm - LEFT_MM - RIGHT_MM, HISTOGRAM_MM)
    histogram_axes.hist(ratio.ravel(), bins=100, range=(0, 1), weights=np.full(ratio.size, 100 / ratio.size),
                        color="#3b528b")
    histogram_axes.set_xlabel("friction ratio µ/µ0", fontsize=TEXT)
    histogram_axes.set_ylabel("area (%)", fontsize=TEXT)
    histogram_axes.set_title(_wrap(f"friction over the texture: mean {ratio.mean():.3f}, {ratio.min():.3f} to "
                                   f"{ratio.max():.3f}", width_mm), fontsize=TEXT, loc="left")
    histogram_axes.grid(alpha=0.3)
    for axes in figure.axes:
        axes.tick_params(labelsize=TEXT)
    return figure


def save_figure(figure, path: Path, dpi: float) -> Path:
    """Save by the file's extension (PNG at ``dpi``, PDF or SVG as vectors), atomically."""
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise UsageError(f"the output must end in .png, .pdf or .svg, got {path}")
    from ultraglide.apps.figures.style import before_saving

    before_saving(fmt)
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format=fmt, dpi=dpi, bbox_inches=figure.bbox_inches)  # the whole page: 1:1 holds
    return path


def show_window(figure, title: str) -> None:
    """The figure in a pygame window until it is closed or Esc is pressed."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    figure.set_dpi(100)
    figure.canvas.draw()
    pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3]
    try:
        init_display(pygame)
    except pygame.error as error:
        raise UsageError(f"cannot open a window ({error}); write a file with -o FILE.png instead") from None
    try:
        info = pygame.display.Info()
        picture = pygame.surfarray.make_surface(np.ascontiguousarray(pixels.transpose(1, 0, 2)))
        fit = min(1.0, (info.current_w or 1600) * 0.95 / picture.get_width(),
                  (info.current_h or 1000) * 0.9 / picture.get_height())
        if fit < 1:
            size = (round(picture.get_width() * fit), round(picture.get_height() * fit))
            picture = pygame.transform.smoothscale(picture, size)
        screen = pygame.display.set_mode(picture.get_size())
        pygame.display.set_caption(title)
        screen.blit(picture, (0, 0))
        pygame.display.flip()
        while True:
            event = pygame.event.wait()
            if event.type == pygame.QUIT or (event.type == pygame.KEYDOWN and event.key in (pygame.K_ESCAPE,
                                                                                             pygame.K_q)):
                return
            if event.type in (pygame.WINDOWEXPOSED, pygame.VIDEOEXPOSE):
                screen.blit(picture, (0, 0))
                pygame.display.flip()
    finally:
        pygame.display.quit()


def run(args) -> int:
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.textures.library import resolve_texture

    output = Path(args.output) if args.output else None
    if output is not None and output.suffix.lower() not in FORMATS:
        raise UsageError(f"the output must end in .png, .pdf or .svg, got {output}")
    if args.window:
        refuse_ignored(args, {"dpi": 300.0}, "{option} is the PNG's resolution, and --window writes none: leave it "
                                             "out, or write a file with -o FILE.png")
    if args.window and not display_available():
        raise UsageError("no display for --window; write a file with -o FILE.png instead")
    refuse_overlaps({"-o": output}, {"the texture": texture_file(args.texture), "--model": model_file(args.model),
                                     "--profile": profile_file(args.profile)})
    texture = resolve_texture(args.texture)
    model = load_model(args.model)
    profile = load_profile(args.profile)
    amplitude = amplitude_map(texture, model, profile.max_amplitude_um_pp, args.force, Path(args.model).name)
    width = getattr(args, "figure_width", "page")
    figure = draw(texture, amplitude, args.force, profile.name, width)
    try:
        if args.window:
            show_window(figure, f"ultraglide: {texture.name}")
            return 0
        save_figure(figure, output, args.dpi)
    finally:
        plt.close(figure)
    width_mm, height_mm, scale = _layout(texture, width)
    size = "at physical size" if scale == 1 else f"at 1:{1 / scale:.3g}"
    print(f"wrote {output}: {texture.name}, {texture.width_mm:g} × {texture.height_mm:g} mm drawn {size} on a "
          f"{width_mm:.0f} × {height_mm:.0f} mm page; amplitude {amplitude.amplitude_um_pp.min():.2f} to "
          f"{amplitude.amplitude_um_pp.max():.2f} µm p-p at {args.force:g} N"
          + (f", {amplitude.clamped} pixels beyond the plate's reach" if amplitude.clamped else ""))
    return 0
