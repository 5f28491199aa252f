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
    if wrap:
        c0 %= cols
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
