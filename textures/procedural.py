"""Textures from parameters: gratings, checkerboards, dots, bumps, noise, a chirp, UI elements.

Every generator takes a physical size in millimetres and a friction range ``ratio_range`` (low,
high): the ratio where the pattern is "off" (slippery) and "on" (sticky). The resolution is
chosen so that the finest feature spans at least 8 pixels, unless ``px_per_mm`` says otherwise.
"""

from __future__ import annotations

import numpy as np
from ultraglide.textures.errors import TextureError
from ultraglide.textures.texture import Texture

DEFAULT_SIZE_MM = (80.0, 50.0)
DEFAULT_RANGE = (0.4, 1.0)
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


def _finish(pattern, size_mm, ratio_range, name, description, kind="friction", outside="tile", **authoring):
    low, high = ratio_range
    if not 0 <= low <= high <= 1:
        raise TextureError(f"range must satisfy 0 <= low <= high <= 1, got {low} {high}")
    pattern = np.clip(pattern, 0.0, 1.0)
    values = pattern if kind == "gradient" else low + (high - low) * pattern
    return Texture(values.astype(np.float32), float(size_mm[0]), float(size_mm[1]), kind=kind,
                   outside=outside, ratio_range=(low, high), name=name, description=description,
                   source="procedural", authoring={"generator": name.split("-")[0], **authoring})


def grating(wavelength_mm: float = 1.0, size_mm=DEFAULT_SIZE_MM, angle_deg: float = 0.0,
            shape: str = "sine", ratio_range=DEFAULT_RANGE, px_per_mm: float | None = None) -> Texture:
    """Parallel ridges of one wavelength; ``angle_deg`` turns the direction across them."""
    _check_positive(wavelength_mm=wavelength_mm)
    if shape not in ("sine", "square"):
        raise TextureError(f"grating shape must be sine or square, got {shape!r}")
    x, y = _grid(size_mm, wavelength_mm, px_per_mm)
    angle = np.deg2rad(angle_deg)
    across = x * np.cos(angle) + y * np.sin(angle)
    wave = np.cos(2 * np.pi * across / wavelength_mm)
    pattern = 0.5 + 0.5 * wave if shape == "sine" else (wave >= 0).astype(float)
    return _finish(pattern, size_mm, ratio_range, f"grating-{shape}",
                   f"{shape} grating, {wavelength_mm:g} mm wavelength at {angle_deg:g}°",
                   wavelength_mm=wavelength_mm, angle_deg=angle_deg, shape=shape)


def checkerboard(square_mm: float = 5.0, size_mm=DEFAULT_SIZE_MM, ratio_range=DEFAULT_RANGE,
                 px_per_mm: float | None = None) -> Texture:
    """Alternating sticky and slippery squares."""
    _check_positive(square_mm=square_mm)
    x, y = _grid(size_mm, square_mm, px_per_mm)
    pattern = ((np.floor(x / square_mm) + np.floor(y / square_mm)) % 2 == 0).astype(float)
    return _finish(pattern, size_mm, ratio_range, "checkerboard", f"checkerboard of {square_mm:g} mm squares",
                   square_mm=square_mm)


def dots(pitch_mm: float = 4.0, diameter_mm: float = 2.0, size_mm=DEFAULT_SIZE_MM, ratio_range=DEFAULT_RANGE,
         px_per_mm: float | None = None) -> Texture:
    """Sticky round dots on a slippery ground, on a square lattice."""
    _check_positive(pitch_mm=pitch_mm, diameter_mm=diameter_mm)
    x, y = _grid(size_mm, min(pitch_mm, diameter_mm), px_per_mm)
    dx = (x % pitch_mm) - pitch_mm / 2
    dy = (y % pitch_mm) - pitch_mm / 2
    pixel = size_mm[0] / x.shape[1]
    pattern = np.clip((diameter_mm / 2 - np.hypot(dx, dy)) / pixel + 0.5, 0, 1)  # antialiased edge
    return _finish(pattern, size_mm, ratio_range, "dots", f"{diameter_mm:g} mm dots every {pitch_mm:g} mm",
                   pitch_mm=pitch_mm, diameter_mm=diameter_mm)


def bumps(pitch_mm: float = 10.0, diameter_mm: float = 8.0, size_mm=DEFAULT_SIZE_MM, ratio_range=DEFAULT_RANGE,
          px_per_mm: float | None = None) -> Texture:
    """Smooth round bumps as a height map: a gradient texture, felt as bumps in every direction."""
    _check_positive(pitch_mm=pitch_mm, diameter_mm=diameter_mm)
    x, y = _grid(size_mm, diameter_mm / 4, px_per_mm)
    radius = np.hypot((x % pitch_mm) - pitch_mm / 2, (y % pitch_mm) - pitch_mm / 2)
    height = np.where(radius < diameter_mm / 2, np.cos(np.pi * radius / diameter_mm) ** 2, 0.0)
    return _finish(height, size_mm, ratio_range, "bumps", f"{diameter_mm:g} mm bumps every {pitch_mm:g} mm",
                   kind="gradient", pitch_mm=pitch_mm, diameter_mm=diameter_mm)


def noise(cutoff_mm: float = 2.0, size_mm=DEFAULT_SIZE_MM, seed: int = 0, ratio_range=DEFAULT_RANGE,
          px_per_mm: float | None = None) -> Texture:
    """Band-limited random roughness: no wavelength shorter than ``cutoff_mm``; tiles seamlessly."""
    _check_positive(cutoff_mm=cutoff_mm)
    x, _ = _grid(size_mm, cutoff_mm, px_per_mm)
    rows, cols = x.shape
    spectrum = np.fft.rfft2(np.random.default_rng(seed).standard_normal((rows, cols)))
    fy = np.fft.fftfreq(rows, d=size_mm[1] / rows)[:, None]
    fx = np.fft.rfftfreq(cols, d=size_mm[0] / cols)[None, :]
    spectrum[np.hypot(fx, fy) > 1.0 / cutoff_mm] = 0.0
    field = np.fft.irfft2(spectrum, s=(rows, cols))
    span = field.max() - field.min()
    pattern = (field - field.min()) / span if span > 0 else np.full_like(field, 0.5)
    return _finish(pattern, size_mm, ratio_range, "noise", f"random roughness above {cutoff_mm:g} mm, seed {seed}",
                   cutoff_mm=cutoff_mm, seed=seed)


def chirp(start_mm: float = 4.0, end_mm: float = 0.5, size_mm=DEFAULT_SIZE_MM, ratio_range=DEFAULT_RANGE,
          px_per_mm: float | None = None) -> Texture:
    """A sine grating whose wavelength sweeps from ``start_mm`` at the left to ``end_mm`` at the right."""
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
    """A button: sticky raised edges around a half-sticky face, on a slippery ground."""
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
    """A horizontal slider track with sticky detents at evenly spaced stops and sticky rails."""
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
    """A toggle switch: a rounded track with a sticky knob at one end."""
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
    """A small keyboard: a grid of keys whose edges are sticky ridges and faces slippery."""
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
    "chirp": chirp,
    "button": button,
    "slider": slider,
    "toggle": toggle,
    "keyboard": keyboard,
}
