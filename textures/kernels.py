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
    """Bilinear interpolation of ``image`` (rows × cols, pixel centres at half-pixels) at mm positions."""
    rows, cols = image.shape
    for i in range(x_mm.shape[0]):
        r0, r1, c0, c1, fu, fv = _corners(x_mm[i] * per_mm_x - 0.5, y_mm[i] * per_mm_y - 0.5, rows, cols, wrap)
        top = image[r0, c0] + fu * (image[r0, c1] - image[r0, c0])
        bottom = image[r1, c0] + fu * (image[r1, c1] - image[r1, c0])
        out[i] = top + fv * (bottom - top)


@njit(cache=True, nogil=True)
def gradient_ratio(slope_x, slope_y, x_mm, y_mm, per_mm_x, per_mm_y, wrap, ux, uy, middle, gain, low, high, out):
    """Friction on a height map along one direction of motion (ux, uy: a unit vector, or zero):
    ratio = clip(middle + gain * slope along the motion, low, high), the slope read bilinearly."""
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
    """Friction at mm positions read from two pyramid levels and blended, near + weight (far − near)
    (weight 0: ``near`` alone), in float32 steps exactly as the sampler's numpy path; where ``fixed``,
    positions beyond [0, width) × [0, height) read ``outside``. One pass, no temporaries."""
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
    """Friction on a height map along one direction of motion (ux, uy: a unit vector, or zero), its slopes
    read from two pyramid levels and blended as :func:`trilinear` does: clip(middle + gain × slope along
    the motion, low, high); ``outside`` beyond the edges where ``fixed``."""
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
    """:func:`trilinear` with a step (mm, the band limit) per sample: each sample reads the two pyramid
    levels its step falls between, level = log2(step / base pixel) clipped to the pyramid, and blends
    them in float32 as the sampler's numpy path does. The levels lie one after another in ``flat``
    (level k from ``starts[k]``, ``rows[k]`` × ``cols[k]``, ``per_mm_x[k]``, ``per_mm_y[k]`` pixels a mm)."""
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
    """Compile (or load from numba's cache) the lookups with the types a Sampler passes, so the first
    real-time block never waits for the compiler. Called when a sampler is built."""
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
