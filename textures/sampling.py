"""Sampling a texture at finger positions: bilinear, band-limited, and along the motion.

A :class:`Sampler` is built once per texture and then answers vectorised queries fast enough for
the real-time path. Band limiting uses a pyramid of prefiltered levels (each a Gaussian-blurred,
half-resolution copy of the one before); a query that moves ``step_mm`` between successive samples
reads the level whose pixels are ``step_mm`` wide, blending the two nearest (trilinear), so detail
finer than the sampling can follow averages out instead of aliasing to a false low frequency.

Example::

    >>> import numpy as np
    >>> from textures.procedural import grating
    >>> sampler = Sampler(grating(wavelength_mm=2.0, size_mm=(20, 10)))
    >>> sampler.ratio(np.array([0.5, 1.5]), np.array([5.0, 5.0])).round(2).tolist()
    [1.0, 0.0]
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from textures.texture import Texture, gradient_ratio

MIN_LEVEL_PIXELS = 2


def gradient_maps(texture: Texture) -> tuple[np.ndarray, np.ndarray]:
    """Slopes (d/dx, d/dy) of a height map, in height units per millimetre."""
    pixel_x, pixel_y = texture.pixel_mm
    values = texture.values.astype(float)
    if texture.outside == "tile":  # periodic differences, so the slope is right across the seam
        slope_x = (np.roll(values, -1, axis=1) - np.roll(values, 1, axis=1)) / (2 * pixel_x)
        slope_y = (np.roll(values, -1, axis=0) - np.roll(values, 1, axis=0)) / (2 * pixel_y)
    else:
        slope_y, slope_x = np.gradient(values, pixel_y, pixel_x)
    return slope_x.astype(np.float32), slope_y.astype(np.float32)


def _pyramid(image: np.ndarray, wrap: bool, levels: int) -> list[np.ndarray]:
    pyramid = [np.ascontiguousarray(image, dtype=np.float32)]
    mode, grid_mode = ("wrap", "grid-wrap") if wrap else ("nearest", "nearest")
    while len(pyramid) < levels and min(pyramid[-1].shape) >= 2 * MIN_LEVEL_PIXELS:
        previous = pyramid[-1]
        blurred = ndimage.gaussian_filter(previous, sigma=1.0, mode=mode)
        shape = (max(1, round(previous.shape[0] / 2)), max(1, round(previous.shape[1] / 2)))
        zoom = (shape[0] / previous.shape[0], shape[1] / previous.shape[1])
        pyramid.append(ndimage.zoom(blurred, zoom, order=1, mode=grid_mode, grid_mode=True).astype(np.float32))
    return pyramid


class Sampler:
    """Vectorised lookups of the friction ratio of one texture; see the module docstring."""

    def __init__(self, texture: Texture, band_limited: bool = True, max_levels: int = 16):
        self.texture = texture
        self.tile = texture.outside == "tile"
        if texture.kind == "gradient":
            channels = gradient_maps(texture)
        else:
            channels = (texture.values,)
        pyramids = [_pyramid(c, self.tile, max_levels if band_limited else 1) for c in channels]
        levels = pyramids[0]
        self.levels = len(levels)
        self.rows = np.array([level.shape[0] for level in levels], dtype=np.intp)
        self.cols = np.array([level.shape[1] for level in levels], dtype=np.intp)
        self.offset = np.concatenate([[0], np.cumsum(self.rows * self.cols)[:-1]]).astype(np.intp)
        self.per_mm_x = self.cols / texture.width_mm
        self.per_mm_y = self.rows / texture.height_mm
        self.buffers = [np.concatenate([level.ravel() for level in p]) for p in pyramids]
        self.base_pixel_mm = max(texture.pixel_mm)

    def _bilinear(self, buffer, x_mm, y_mm, level):
        """Bilinear interpolation at one pyramid level (a scalar) or per-sample levels (an array)."""
        rows, cols = self.rows[level], self.cols[level]
        u = x_mm * self.per_mm_x[level] - 0.5
        v = y_mm * self.per_mm_y[level] - 0.5
        col0 = np.floor(u)
        row0 = np.floor(v)
        fu = (u - col0).astype(np.float32)
        fv = (v - row0).astype(np.float32)
        col0 = col0.astype(np.intp)
        row0 = row0.astype(np.intp)
        if self.tile:
            col0 %= cols
            row0 %= rows
            col1 = col0 + 1
            row1 = row0 + 1
            col1[col1 >= cols] = 0
            row1[row1 >= rows] = 0
        else:
            col1 = np.clip(col0 + 1, 0, cols - 1)
            row1 = np.clip(row0 + 1, 0, rows - 1)
            np.clip(col0, 0, cols - 1, out=col0)
            np.clip(row0, 0, rows - 1, out=row0)
        top = self.offset[level] + row0 * cols
        bottom = self.offset[level] + row1 * cols
        a = buffer.take(top + col0)
        b = buffer.take(top + col1)
        c = buffer.take(bottom + col0)
        d = buffer.take(bottom + col1)
        upper = a + fu * (b - a)
        lower = c + fu * (d - c)
        return upper + fv * (lower - upper)

    def _channel(self, buffer, x_mm, y_mm, step_mm):
        if step_mm is None or self.levels == 1:
            return self._bilinear(buffer, x_mm, y_mm, 0)
        level = np.log2(np.maximum(np.asarray(step_mm, dtype=float), 1e-12) / self.base_pixel_mm)
        level = np.clip(level, 0.0, self.levels - 1.0)
        low = np.floor(level).astype(np.intp)
        high = np.minimum(low + 1, self.levels - 1)
        weight = (level - low).astype(np.float32)
        if np.ndim(level) == 0:
            low, high = int(low), int(high)
        else:
            low = np.broadcast_to(low, np.shape(x_mm))
            high = np.broadcast_to(high, np.shape(x_mm))
        near = self._bilinear(buffer, x_mm, y_mm, low)
        far = self._bilinear(buffer, x_mm, y_mm, high)
        return near + weight * (far - near)

    def ratio(self, x_mm, y_mm, step_mm=None, direction=None) -> np.ndarray:
        """Friction ratio at positions (mm), float32.

        ``step_mm`` (scalar or per sample) is the distance the finger moves between samples; give
        it to band-limit the lookup. ``direction`` is a pair of arrays (dx, dy) of the motion,
        needed by gradient textures (any length; zero means at rest, which reads as flat ground).
        """
        x_mm = np.asarray(x_mm, dtype=float)
        y_mm = np.asarray(y_mm, dtype=float)
        texture = self.texture
        if texture.kind == "friction":
            ratio = self._channel(self.buffers[0], x_mm, y_mm, step_mm)
        else:
            slope_x = self._channel(self.buffers[0], x_mm, y_mm, step_mm)
            slope_y = self._channel(self.buffers[1], x_mm, y_mm, step_mm)
            if direction is None:
                slope = np.zeros_like(slope_x)
            else:
                dx, dy = (np.asarray(d, dtype=np.float32) for d in direction)
                length = np.hypot(dx, dy)
                with np.errstate(invalid="ignore", divide="ignore"):
                    slope = np.where(length > 0, (slope_x * dx + slope_y * dy) / length, 0.0)
            ratio = gradient_ratio(texture, slope)
        if texture.outside == "fixed":
            beyond = (x_mm < 0) | (x_mm >= texture.width_mm) | (y_mm < 0) | (y_mm >= texture.height_mm)
            ratio = np.where(beyond, np.float32(texture.outside_ratio), ratio)
        return ratio
