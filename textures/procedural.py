"""Textures from parameters: gratings, checkerboards, dots, bumps, noise, fractal roughness, Gabor
patches, single bumps, edges and lines, a chirp, UI elements.

Every generator takes a physical size in millimetres and a friction range ``ratio_range`` (low,
high): the ratio where the pattern is "off" (slippery) and "on" (sticky). The resolution is
chosen so that the finest feature spans at least 8 pixels, unless ``px_per_mm`` says otherwise.

Textures that tile (gratings, checkerboards, dots, bumps, noise, fractal roughness) are exactly
periodic within their tile: the tile keeps the size asked for, and the period snaps to the nearest
one that fits a whole number of times across each side (gratings snap their wave vector, so the
wavelength and the angle may both move a little; lattices snap their pitch per axis). The
realised periods are in the description and in the metadata (``tile_*``). The rest (chirp, Gabor
patch, single bump, edge, lines, widgets) do not repeat: beyond their edges lies their ground.
"""

from __future__ import annotations

import numpy as np
from ultraglide.textures.errors import TextureError
from ultraglide.textures.texture import Texture

DEFAULT_SIZE_MM = (80.0, 50.0)
DEFAULT_RANGE = (0.4, 1.0)
Size = tuple[float, float]  # width, height in mm
Range = tuple[float, float]  # friction ratios, low and high
MAX_PIXELS = 16_000_000
FEATURE_PIXELS = 8


def _check_positive(**values: float) -> None:
    for name, value in values.items():
        if not (np.isfinite(value) and value > 0):
            raise TextureError(f"{name} must be a positive number, got {value}")


def _grid(size_mm, finest_mm: float, px_per_mm: float | None):
    width_mm, height_mm = size_mm
    _check_positive(width_mm=width_mm, height_mm=height_mm, feature_mm=finest_mm)
    density = px_per_mm if px_per_mm else max(10.0, FEATURE_PIXELS / finest_mm)
    cols, rows = max(1, round(width_mm * density)), max(1, round(height_mm * density))
    if rows * cols > MAX_PIXELS:
        raise TextureError(f"{cols}×{rows} pixels is too many; use a coarser feature or a smaller size")
    x = (np.arange(cols) + 0.5) * (width_mm / cols)
    y = (np.arange(rows) + 0.5) * (height_mm / rows)
    return np.meshgrid(x, y)


def _finish(pattern, size_mm, ratio_range, name, description, kind="friction", outside="tile",
            outside_ratio: float | None = None, **authoring):
    low, high = ratio_range
    if not 0 <= low <= high <= 1:
        raise TextureError(f"range must satisfy 0 <= low <= high <= 1, got {low} {high}")
    pattern = np.clip(pattern, 0.0, 1.0)
    values = pattern if kind == "gradient" else low + (high - low) * pattern
    if outside_ratio is None:  # beyond a fixed texture lies its ground, so its edge has no step
        outside_ratio = low if kind == "friction" else 0.5 * (low + high)
    return Texture(values.astype(np.float32), float(size_mm[0]), float(size_mm[1]), kind=kind,
                   outside=outside, outside_ratio=float(outside_ratio), ratio_range=(low, high), name=name,
                   description=description,
                   source="procedural", authoring={"generator": name.split("-")[0], **authoring})


def _whole(period_mm: float, length_mm: float) -> tuple[int, float]:
    """How many periods fit a side (at least one), and the period that makes them fit exactly."""
    count = max(1, int(np.floor(length_mm / period_mm + 0.5)))
    return count, length_mm / count


def grating(wavelength_mm: float = 1.0, size_mm: Size = DEFAULT_SIZE_MM, angle_deg: float = 0.0,
            shape: str = "sine", ratio_range: Range = DEFAULT_RANGE, px_per_mm: float | None = None,
            duty: float = 0.5, tile: bool = True) -> Texture:
    """Parallel ridges of one wavelength; ``angle_deg`` turns the direction across them.

    ``duty`` is the sticky fraction of each period of a square grating. With ``tile`` (the
    default) the wave vector snaps to the nearest one with whole cycles across the width and the
    height, so the texture repeats without a seam: the wavelength and angle change by at most
    half a cycle over the tile (both realised values are in the description and metadata);
    ``tile=False`` keeps them exact and extends the edges instead of repeating.

    Parameters
    ----------
    wavelength_mm : float
        The ridges' period (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    angle_deg : float
        The direction across the ridges (degrees; 0: ridges run top to bottom).
    shape : str
        ``sine``, ``square``, ``triangle`` or ``sawtooth``.
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the wavelength.
    duty : float
        A square grating's sticky fraction of each period.
    tile : bool
        Snap to whole cycles so the texture tiles.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, wavelength, range or shape out of bounds, in one line.

    Examples
    --------
    >>> texture = grating(wavelength_mm=2.0, size_mm=(20.0, 10.0), ratio_range=(0.5, 1.0))
    >>> texture.width_mm, round(float(texture.values.min()), 2), round(float(texture.values.max()), 2)
    (20.0, 0.5, 1.0)
    """
    _check_positive(wavelength_mm=wavelength_mm)
    if shape not in ("sine", "square"):
        raise TextureError(f"grating shape must be sine or square, got {shape!r}")
    if not (np.isfinite(duty) and 0 < duty < 1):
        raise TextureError(f"duty cycle must lie strictly between 0 and 1, got {duty}")
    x, y = _grid(size_mm, wavelength_mm * (min(duty, 1 - duty) * 2 if shape == "square" else 1), px_per_mm)
    angle = np.deg2rad(angle_deg)
    fx, fy = np.cos(angle) / wavelength_mm, np.sin(angle) / wavelength_mm  # cycles per mm
    if tile:
        width_mm, height_mm = size_mm
        nx, ny = np.floor(fx * width_mm + 0.5), np.floor(fy * height_mm + 0.5)
        if nx == 0 and ny == 0:  # longer than the tile: one cycle along the nearer axis
            nx, ny = (np.sign(fx) or 1.0, 0.0) if abs(fx) * width_mm >= abs(fy) * height_mm else (0.0, np.sign(fy))
        fx, fy = nx / width_mm, ny / height_mm
    realised_mm, realised_deg = 1.0 / np.hypot(fx, fy), float(np.rad2deg(np.arctan2(fy, fx)))
    wave = np.cos(2 * np.pi * (fx * x + fy * y))
    pattern = 0.5 + 0.5 * wave if shape == "sine" else (wave >= np.cos(np.pi * duty)).astype(float)
    description = f"{shape} grating, {realised_mm:.4g} mm wavelength at {realised_deg:.3g}°"
    if shape == "square" and duty != 0.5:
        description += f", {duty:.0%} sticky"
    if tile and (not np.isclose(realised_mm, wavelength_mm, rtol=1e-9) or not np.isclose(realised_deg, angle_deg)):
        description += f" (snapped from {wavelength_mm:g} mm at {angle_deg:g}° to tile)"
    return _finish(pattern, size_mm, ratio_range, f"grating-{shape}", description,
                   outside="tile" if tile else "clamp", wavelength_mm=wavelength_mm, angle_deg=angle_deg,
                   shape=shape, duty=duty, tile_wavelength_mm=float(realised_mm), tile_angle_deg=realised_deg)


def checkerboard(square_mm: float = 5.0, size_mm: Size = DEFAULT_SIZE_MM, ratio_range: Range = DEFAULT_RANGE,
                 px_per_mm: float | None = None) -> Texture:
    """Alternating sticky and slippery squares; the square snaps (per axis) to an even number across
    each side so the texture tiles.

    Parameters
    ----------
    square_mm : float
        A square's side (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slippery and the sticky squares (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the squares.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size or range out of bounds, in one line.

    Examples
    --------
    >>> board = checkerboard(square_mm=5.0, size_mm=(20.0, 10.0))
    >>> sorted({round(float(v), 2) for v in board.values.ravel()})
    [0.4, 1.0]
    """
    _check_positive(square_mm=square_mm)
    x, y = _grid(size_mm, square_mm, px_per_mm)
    across, square_x = _whole(2 * square_mm, size_mm[0])
    down, square_y = _whole(2 * square_mm, size_mm[1])
    square_x, square_y = square_x / 2, square_y / 2
    pattern = ((np.floor(x / square_x) + np.floor(y / square_y)) % 2 == 0).astype(float)
    return _finish(pattern, size_mm, ratio_range, "checkerboard",
                   f"checkerboard of {square_x:.3g} × {square_y:.3g} mm squares", square_mm=square_mm,
                   tile_square_mm=[square_x, square_y])


def _lattice(size_mm, pitch_mm: float, x, y):
    """Offsets from the nearest lattice site, the pitch snapped per axis to whole cells per side."""
    _, pitch_x = _whole(pitch_mm, size_mm[0])
    _, pitch_y = _whole(pitch_mm, size_mm[1])
    return (x % pitch_x) - pitch_x / 2, (y % pitch_y) - pitch_y / 2, [pitch_x, pitch_y]


def dots(pitch_mm: float = 4.0, diameter_mm: float = 2.0, size_mm: Size = DEFAULT_SIZE_MM,
         ratio_range: Range = DEFAULT_RANGE, px_per_mm: float | None = None) -> Texture:
    """Sticky round dots on a slippery ground, on a lattice whose pitch snaps to whole cells per side.

    Parameters
    ----------
    pitch_mm : float
        The distance between dot centres (mm).
    diameter_mm : float
        A dot's diameter (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the ground and of the dots (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the dots.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, pitch or range out of bounds, in one line.

    Examples
    --------
    >>> texture = dots(pitch_mm=4.0, diameter_mm=2.0, size_mm=(20.0, 20.0))
    >>> sticky = float((texture.values > 0.7).mean())      # a 2 mm disc in each 4 mm cell: π/16 of the area
    >>> abs(sticky - 3.14159 / 16) < 0.02
    True
    """
    _check_positive(pitch_mm=pitch_mm, diameter_mm=diameter_mm)
    x, y = _grid(size_mm, min(pitch_mm, diameter_mm), px_per_mm)
    dx, dy, pitches = _lattice(size_mm, pitch_mm, x, y)
    pixel = size_mm[0] / x.shape[1]
    pattern = np.clip((diameter_mm / 2 - np.hypot(dx, dy)) / pixel + 0.5, 0, 1)  # antialiased edge
    return _finish(pattern, size_mm, ratio_range, "dots",
                   f"{diameter_mm:g} mm dots every {pitches[0]:.3g} × {pitches[1]:.3g} mm",
                   pitch_mm=pitch_mm, diameter_mm=diameter_mm, tile_pitch_mm=pitches)


def bumps(pitch_mm: float = 10.0, diameter_mm: float = 8.0, size_mm=DEFAULT_SIZE_MM, ratio_range=DEFAULT_RANGE,
          px_per_mm: float | None = None) -> Texture:
    """Smooth round bumps (cos² profile) as a height map: a gradient texture, felt as bumps in every direction.

    Parameters
    ----------
    pitch_mm : float
        The bumps' spacing (mm), snapped so the texture tiles.
    diameter_mm : float
        Each bump's diameter (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> texture = bumps(pitch_mm=10.0, diameter_mm=8.0)
    >>> texture
    Texture('bumps', 80 × 50 mm, 800 × 500 px, gradient)
    """
    _check_positive(pitch_mm=pitch_mm, diameter_mm=diameter_mm)
    x, y = _grid(size_mm, diameter_mm / 4, px_per_mm)
    dx, dy, pitches = _lattice(size_mm, pitch_mm, x, y)
    radius = np.hypot(dx, dy)
    height = np.where(radius < diameter_mm / 2, np.cos(np.pi * radius / diameter_mm) ** 2, 0.0)
    return _finish(height, size_mm, ratio_range, "bumps",
                   f"{diameter_mm:g} mm bumps every {pitches[0]:.3g} × {pitches[1]:.3g} mm",
                   kind="gradient", pitch_mm=pitch_mm, diameter_mm=diameter_mm, tile_pitch_mm=pitches)


def _normalised(field: np.ndarray) -> np.ndarray:
    span = field.max() - field.min()
    return (field - field.min()) / span if span > 0 else np.full_like(field, 0.5)


def noise(cutoff_mm: float = 2.0, size_mm: Size = DEFAULT_SIZE_MM, seed: int = 0, ratio_range: Range = DEFAULT_RANGE,
          px_per_mm: float | None = None) -> Texture:
    """Band-limited random roughness: no wavelength shorter than ``cutoff_mm``; tiles seamlessly.

    Parameters
    ----------
    cutoff_mm : float
        The shortest wavelength (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    seed : int
        The random generator's seed: the same seed, the same texture.
    ratio_range : (float, float)
        The friction ratios the roughness spans (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the cutoff.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, cutoff or range out of bounds, in one line.

    Examples
    --------
    >>> a, b = noise(seed=3, size_mm=(20.0, 10.0)), noise(seed=3, size_mm=(20.0, 10.0))
    >>> bool((a.values == b.values).all()), bool(0.4 <= a.values.min() and a.values.max() <= 1.0)
    (True, True)
    """
    _check_positive(cutoff_mm=cutoff_mm)
    x, _ = _grid(size_mm, cutoff_mm, px_per_mm)
    rows, cols = x.shape
    spectrum = np.fft.rfft2(np.random.default_rng(seed).standard_normal((rows, cols)))
    fy = np.fft.fftfreq(rows, d=size_mm[1] / rows)[:, None]
    fx = np.fft.rfftfreq(cols, d=size_mm[0] / cols)[None, :]
    spectrum[np.hypot(fx, fy) > 1.0 / cutoff_mm] = 0.0
    field = np.fft.irfft2(spectrum, s=(rows, cols))
    return _finish(_normalised(field), size_mm, ratio_range, "noise",
                   f"random roughness above {cutoff_mm:g} mm, seed {seed}", cutoff_mm=cutoff_mm, seed=seed)


def fractal(hurst: float = 0.5, cutoff_mm: float = 0.5, size_mm: Size = (40.0, 40.0), seed: int = 0,
            ratio_range: Range = DEFAULT_RANGE, px_per_mm: float | None = None) -> Texture:
    """Fractal (self-affine) roughness with Hurst exponent ``hurst`` in (0, 1), by spectral synthesis.

    Seeded white noise is shaped in the Fourier domain to the power spectrum of a 2-D
    fractional Brownian surface, P(f) ∝ |f|^-(2H+2), from the tile's size down to ``cutoff_mm``,
    with no mean (f = 0) term; low H is rough and jagged, high H smooth and rolling. Periodic by
    construction, so it tiles seamlessly.

    Parameters
    ----------
    hurst : float
        The Hurst exponent, in (0, 1).
    cutoff_mm : float
        The shortest wavelength (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    seed : int
        The random generator's seed.
    ratio_range : (float, float)
        The friction ratios the roughness spans (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the cutoff.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A Hurst exponent outside (0, 1), or a size, cutoff or range out of bounds, in one line.

    Examples
    --------
    >>> rough = fractal(hurst=0.3, size_mm=(10.0, 10.0))
    >>> rough.width_mm, bool(0.4 <= rough.values.min() and rough.values.max() <= 1.0)
    (10.0, True)
    """
    _check_positive(cutoff_mm=cutoff_mm)
    if not (np.isfinite(hurst) and 0 < hurst < 1):
        raise TextureError(f"the Hurst exponent must lie strictly between 0 and 1, got {hurst}")
    x, _ = _grid(size_mm, cutoff_mm, px_per_mm)
    rows, cols = x.shape
    spectrum = np.fft.rfft2(np.random.default_rng(seed).standard_normal((rows, cols)))
    fy = np.fft.fftfreq(rows, d=size_mm[1] / rows)[:, None]
    fx = np.fft.rfftfreq(cols, d=size_mm[0] / cols)[None, :]
    f = np.hypot(fx, fy)
    with np.errstate(divide="ignore"):
        gain = np.where((f > 0) & (f <= 1.0 / cutoff_mm), f ** -(hurst + 1.0), 0.0)
    field = np.fft.irfft2(spectrum * gain, s=(rows, cols))
    return _finish(_normalised(field), size_mm, ratio_range, "fractal",
                   f"fractal roughness, Hurst exponent {hurst:g}, down to {cutoff_mm:g} mm, seed {seed}",
                   hurst=hurst, cutoff_mm=cutoff_mm, seed=seed)


def gabor(wavelength_mm: float = 2.0, sigma_mm: float = 4.0, size_mm=(30.0, 30.0), angle_deg: float = 0.0,
          ratio_range=DEFAULT_RANGE, px_per_mm: float | None = None) -> Texture:
    """A Gabor patch: a sine grating under a round Gaussian window of ``sigma_mm``, centred; beyond
    the window the friction is the middle of the range, also outside the texture.

    Parameters
    ----------
    wavelength_mm : float
        The grating's period (mm).
    sigma_mm : float
        The window's standard deviation (mm).
    angle_deg : float
        The direction across the ridges (degrees).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> texture = gabor(wavelength_mm=2.0, sigma_mm=4.0, ratio_range=(0.4, 1.0))
    >>> texture.outside, round(texture.outside_ratio, 6)             # the middle of the range
    ('fixed', 0.7)
    >>> round(float(texture.values[0, 0]), 3)                         # a corner, far out of the window
    0.7
    """
    _check_positive(wavelength_mm=wavelength_mm, sigma_mm=sigma_mm)
    x, y = _grid(size_mm, min(wavelength_mm, sigma_mm), px_per_mm)
    cx, cy = x - size_mm[0] / 2, y - size_mm[1] / 2
    angle = np.deg2rad(angle_deg)
    across = cx * np.cos(angle) + cy * np.sin(angle)
    window = np.exp(-(cx ** 2 + cy ** 2) / (2 * sigma_mm ** 2))
    pattern = 0.5 + 0.5 * window * np.cos(2 * np.pi * across / wavelength_mm)
    low, high = ratio_range
    return _finish(pattern, size_mm, ratio_range, "gabor",
                   f"Gabor patch, {wavelength_mm:g} mm wavelength at {angle_deg:g}°, σ {sigma_mm:g} mm",
                   outside="fixed", outside_ratio=0.5 * (low + high), wavelength_mm=wavelength_mm,
                   sigma_mm=sigma_mm, angle_deg=angle_deg)


def bump(diameter_mm: float = 10.0, size_mm=(30.0, 30.0), ratio_range=DEFAULT_RANGE,
         px_per_mm: float | None = None) -> Texture:
    """One smooth round bump (cos² profile) in the middle of flat ground: a gradient texture.

    Parameters
    ----------
    diameter_mm : float
        The bump's diameter (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> texture = bump(diameter_mm=10.0)
    >>> texture.kind, texture.outside, round(texture.outside_ratio, 6)   # flat ground: the middle
    ('gradient', 'fixed', 0.7)
    """
    _check_positive(diameter_mm=diameter_mm)
    x, y = _grid(size_mm, diameter_mm / 4, px_per_mm)
    radius = np.hypot(x - size_mm[0] / 2, y - size_mm[1] / 2)
    height = np.where(radius < diameter_mm / 2, np.cos(np.pi * radius / diameter_mm) ** 2, 0.0)
    low, high = ratio_range
    return _finish(height, size_mm, ratio_range, "bump", f"a single {diameter_mm:g} mm bump", kind="gradient",
                   outside="fixed", outside_ratio=0.5 * (low + high), diameter_mm=diameter_mm)


def edge(width_mm: float = 0.5, size_mm=(40.0, 30.0), ratio_range=DEFAULT_RANGE,
         px_per_mm: float | None = None) -> Texture:
    """One straight edge down the middle: slippery on the left, sticky on the right, the step
    spread over ``width_mm`` (a raised-cosine ramp); the two sides extend beyond the texture.

    Parameters
    ----------
    width_mm : float
        How wide the step is (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> texture = edge(width_mm=0.5, size_mm=(40.0, 30.0), ratio_range=(0.4, 1.0))
    >>> round(float(texture.values[0, 0]), 3), round(float(texture.values[0, -1]), 3), texture.outside
    (0.4, 1.0, 'clamp')
    """
    _check_positive(width_mm=width_mm)
    x, _ = _grid(size_mm, width_mm, px_per_mm)
    t = np.clip((x - size_mm[0] / 2) / width_mm + 0.5, 0.0, 1.0)
    pattern = 0.5 - 0.5 * np.cos(np.pi * t)
    return _finish(pattern, size_mm, ratio_range, "edge", f"one edge, slippery to sticky over {width_mm:g} mm",
                   outside="clamp", width_mm=width_mm)


def lines(widths_mm=(0.25, 0.5, 1.0, 2.0, 4.0), spacing_mm: float = 10.0, size_mm=(80.0, 40.0),
          ratio_range=DEFAULT_RANGE, px_per_mm: float | None = None) -> Texture:
    """Single sticky vertical lines of the given widths, ``spacing_mm`` apart (centre to centre),
    centred on a slippery ground: a chart for the finest line a finger finds.

    Parameters
    ----------
    widths_mm : sequence of float
        The lines' widths (mm), left to right; one or more.
    spacing_mm : float
        From one line's centre to the next (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> texture = lines(widths_mm=(0.5, 2.0), spacing_mm=10.0, size_mm=(40.0, 20.0), ratio_range=(0.4, 1.0))
    >>> texture.description
    'single lines 0.5, 2 mm wide, 10 mm apart'
    >>> [round(float(texture.values[0, texture.cols * x // 40]), 3) for x in (5, 15, 25)]  # ground, line, line
    [0.4, 1.0, 1.0]
    """
    widths = [float(w) for w in widths_mm]
    if not widths:
        raise TextureError("lines needs at least one width")
    _check_positive(spacing_mm=spacing_mm, **{f"width_{i}": w for i, w in enumerate(widths)})
    x, _ = _grid(size_mm, min(widths), px_per_mm)
    pixel = size_mm[0] / x.shape[1]
    centres = size_mm[0] / 2 + spacing_mm * (np.arange(len(widths)) - (len(widths) - 1) / 2)
    pattern = np.zeros_like(x)
    for centre, width in zip(centres, widths, strict=True):  # a handful of lines, each antialiased
        pattern = np.maximum(pattern, np.clip((width / 2 - np.abs(x - centre)) / pixel + 0.5, 0, 1))
    low, _ = ratio_range
    return _finish(pattern, size_mm, ratio_range, "lines",
                   f"single lines {', '.join(f'{w:g}' for w in widths)} mm wide, {spacing_mm:g} mm apart",
                   outside="fixed", outside_ratio=low, widths_mm=widths, spacing_mm=spacing_mm)


def chirp(start_mm: float = 4.0, end_mm: float = 0.5, size_mm=DEFAULT_SIZE_MM, ratio_range=DEFAULT_RANGE,
          px_per_mm: float | None = None) -> Texture:
    """A sine grating whose wavelength sweeps from ``start_mm`` at the left to ``end_mm`` at the right.

    Parameters
    ----------
    start_mm, end_mm : float
        The wavelengths (mm) at the left and right edges.
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> chirp(start_mm=4.0, end_mm=0.5).description
    'wavelength sweeping 4 → 0.5 mm'
    """
    _check_positive(start_mm=start_mm, end_mm=end_mm)
    x, _ = _grid(size_mm, min(start_mm, end_mm), px_per_mm)
    width = size_mm[0]
    if np.isclose(start_mm, end_mm):
        phase = 2 * np.pi * x / start_mm
    else:  # phase = 2 pi ∫ dx / lambda(x), lambda linear in x
        slope = (end_mm - start_mm) / width
        phase = 2 * np.pi / slope * np.log1p(slope * x / start_mm)
    pattern = 0.5 + 0.5 * np.cos(phase)
    return _finish(pattern, size_mm, ratio_range, "chirp", f"wavelength sweeping {start_mm:g} → {end_mm:g} mm",
                   outside="clamp", start_mm=start_mm, end_mm=end_mm)


def _box(x, y, left, top, width, height):
    return (x >= left) & (x < left + width) & (y >= top) & (y < top + height)


def button(size_mm=(60.0, 40.0), button_mm=(36.0, 20.0), edge_mm: float = 1.5, ratio_range=DEFAULT_RANGE,
           px_per_mm: float | None = None) -> Texture:
    """A button: sticky raised edges around a half-sticky face, on a slippery ground.

    Parameters
    ----------
    button_mm : (float, float)
        The button's width and height (mm), centred.
    edge_mm : float
        How wide its raised edge is (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> texture = button(ratio_range=(0.4, 1.0))
    >>> round(float(texture.values[0, 0]), 3), round(float(texture.values[texture.rows // 2, texture.cols // 2]), 3)
    (0.4, 0.7)
    """
    _check_positive(edge_mm=edge_mm)
    x, y = _grid(size_mm, edge_mm, px_per_mm)
    left, top = (size_mm[0] - button_mm[0]) / 2, (size_mm[1] - button_mm[1]) / 2
    outer = _box(x, y, left, top, *button_mm)
    inner = _box(x, y, left + edge_mm, top + edge_mm, button_mm[0] - 2 * edge_mm, button_mm[1] - 2 * edge_mm)
    pattern = np.where(inner, 0.5, np.where(outer, 1.0, 0.0))
    return _finish(pattern, size_mm, ratio_range, "button", f"a {button_mm[0]:g}×{button_mm[1]:g} mm button "
                   "with raised edges", outside="fixed", edge_mm=edge_mm)


def slider(size_mm=(80.0, 20.0), detents: int = 5, detent_mm: float = 1.0, ratio_range=DEFAULT_RANGE,
           px_per_mm: float | None = None) -> Texture:
    """A horizontal slider track with sticky detents at evenly spaced stops and sticky rails.

    Parameters
    ----------
    detents : int
        How many stops, 2 or more.
    detent_mm : float
        Each detent's width (mm), and the rails'.
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> slider(detents=5)
    Texture('slider', 80 × 20 mm, 800 × 200 px)
    >>> slider(detents=1)
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: a slider needs at least 2 detents, got 1
    """
    if detents < 2:
        raise TextureError(f"a slider needs at least 2 detents, got {detents}")
    _check_positive(detent_mm=detent_mm)
    x, y = _grid(size_mm, detent_mm, px_per_mm)
    margin = size_mm[0] * 0.08
    stops = np.linspace(margin, size_mm[0] - margin, detents)
    distance = np.min(np.abs(x[..., None] - stops), axis=-1)
    track_top, track_height = size_mm[1] * 0.3, size_mm[1] * 0.4
    track = _box(x, y, margin - detent_mm, track_top, size_mm[0] - 2 * margin + 2 * detent_mm, track_height)
    rails = track & ~_box(x, y, margin - detent_mm, track_top + detent_mm, size_mm[0] - 2 * margin + 2 * detent_mm,
                          track_height - 2 * detent_mm)
    detent = np.clip(1.0 - distance / (detent_mm / 2), 0, 1)
    pattern = np.where(rails, 1.0, np.where(track, 0.15 + 0.85 * detent, 0.0))
    return _finish(pattern, size_mm, ratio_range, "slider", f"a slider with {detents} detents", outside="fixed",
                   detents=detents, detent_mm=detent_mm)


def toggle(size_mm=(40.0, 24.0), on: bool = False, ratio_range=DEFAULT_RANGE,
           px_per_mm: float | None = None) -> Texture:
    """A toggle switch: a rounded track with a sticky knob at one end.

    Parameters
    ----------
    on : bool
        The knob at the right (on) or the left (off).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> toggle(on=True).description
    'a toggle switch, on'
    """
    x, y = _grid(size_mm, 1.0, px_per_mm)
    centre_y, radius = size_mm[1] / 2, size_mm[1] * 0.35
    left, right = size_mm[0] * 0.25, size_mm[0] * 0.75
    along = np.clip(x, left, right)
    track = np.hypot(x - along, y - centre_y) < radius
    knob_x = right if on else left
    knob = np.hypot(x - knob_x, y - centre_y) < radius * 0.8
    pattern = np.where(knob, 1.0, np.where(track, 0.3, 0.0))
    return _finish(pattern, size_mm, ratio_range, "toggle", f"a toggle switch, {'on' if on else 'off'}",
                   outside="fixed", on=on)


def keyboard(size_mm=(90.0, 30.0), keys=(10, 3), edge_mm: float = 0.8, ratio_range=DEFAULT_RANGE,
             px_per_mm: float | None = None) -> Texture:
    """A small keyboard: a grid of keys whose edges are sticky ridges and faces slippery.

    Parameters
    ----------
    keys : (int, int)
        Keys across and down.
    edge_mm : float
        How wide each key's edge is (mm).
    size_mm : (float, float)
        The texture's width and height (mm).
    ratio_range : (float, float)
        The friction ratios of the slipperiest and stickiest parts (0..1).
    px_per_mm : float, optional
        The resolution; by default fine enough for the finest feature.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A size, feature or range out of bounds, in one line.

    Examples
    --------
    >>> keyboard(keys=(10, 3)).description
    'a 10×3 keyboard with key edges'
    """
    _check_positive(edge_mm=edge_mm)
    x, y = _grid(size_mm, edge_mm, px_per_mm)
    key_w, key_h = size_mm[0] / keys[0], size_mm[1] / keys[1]
    fx, fy = x % key_w, y % key_h
    gap = edge_mm
    face = (fx > gap) & (fx < key_w - gap) & (fy > gap) & (fy < key_h - gap)
    pattern = np.where(face, 0.0, 1.0)
    return _finish(pattern, size_mm, ratio_range, "keyboard", f"a {keys[0]}×{keys[1]} keyboard with key edges",
                   outside="fixed", keys=list(keys), edge_mm=edge_mm)


GENERATORS = {
    "grating": grating,
    "checkerboard": checkerboard,
    "dots": dots,
    "bumps": bumps,
    "noise": noise,
    "fractal": fractal,
    "gabor": gabor,
    "bump": bump,
    "edge": edge,
    "lines": lines,
    "chirp": chirp,
    "button": button,
    "slider": slider,
    "toggle": toggle,
    "keyboard": keyboard,
}
