"""Compiled bilinear lookup (numba), for the real-time path's small blocks and for exports alike.

It computes exactly what scipy's ``ndimage.map_coordinates(order=1, prefilter=False)`` does with
``mode="grid-wrap"`` (tiling) or ``mode="nearest"`` (clamping), which the tests pin; scipy's Python
wrapper costs about 5 µs a call, a tenth of a live block's budget, where this costs a quarter of one.

Compiled code is cached on disk beside this file (numba ``cache=True``); a cache made when this module
had another name (``textures.kernels``, before the ``ultraglide`` namespace) is stale, and editing this
file is what makes numba rebuild it.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _corners(u, v, rows, cols, wrap):
    """The four pixels around (u, v) in pixel units (centres at integers) and the fractions."""
    c0 = math.floor(u)
    r0 = math.floor(v)
    fu = u - c0
    fv = v - r0
    c0 = int(c0)
    r0 = int(r0)
    if wrap:  # the modulo (an integer division) only off the image: most samples lie on it
        if c0 < 0 or c0 >= cols:
            c0 %= cols
        if r0 < 0 or r0 >= rows:
            r0 %= rows
        c1 = c0 + 1 if c0 + 1 < cols else 0
        r1 = r0 + 1 if r0 + 1 < rows else 0
    else:
        c1 = min(max(c0 + 1, 0), cols - 1)
        r1 = min(max(r0 + 1, 0), rows - 1)
        c0 = min(max(c0, 0), cols - 1)
        r0 = min(max(r0, 0), rows - 1)
    return r0, r1, c0, c1, fu, fv


@njit(cache=True, nogil=True)
def bilinear(image, x_mm, y_mm, per_mm_x, per_mm_y, wrap, out):
    """Bilinear interpolation of ``image`` (rows × cols, pixel centres at half-pixels) at mm positions.

    Parameters
    ----------
    image : numpy.ndarray of float32, shape (rows, cols)
        The map, read-only (a pyramid level), any unit (friction ratios in a texture).
    x_mm, y_mm : numpy.ndarray of float64
        The positions, mm from the map's top-left corner.
    per_mm_x, per_mm_y : float
        Pixels a mm along each axis.
    wrap : bool
        Tile the map (True) or clamp to its edge pixels (False).
    out : numpy.ndarray of float32
        Filled with the values, ``image``'s unit.

    Returns
    -------
    None

    Examples
    --------
    A 2 × 2 map at 1 pixel a mm: its centres at 0.5 and 1.5 mm, the four pixels' mean between them; at
    x = 0 a tiled map reads halfway to the far column, a clamped one the near column:

    >>> import numpy as np
    >>> image = np.array([[0.0, 1.0], [2.0, 3.0]], dtype=np.float32)
    >>> image.setflags(write=False)
    >>> out = np.empty(3, dtype=np.float32)
    >>> bilinear(image, np.array([0.5, 1.0, 0.0]), np.array([0.5, 1.0, 0.5]), 1.0, 1.0, True, out)
    >>> out.tolist()
    [0.0, 1.5, 0.5]
    >>> bilinear(image, np.array([0.5, 1.0, 0.0]), np.array([0.5, 1.0, 0.5]), 1.0, 1.0, False, out)
    >>> out.tolist()
    [0.0, 1.5, 0.0]
    """
    rows, cols = image.shape
    for i in range(x_mm.shape[0]):
        r0, r1, c0, c1, fu, fv = _corners(x_mm[i] * per_mm_x - 0.5, y_mm[i] * per_mm_y - 0.5, rows, cols, wrap)
        top = image[r0, c0] + fu * (image[r0, c1] - image[r0, c0])
        bottom = image[r1, c0] + fu * (image[r1, c1] - image[r1, c0])
        out[i] = top + fv * (bottom - top)


@njit(cache=True, nogil=True)
def gradient_ratio(slope_x, slope_y, x_mm, y_mm, per_mm_x, per_mm_y, wrap, ux, uy, middle, gain, low, high, out):
    """Friction on a height map along one direction of motion: clip(middle + gain × slope along the motion, low, high).

    The slopes are read bilinearly as :func:`bilinear` reads a map.

    Parameters
    ----------
    slope_x, slope_y : numpy.ndarray of float32, shape (rows, cols)
        The height map's slopes along x and y (height per mm), read-only.
    x_mm, y_mm : numpy.ndarray of float64
        The positions, mm.
    per_mm_x, per_mm_y : float
        Pixels a mm along each axis.
    wrap : bool
        Tile the map (True) or clamp to its edges (False).
    ux, uy : float
        The direction of motion, a unit vector (or zero: no motion).
    middle : float
        The friction ratio on flat ground.
    gain : float
        Friction ratio per unit of slope along the motion.
    low, high : float
        The friction ratios the result is clipped to.
    out : numpy.ndarray of float32
        Filled with friction ratios.

    Returns
    -------
    None

    Examples
    --------
    A ramp rising 0.1 a mm along x: moving up it raises friction, moving down lowers it:

    >>> import numpy as np
    >>> slope_x = np.full((2, 2), 0.1, dtype=np.float32)
    >>> slope_y = np.zeros((2, 2), dtype=np.float32)
    >>> slope_x.setflags(write=False); slope_y.setflags(write=False)
    >>> out = np.empty(1, dtype=np.float32)
    >>> where = np.array([1.0])
    >>> gradient_ratio(slope_x, slope_y, where, where, 1.0, 1.0, True, 1.0, 0.0, 0.5, 1.0, 0.0, 1.0, out)
    >>> round(float(out[0]), 4)
    0.6
    >>> gradient_ratio(slope_x, slope_y, where, where, 1.0, 1.0, True, -1.0, 0.0, 0.5, 1.0, 0.0, 1.0, out)
    >>> round(float(out[0]), 4)
    0.4
    """
    rows, cols = slope_x.shape
    for i in range(x_mm.shape[0]):
        r0, r1, c0, c1, fu, fv = _corners(x_mm[i] * per_mm_x - 0.5, y_mm[i] * per_mm_y - 0.5, rows, cols, wrap)
        w00 = (1.0 - fu) * (1.0 - fv)
        w01 = fu * (1.0 - fv)
        w10 = (1.0 - fu) * fv
        w11 = fu * fv
        sx = w00 * slope_x[r0, c0] + w01 * slope_x[r0, c1] + w10 * slope_x[r1, c0] + w11 * slope_x[r1, c1]
        sy = w00 * slope_y[r0, c0] + w01 * slope_y[r0, c1] + w10 * slope_y[r1, c0] + w11 * slope_y[r1, c1]
        out[i] = min(max(middle + gain * (sx * ux + sy * uy), low), high)


@njit(cache=True, nogil=True, inline="always")
def _level(image, u, v, wrap):
    """Bilinear value of one pyramid level at (u, v) in its pixel units (float64)."""
    rows, cols = image.shape
    r0, r1, c0, c1, fu, fv = _corners(u, v, rows, cols, wrap)
    top = image[r0, c0] + fu * (image[r0, c1] - image[r0, c0])
    bottom = image[r1, c0] + fu * (image[r1, c1] - image[r1, c0])
    return top + fv * (bottom - top)


@njit(cache=True, nogil=True)
def trilinear(near, far, weight, x_mm, y_mm, near_per_mm_x, near_per_mm_y, far_per_mm_x, far_per_mm_y, wrap,
              fixed, width_mm, height_mm, outside, out):
    """Friction at mm positions read from two pyramid levels and blended, near + weight (far − near).

    Weight 0 reads ``near`` alone. The blend is in float32 steps exactly as the sampler's numpy path; where
    ``fixed``, positions beyond [0, width) × [0, height) read ``outside``. One pass, no temporaries.

    Parameters
    ----------
    near, far : numpy.ndarray of float32, shape (rows, cols)
        The two pyramid levels, read-only, friction ratios.
    weight : float
        How far towards ``far``, 0 to 1.
    x_mm, y_mm : numpy.ndarray of float64
        The positions, mm.
    near_per_mm_x, near_per_mm_y, far_per_mm_x, far_per_mm_y : float
        Each level's pixels a mm along each axis.
    wrap : bool
        Tile the levels (True) or clamp to their edges (False).
    fixed : bool
        A texture of fixed size: positions off it read ``outside``.
    width_mm, height_mm : float
        The texture's size, mm.
    outside : numpy.float32
        The friction ratio off a fixed texture.
    out : numpy.ndarray of float32
        Filled with friction ratios.

    Returns
    -------
    None

    Examples
    --------
    Halfway between a 2 × 2 level (1.5 at the centre of its four pixels) and a 1 × 1 level (10), and a
    position off a 2 mm × 2 mm texture:

    >>> import numpy as np
    >>> near = np.array([[0.0, 1.0], [2.0, 3.0]], dtype=np.float32)
    >>> far = np.array([[10.0]], dtype=np.float32)
    >>> near.setflags(write=False); far.setflags(write=False)
    >>> out = np.empty(2, dtype=np.float32)
    >>> where = np.array([1.0, 3.0])
    >>> trilinear(near, far, 0.5, where, where, 1.0, 1.0, 0.5, 0.5, True, True, 2.0, 2.0, np.float32(1.0), out)
    >>> out.tolist()
    [5.75, 1.0]
    """
    w32 = np.float32(weight)
    for i in range(x_mm.shape[0]):
        x = x_mm[i]
        y = y_mm[i]
        if fixed and (x < 0.0 or x >= width_mm or y < 0.0 or y >= height_mm):
            out[i] = outside
            continue
        value = np.float32(_level(near, x * near_per_mm_x - 0.5, y * near_per_mm_y - 0.5, wrap))
        if weight > 0.0:
            beyond = np.float32(_level(far, x * far_per_mm_x - 0.5, y * far_per_mm_y - 0.5, wrap))
            value = np.float32(np.float32(np.float32(beyond - value) * w32) + value)
        out[i] = value


@njit(cache=True, nogil=True)
def gradient_levels(near_x, near_y, far_x, far_y, weight, x_mm, y_mm, near_per_mm_x, near_per_mm_y, far_per_mm_x,
                    far_per_mm_y, wrap, ux, uy, middle, gain, low, high, fixed, width_mm, height_mm, outside, out):
    """Friction on a height map along one direction of motion, its slopes read from two pyramid levels.

    The slopes are blended as :func:`trilinear` blends values: clip(middle + gain × slope along the motion,
    low, high); ``outside`` beyond the edges where ``fixed``.

    Parameters
    ----------
    near_x, near_y, far_x, far_y : numpy.ndarray of float32, shape (rows, cols)
        The slopes along x and y of the two pyramid levels (height per mm), read-only.
    weight : float
        How far towards the far level, 0 to 1.
    x_mm, y_mm : numpy.ndarray of float64
        The positions, mm.
    near_per_mm_x, near_per_mm_y, far_per_mm_x, far_per_mm_y : float
        Each level's pixels a mm along each axis.
    wrap : bool
        Tile the levels (True) or clamp to their edges (False).
    ux, uy : float
        The direction of motion, a unit vector (or zero).
    middle, gain, low, high : float
        The friction ratio on flat ground, friction ratio per unit of slope, and the clip.
    fixed : bool
        A texture of fixed size: positions off it read ``outside``.
    width_mm, height_mm : float
        The texture's size, mm.
    outside : numpy.float32
        The friction ratio off a fixed texture.
    out : numpy.ndarray of float32
        Filled with friction ratios.

    Returns
    -------
    None

    Examples
    --------
    A slope of 0.1 (near) and 0.3 (far) along x, blended halfway: 0.2, moving along +x:

    >>> import numpy as np
    >>> near_x = np.full((2, 2), 0.1, dtype=np.float32); far_x = np.full((2, 2), 0.3, dtype=np.float32)
    >>> flat = np.zeros((2, 2), dtype=np.float32)
    >>> for level in (near_x, far_x, flat):
    ...     level.setflags(write=False)
    >>> out = np.empty(2, dtype=np.float32)
    >>> where = np.array([1.0, 3.0])
    >>> gradient_levels(near_x, flat, far_x, flat, 0.5, where, where, 1.0, 1.0, 1.0, 1.0, True, 1.0, 0.0,
    ...                 0.5, 1.0, 0.0, 1.0, True, 2.0, 2.0, np.float32(1.0), out)
    >>> out.round(4).astype(float).round(4).tolist()
    [0.7, 1.0]
    """
    for i in range(x_mm.shape[0]):
        x = x_mm[i]
        y = y_mm[i]
        if fixed and (x < 0.0 or x >= width_mm or y < 0.0 or y >= height_mm):
            out[i] = outside
            continue
        u, v = x * near_per_mm_x - 0.5, y * near_per_mm_y - 0.5
        sx = _level(near_x, u, v, wrap)
        sy = _level(near_y, u, v, wrap)
        if weight > 0.0:
            u, v = x * far_per_mm_x - 0.5, y * far_per_mm_y - 0.5
            sx += weight * (_level(far_x, u, v, wrap) - sx)
            sy += weight * (_level(far_y, u, v, wrap) - sy)
        out[i] = min(max(middle + gain * (sx * ux + sy * uy), low), high)


@njit(cache=True, nogil=True, inline="always")
def _flat_level(flat, start, rows, cols, u, v, wrap):
    """Bilinear value at (u, v) (pixel units) of the level stored row-major in ``flat`` from ``start``."""
    r0, r1, c0, c1, fu, fv = _corners(u, v, rows, cols, wrap)
    top = flat[start + r0 * cols + c0] + fu * (flat[start + r0 * cols + c1] - flat[start + r0 * cols + c0])
    bottom = flat[start + r1 * cols + c0] + fu * (flat[start + r1 * cols + c1] - flat[start + r1 * cols + c0])
    return top + fv * (bottom - top)


@njit(cache=True, nogil=True)
def trilinear_steps(flat, starts, rows, cols, per_mm_x, per_mm_y, base_pixel_mm, step_mm, x_mm, y_mm, wrap,
                    fixed, width_mm, height_mm, outside, out):
    """:func:`trilinear` with a step (mm, the band limit) per sample.

    Each sample reads the two pyramid levels its step falls between, level = log2(step / base pixel) clipped
    to the pyramid, and blends them in float32 as the sampler's numpy path does. The levels lie one after
    another in ``flat`` (level k from ``starts[k]``, ``rows[k]`` × ``cols[k]``, ``per_mm_x[k]``,
    ``per_mm_y[k]`` pixels a mm).

    Parameters
    ----------
    flat : numpy.ndarray of float32
        Every level row-major, one after another, read-only; friction ratios.
    starts, rows, cols : numpy.ndarray of intp
        Each level's first index in ``flat`` and its size in pixels.
    per_mm_x, per_mm_y : numpy.ndarray of float64
        Each level's pixels a mm.
    base_pixel_mm : float
        The full-resolution level's pixel, mm.
    step_mm : numpy.ndarray of float64
        The finger's step per sample, mm.
    x_mm, y_mm : numpy.ndarray of float64
        The positions, mm.
    wrap, fixed : bool
        Tile the levels; read ``outside`` off a fixed texture.
    width_mm, height_mm : float
        The texture's size, mm.
    outside : numpy.float32
        The friction ratio off a fixed texture.
    out : numpy.ndarray of float32
        Filled with friction ratios.

    Returns
    -------
    None

    Examples
    --------
    Two levels, 2 × 2 (1.5 at the middle) and 1 × 1 (10), a 1 mm base pixel: a 0.5 mm step reads the
    first, a 2 mm step the second, a √2 mm step halfway between (log2 √2 = 0.5):

    >>> import numpy as np
    >>> flat = np.array([0.0, 1.0, 2.0, 3.0, 10.0], dtype=np.float32)
    >>> flat.setflags(write=False)
    >>> starts, rows = np.array([0, 4], dtype=np.intp), np.array([2, 1], dtype=np.intp)
    >>> per_mm = np.array([1.0, 0.5])
    >>> steps, where = np.array([0.5, 2.0, np.sqrt(2.0)]), np.ones(3)
    >>> out = np.empty(3, dtype=np.float32)
    >>> trilinear_steps(flat, starts, rows, rows, per_mm, per_mm, 1.0, steps, where, where, True, False, 2.0,
    ...                 2.0, np.float32(1.0), out)
    >>> out.tolist()
    [1.5, 10.0, 5.75]
    """
    top = starts.shape[0] - 1
    for i in range(x_mm.shape[0]):
        x = x_mm[i]
        y = y_mm[i]
        if fixed and (x < 0.0 or x >= width_mm or y < 0.0 or y >= height_mm):
            out[i] = outside
            continue
        scaled = max(step_mm[i], 1e-12) / base_pixel_mm
        if scaled <= 1.0:  # a step within a pixel (log2 <= 0): the full-resolution level alone, without the log
            out[i] = np.float32(_flat_level(flat, starts[0], rows[0], cols[0], x * per_mm_x[0] - 0.5,
                                            y * per_mm_y[0] - 0.5, wrap))
            continue
        level = min(max(math.log2(scaled), 0.0), float(top))
        near = int(math.floor(level))
        weight = np.float32(level - near)
        value = np.float32(_flat_level(flat, starts[near], rows[near], cols[near], x * per_mm_x[near] - 0.5,
                                       y * per_mm_y[near] - 0.5, wrap))
        if weight > 0.0:
            far = min(near + 1, top)
            beyond = np.float32(_flat_level(flat, starts[far], rows[far], cols[far], x * per_mm_x[far] - 0.5,
                                            y * per_mm_y[far] - 0.5, wrap))
            value = np.float32(np.float32(np.float32(beyond - value) * weight) + value)
        out[i] = value


@functools.cache
def warm_up() -> None:
    """Compile (or load from numba's cache) the lookups with the types a Sampler passes.

    So the first real-time block never waits for the compiler; called when a sampler is built (once a
    process: cached).

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up()
    >>> len(bilinear.signatures) >= 1
    True
    """
    image = np.zeros((2, 2), dtype=np.float32)
    image.setflags(write=False)  # pyramid levels are read-only
    where = np.zeros(1)
    for wrap in (True, False):
        bilinear(image, where, where, 1.0, 1.0, wrap, np.empty(1, dtype=np.float32))
        gradient_ratio(image, image, where, where, 1.0, 1.0, wrap, 1.0, 0.0, 0.5, 0.1, 0.0, 1.0,
                       np.empty(1, dtype=np.float32))
        for fixed in (True, False):
            trilinear(image, image, 0.5, where, where, 1.0, 1.0, 1.0, 1.0, wrap, fixed, 1.0, 1.0,
                      np.float32(1.0), np.empty(1, dtype=np.float32))
            gradient_levels(image, image, image, image, 0.5, where, where, 1.0, 1.0, 1.0, 1.0, wrap, 1.0, 0.0,
                            0.5, 0.1, 0.0, 1.0, fixed, 1.0, 1.0, np.float32(1.0), np.empty(1, dtype=np.float32))
            trilinear_steps(image.reshape(-1), np.zeros(1, dtype=np.intp), np.full(1, 2, dtype=np.intp),
                            np.full(1, 2, dtype=np.intp), where + 1.0, where + 1.0, 1.0, where, where, where, wrap,
                            fixed, 1.0, 1.0, np.float32(1.0), np.empty(1, dtype=np.float32))
