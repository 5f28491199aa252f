"""Sampling a texture at finger positions: bilinear, band-limited, and along the motion.

A :class:`Sampler` is built once per texture and then answers vectorised queries fast enough for
the real-time path; the interpolation is a compiled bilinear kernel (:mod:`textures.kernels`),
identical to scipy's ``map_coordinates(order=1)`` with grid-wrap or nearest edges.

Band limiting uses a pyramid of prefiltered levels (each a Gaussian-blurred, half-resolution
copy of the one before); a query that moves ``step_mm`` between successive samples
reads the level whose pixels are ``step_mm`` wide, blending the two nearest (trilinear), so detail
finer than the sampling can follow averages out instead of aliasing to a false low frequency.

Examples
--------
>>> import numpy as np
>>> from ultraglide.textures.procedural import grating
>>> sampler = Sampler(grating(wavelength_mm=2.0, size_mm=(20, 10)))
>>> [round(float(r), 2) for r in sampler.ratio(np.array([1.0, 2.0]), np.array([5.0, 5.0]))]
[0.4, 1.0]
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.textures import kernels
from ultraglide.textures.texture import Texture, gradient_ratio

MIN_LEVEL_PIXELS = 2


def gradient_maps(texture: Texture) -> tuple[np.ndarray, np.ndarray]:
    """Slopes (d/dx, d/dy) of a height map, in height units per millimetre: central differences over the
    pixels' pitch, wrapping around the edges.

    Parameters
    ----------
    texture : Texture
        A gradient texture (its values are heights).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        d/dx and d/dy, rows × cols each.

    Examples
    --------
    >>> import numpy as np
    >>> hill = Texture(np.array([[0.0, 0.5, 1.0]] * 2), width_mm=3.0, height_mm=2.0, kind="gradient")
    >>> slope_x, slope_y = gradient_maps(hill)
    >>> slope_x[0].tolist(), slope_y[0].tolist()     # (1 - 0) / 2 mm in the middle; the edges wrap
    ([-0.25, 0.5, -0.25], [0.0, 0.0, 0.0])
    """
    pixel_x, pixel_y = texture.pixel_mm
    values = texture.values.astype(float)
    if texture.outside == "tile":  # periodic differences, so the slope is right across the seam
        slope_x = (np.roll(values, -1, axis=1) - np.roll(values, 1, axis=1)) / (2 * pixel_x)
        slope_y = (np.roll(values, -1, axis=0) - np.roll(values, 1, axis=0)) / (2 * pixel_y)
    else:
        slope_y, slope_x = np.gradient(values, pixel_y, pixel_x)
    return slope_x.astype(np.float32), slope_y.astype(np.float32)


# a Gaussian of one pixel's sigma cut at four sigmas (scipy.ndimage's default): the blur before each halving
_BLUR_TAPS = np.exp(-0.5 * np.arange(-4.0, 5.0) ** 2)
_BLUR_TAPS /= _BLUR_TAPS.sum()


def _blur(image: np.ndarray, wrap: bool) -> np.ndarray:
    """``image`` blurred by a Gaussian of one pixel, down the columns then along the rows; past the edges it
    wraps round (a tile) or repeats the edge pixel. What ``scipy.ndimage.gaussian_filter(sigma=1)`` computes
    (to float32's rounding), without loading scipy (0.15 s of a command's start) for it."""
    return _blur_columns(_blur_columns(np.asarray(image, dtype=np.float32), wrap).T, wrap).T


def _blur_columns(image: np.ndarray, wrap: bool) -> np.ndarray:
    radius = len(_BLUR_TAPS) // 2
    padded = np.pad(image, ((radius, radius), (0, 0)), mode="wrap" if wrap else "edge")
    n = image.shape[0]
    out = padded[radius:radius + n] * np.float32(_BLUR_TAPS[radius])
    pair = np.empty_like(out)
    for k in range(radius):  # the taps are symmetric: one product for the pair either side
        np.add(padded[k:k + n], padded[2 * radius - k:2 * radius - k + n], out=pair)
        pair *= np.float32(_BLUR_TAPS[k])
        out += pair
    return out


def _halve(image: np.ndarray, wrap: bool) -> np.ndarray:
    """``image`` at half its size on each axis (rounded), each new pixel interpolated linearly at its centre
    (``scipy.ndimage.zoom(order=1, grid_mode=True)``); past the edges it wraps round or repeats the edge."""
    for axis in (0, 1):
        n = image.shape[axis]
        m = max(1, round(n / 2))
        centre = (np.arange(m) + 0.5) * (n / m) - 0.5  # in the input's pixels
        low = np.floor(centre).astype(np.intp)
        fraction = (centre - low).astype(np.float32)
        below, above = (low % n, (low + 1) % n) if wrap else (np.clip(low, 0, n - 1), np.clip(low + 1, 0, n - 1))
        if axis == 1:
            image = image[:, below] * (1 - fraction) + image[:, above] * fraction
        else:
            image = image[below] * (1 - fraction)[:, None] + image[above] * fraction[:, None]
    return image


def _pyramid(image: np.ndarray, wrap: bool, levels: int) -> list[np.ndarray]:
    pyramid = [np.ascontiguousarray(image, dtype=np.float32)]
    while len(pyramid) < levels and min(pyramid[-1].shape) >= 2 * MIN_LEVEL_PIXELS:
        pyramid.append(np.ascontiguousarray(_halve(_blur(pyramid[-1], wrap), wrap), dtype=np.float32))
    for level in pyramid:  # immutable lookup data; also one array type for the compiled lookups
        level.setflags(write=False)
    return pyramid


class Sampler:
    """Vectorised lookups of the friction ratio of one texture; see the module docstring.

    Parameters
    ----------
    texture : Texture
    band_limited : bool
        Average over the distance a sample's step covers (a pyramid of levels), so fine detail does not alias.
    max_levels : int
        The pyramid's levels at most.

    Examples
    --------
    >>> import numpy as np
    >>> halves = Texture(np.array([[0.2, 0.8]]), width_mm=2.0, height_mm=1.0)
    >>> Sampler(halves, band_limited=False).ratio([0.5, 1.5, 2.5], [0.5, 0.5, 0.5]).tolist()   # mm; tiled beyond
    [0.20000000298023224, 0.800000011920929, 0.20000000298023224]
    """

    def __init__(self, texture: Texture, band_limited: bool = True, max_levels: int = 16):
        kernels.warm_up()
        self.texture = texture
        self.tile = texture.outside == "tile"
        if texture.kind == "gradient":
            channels = gradient_maps(texture)
        else:
            channels = (texture.values,)
        self.pyramids = [_pyramid(c, self.tile, max_levels if band_limited else 1) for c in channels]
        levels = self.pyramids[0]
        self.levels = len(levels)
        if texture.kind == "friction":  # the levels one after another, for the compiled per-sample-step lookup
            sizes = [level.size for level in levels]
            self._flat = np.concatenate([level.reshape(-1) for level in levels])
            self._flat.setflags(write=False)
            self._starts = np.cumsum([0, *sizes[:-1]]).astype(np.intp)
            self._rows = np.array([level.shape[0] for level in levels], dtype=np.intp)
            self._cols = np.array([level.shape[1] for level in levels], dtype=np.intp)
        self.per_mm_x = [level.shape[1] / texture.width_mm for level in levels]
        self.per_mm_y = [level.shape[0] / texture.height_mm for level in levels]
        self.base_pixel_mm = max(texture.pixel_mm)
        self._per_mm = (np.array(self.per_mm_x), np.array(self.per_mm_y))
        self._fixed = texture.outside == "fixed"
        self._outside = np.float32(texture.outside_ratio if self._fixed else 1.0)
        if texture.kind == "gradient":
            low, high = texture.ratio_range
            self._gradient = (0.5 * (low + high), 0.5 * (high - low) / texture.full_slope_per_mm, low, high)

    def _bilinear(self, channel: int, x_mm, y_mm, level: int):
        """Bilinear interpolation at one pyramid level (:func:`textures.kernels.bilinear`)."""
        output = np.empty(np.shape(x_mm), dtype=np.float32)
        kernels.bilinear(self.pyramids[channel][level], x_mm.reshape(-1), y_mm.reshape(-1), self.per_mm_x[level],
                         self.per_mm_y[level], self.tile, output.reshape(-1))
        return output

    def _channel(self, channel: int, x_mm, y_mm, step_mm):
        if step_mm is None or self.levels == 1:
            return self._bilinear(channel, x_mm, y_mm, 0)
        if not isinstance(step_mm, np.ndarray):  # one step for the whole query: the level is one number
            level = min(max(math.log2(max(float(step_mm), 1e-12) / self.base_pixel_mm), 0.0), self.levels - 1.0)
            low = int(level)
            near = self._bilinear(channel, x_mm, y_mm, low)
            if level == low:
                return near
            far = self._bilinear(channel, x_mm, y_mm, min(low + 1, self.levels - 1))
            far -= near
            far *= np.float32(level - low)
            far += near
            return far
        level = np.log2(np.maximum(np.asarray(step_mm, dtype=float), 1e-12) / self.base_pixel_mm)
        level = np.clip(level, 0.0, self.levels - 1.0)
        low = np.floor(level).astype(np.intp)
        weight = (level - low).astype(np.float32)
        if not level.any():  # every step finer than a pixel: the full-resolution level alone
            return self._bilinear(channel, x_mm, y_mm, 0)
        low = np.broadcast_to(low, np.shape(x_mm))
        weight = np.broadcast_to(weight, np.shape(x_mm))
        result = np.empty(np.shape(x_mm), dtype=np.float32)
        for index in np.flatnonzero(np.bincount(low.reshape(-1))):  # one pass per level present, not per sample
            pick = low == index
            near = self._bilinear(channel, x_mm[pick], y_mm[pick], int(index))
            if not weight[pick].any():
                result[pick] = near
                continue
            far = self._bilinear(channel, x_mm[pick], y_mm[pick], min(int(index) + 1, self.levels - 1))
            result[pick] = near + weight[pick] * (far - near)
        return result

    def _stepped(self, x_mm: np.ndarray, y_mm: np.ndarray, step_mm: np.ndarray) -> np.ndarray:
        """A friction map read along a path with a step per sample (an export's): one compiled pass."""
        out = np.empty(len(x_mm), dtype=np.float32)
        kernels.trilinear_steps(self._flat, self._starts, self._rows, self._cols, *self._per_mm, self.base_pixel_mm,
                                step_mm.astype(np.float64, copy=False), x_mm, y_mm, self.tile, self._fixed,
                                self.texture.width_mm, self.texture.height_mm, self._outside, out)
        return out

    def _levels(self, step_mm) -> tuple[int, int, float]:
        """The two pyramid levels a scalar step reads and the far one's weight (0: the near one alone)."""
        if step_mm is None or self.levels == 1:
            return 0, 0, 0.0
        level = min(max(math.log2(max(float(step_mm), 1e-12) / self.base_pixel_mm), 0.0), self.levels - 1.0)
        low = int(level)
        return low, min(low + 1, self.levels - 1), level - low

    def _block(self, x_mm: np.ndarray, y_mm: np.ndarray, step_mm, direction, out: np.ndarray) -> np.ndarray:
        """One compiled pass over a live block: one step (band limit) and one direction for every sample."""
        near, far, weight = self._levels(step_mm)
        texture = self.texture
        if texture.kind == "friction":
            levels = self.pyramids[0]
            kernels.trilinear(levels[near], levels[far], weight, x_mm, y_mm, self.per_mm_x[near], self.per_mm_y[near],
                              self.per_mm_x[far], self.per_mm_y[far], self.tile, self._fixed, texture.width_mm,
                              texture.height_mm, self._outside, out)
            return out
        dx, dy = (0.0, 0.0) if direction is None else (float(direction[0]), float(direction[1]))
        length = math.hypot(dx, dy)
        ux, uy = (dx / length, dy / length) if length > 0 else (0.0, 0.0)
        middle, gain, low, high = self._gradient
        slope_x, slope_y = self.pyramids
        kernels.gradient_levels(slope_x[near], slope_y[near], slope_x[far], slope_y[far], weight, x_mm, y_mm,
                                self.per_mm_x[near], self.per_mm_y[near], self.per_mm_x[far], self.per_mm_y[far],
                                self.tile, ux, uy, middle, gain, low, high, self._fixed, texture.width_mm,
                                texture.height_mm, self._outside, out)
        return out

    def _one_level(self, step_mm) -> bool:
        """True when the query reads the full-resolution level alone."""
        if step_mm is None or self.levels == 1:
            return True
        return not isinstance(step_mm, np.ndarray) and float(step_mm) <= self.base_pixel_mm

    def _directional(self, x_mm, y_mm, dx: float, dy: float) -> np.ndarray:
        """A gradient texture along one direction of motion, in one compiled pass."""
        length = math.hypot(dx, dy)
        ux, uy = (dx / length, dy / length) if length > 0 else (0.0, 0.0)
        low, high = self.texture.ratio_range
        out = np.empty(len(x_mm), dtype=np.float32)
        kernels.gradient_ratio(self.pyramids[0][0], self.pyramids[1][0], x_mm, y_mm, self.per_mm_x[0],
                               self.per_mm_y[0], self.tile, ux, uy, 0.5 * (low + high),
                               0.5 * (high - low) / self.texture.full_slope_per_mm, low, high, out)
        return out

    def ratio(self, x_mm: ArrayLike, y_mm: ArrayLike, step_mm: ArrayLike | None = None,
              direction: tuple[ArrayLike, ArrayLike] | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """Friction ratio at positions (mm), float32.

        ``step_mm`` (scalar or per sample) is the distance the finger moves between samples; give
        it to band-limit the lookup. ``direction`` is a pair of arrays (dx, dy) of the motion,
        needed by gradient textures (any length; zero means at rest, which reads as flat ground).
        ``out``: a float32 array of the positions' length to write into. A live block's query (1-d
        float64 positions, one step and one direction for the block) then runs in one compiled pass
        and allocates nothing; any other query is computed as without ``out`` and copied there.

        Parameters
        ----------
        x_mm, y_mm : array_like
            Positions (mm from the top-left corner).
        step_mm : array_like, optional
            The distance (mm) moved between samples, one or one a sample.
        direction : (array_like, array_like), optional
            The motion (dx, dy), for a gradient texture.
        out : numpy.ndarray, optional
            A float32 array of the positions' length to write into.

        Returns
        -------
        numpy.ndarray of float32
            Friction ratios.

        Examples
        --------
        >>> import numpy as np
        >>> stripes = Texture(np.tile([0.2, 0.8], (8, 8)), width_mm=16.0, height_mm=8.0)   # 1 mm stripes
        >>> sampler = Sampler(stripes)
        >>> sampler.ratio([0.5, 1.5], [0.5, 0.5]).astype(float).round(3).tolist()     # on each stripe
        [0.2, 0.8]
        >>> round(float(sampler.ratio([0.5], [0.5], step_mm=4.0)[0]), 3)     # 4 mm a sample: their mean
        0.5
        """
        if out is not None:
            if (isinstance(x_mm, np.ndarray) and x_mm.ndim == 1 and x_mm.dtype == np.float64
                    and isinstance(y_mm, np.ndarray) and y_mm.dtype == np.float64
                    and not isinstance(step_mm, np.ndarray)
                    and (direction is None or not isinstance(direction[0], np.ndarray) or direction[0].ndim == 0)):
                return self._block(x_mm, y_mm, step_mm, direction, out)
            out[:] = self.ratio(x_mm, y_mm, step_mm, direction)
            return out
        x_mm = np.asarray(x_mm, dtype=np.float64)
        y_mm = np.asarray(y_mm, dtype=np.float64)
        texture = self.texture
        if (texture.kind == "friction" and isinstance(step_mm, np.ndarray) and x_mm.ndim == 1
                and step_mm.shape == x_mm.shape == y_mm.shape):
            return self._stepped(x_mm, y_mm, step_mm)
        if texture.kind == "friction":
            ratio = self._channel(0, x_mm, y_mm, step_mm)
        elif self._one_level(step_mm) and direction is not None and np.ndim(direction[0]) == 0 and x_mm.ndim == 1:
            ratio = self._directional(x_mm, y_mm, float(direction[0]), float(direction[1]))
        else:
            slope_x = self._channel(0, x_mm, y_mm, step_mm)
            slope_y = self._channel(1, x_mm, y_mm, step_mm)
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
