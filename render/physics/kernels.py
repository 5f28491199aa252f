"""Compiled inverses of the friction models (numba): friction ratio (and force) to amplitude, per sample.

Each fills ``out`` from arrays of any length (8 samples of a live block to millions of an export) and
allocates nothing, so the renderer's real-time path can call them; the models in
:mod:`ultraglide.render.physics.friction_models` are their only callers.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def inverse_stretched(ratio, floor, limit, scale, inverse_shape, residual, out):
    """Amplitudes for ratios under mu/mu0 = d + (1 - d) exp(-(a / scale)^shape) at one force (d:
    ``residual``, below ``floor``): ratios >= 1 → 0, below ``floor`` → ``limit``. Returns how many
    were below the floor, or -1 - i if ratio i is NaN, negative or infinite (the caller raises)."""
    clamped = 0
    reducible = 1.0 - residual
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])  # a float32 ratio (the texture's) is read as float64, as numpy would
        if not (0.0 <= r < np.inf):
            return -1 - i
        if r >= 1.0:
            out[i] = 0.0
        elif r < floor:
            out[i] = limit
            clamped += 1
        else:
            depth = -np.log(r if residual == 0.0 else (r - residual) / reducible)
            root = np.sqrt(depth) if inverse_shape == 0.5 else depth ** inverse_shape  # sqrt: the Gaussian law
            out[i] = min(scale * root, limit)
    return clamped


@njit(cache=True, nogil=True)
def inverse_stretched_forces(ratio, force, limit, scale, inverse_shape, force_exponent, reference_force,
                             min_force, max_force, residual, out):
    """As :func:`inverse_stretched` with a force per sample: scale × (F / reference)^force_exponent.
    A ratio is clamped (and counted) when the amplitude it needs exceeds ``limit`` (or it lies at or
    below the floor ``residual``); a bad ratio or force (NaN, negative, infinite) returns -1 - i."""
    clamped = 0
    reducible = 1.0 - residual
    last_force = -1.0  # the force factor is kept while the force repeats (a panel without force sensing)
    factor = 1.0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])  # a float32 ratio (the texture's) is read as float64, as numpy would
        f = force[i]
        if not (0.0 <= r < np.inf and 0.0 <= f < np.inf):
            return -1 - i
        if r >= 1.0:
            out[i] = 0.0
            continue
        if r <= residual:
            out[i] = limit
            clamped += 1
            continue
        if f != last_force:
            last_force = f
            factor = scale * (min(max(f, min_force), max_force) / reference_force) ** force_exponent
        depth = -np.log(r if residual == 0.0 else (r - residual) / reducible)
        a = factor * (np.sqrt(depth) if inverse_shape == 0.5 else depth ** inverse_shape)
        if a > limit:
            out[i] = limit
            clamped += 1
        else:
            out[i] = a
    return clamped


@njit(cache=True, nogil=True)
def inverse_uniform(ratio, floor, limit, start, per_step, values, slopes, amplitude_scale, out):
    """Amplitudes from a uniform-grid table of the inverse (value at ratio ``start + i / per_step``),
    times ``amplitude_scale``; ratios >= 1 → 0, below ``floor`` → ``limit``. Returns how many were
    below, or -1 - i if ratio i is NaN, negative or infinite."""
    clamped = 0
    last = values.shape[0] - 2
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])  # a float32 ratio (the texture's) is read as float64, as numpy would
        if not (0.0 <= r < np.inf):
            return -1 - i
        if r < floor:
            out[i] = limit
            clamped += 1
            continue
        position = (min(r, 1.0) - start) * per_step
        if position < 0.0:
            position = 0.0
        index = min(int(position), last)
        a = (values[index] + (position - index) * slopes[index]) * amplitude_scale
        out[i] = min(max(a, 0.0), limit)
    return clamped


@njit(cache=True, nogil=True)
def inverse_uniform_forces(ratio, force, limit, start, per_step, values, slopes, scale_at_1n, force_exponent,
                           saturation_force, min_force, max_force, out):
    """As :func:`inverse_uniform` with a force per sample: the table's value times
    scale_at_1n × F^force_exponent, which grows as F instead above ``saturation_force`` (the contact
    area is then a fingertip's). Clamped (and counted) where that exceeds ``limit``."""
    clamped = 0
    last = values.shape[0] - 2
    last_force = -1.0  # the force factor is kept while the force repeats
    factor = 1.0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])  # a float32 ratio (the texture's) is read as float64, as numpy would
        f = force[i]
        if not (0.0 <= r < np.inf and 0.0 <= f < np.inf):
            return -1 - i
        if f != last_force:
            last_force = f
            clipped = min(max(f, min_force), max_force)
            factor = scale_at_1n * min(clipped, saturation_force) ** force_exponent * max(clipped / saturation_force,
                                                                                          1.0)
        position = (min(r, 1.0) - start) * per_step
        if position < 0.0:
            position = 0.0
        index = min(int(position), last)
        a = (values[index] + (position - index) * slopes[index]) * factor
        if a > limit:
            out[i] = limit
            clamped += 1
        else:
            out[i] = max(a, 0.0)
    return clamped


@njit(cache=True, nogil=True)
def _table_point(r, f, start, per_step, values, slopes, force_nodes):
    """One amplitude from the per-force inverse tables (rows of ``values``): linear between the
    neighbouring measured forces, held beyond the ends."""
    last = values.shape[1] - 2
    rows = force_nodes.shape[0]
    f = min(max(f, force_nodes[0]), force_nodes[rows - 1])
    upper = 1
    while upper < rows - 1 and force_nodes[upper] < f:
        upper += 1
    lower = upper - 1 if rows > 1 else 0
    upper = upper if rows > 1 else 0
    weight = 0.0 if rows == 1 else (f - force_nodes[lower]) / (force_nodes[upper] - force_nodes[lower])
    position = (r - start) * per_step
    if position < 0.0:
        position = 0.0
    index = min(int(position), last)
    fraction = position - index
    low = values[lower, index] + fraction * slopes[lower, index]
    high = values[upper, index] + fraction * slopes[upper, index]
    return max((1.0 - weight) * low + weight * high, 0.0)


@njit(cache=True, nogil=True)
def _table_sample(r, f, limit, start, per_step, values, slopes, force_nodes, out, i):
    """Writes one table amplitude (0 at a ratio of 1 or more, at most ``limit``) into ``out[i]``;
    returns 1 where it was clamped at the limit."""
    if r >= 1.0:
        out[i] = 0.0
        return 0
    a = _table_point(r, f, start, per_step, values, slopes, force_nodes)
    if a >= limit:
        out[i] = limit
        return 1
    out[i] = a
    return 0


@njit(cache=True, nogil=True)
def inverse_table_forces(ratio, force, limit, start, per_step, values, slopes, force_nodes, out):
    """Amplitudes from a table with one uniform-grid inverse per measured force, a force per sample.
    A ratio is clamped (and counted) where the amplitude reaches ``limit``; a bad ratio or force
    returns -1 - i."""
    clamped = 0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])  # a float32 ratio (the texture's) is read as float64, as numpy would
        f = force[i]
        if not (0.0 <= r < np.inf and 0.0 <= f < np.inf):
            return -1 - i
        clamped += _table_sample(r, f, limit, start, per_step, values, slopes, force_nodes, out, i)
    return clamped


@njit(cache=True, nogil=True)
def inverse_table_force(ratio, force, limit, start, per_step, values, slopes, force_nodes, out):
    """:func:`inverse_table_forces` at one force for the whole block (a panel that does not sense
    pressure): no force array to allocate."""
    clamped = 0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])
        if not (0.0 <= r < np.inf):
            return -1 - i
        clamped += _table_sample(r, force, limit, start, per_step, values, slopes, force_nodes, out, i)
    return clamped


@njit(cache=True, nogil=True)
def _grid_row(f, log_start, per_log, min_force, max_force, rows):
    """The force row below ``f`` and the weight of the row above, in a table over log-spaced forces."""
    position = (np.log(min(max(f, min_force), max_force)) - log_start) * per_log
    if position < 0.0:
        position = 0.0
    row = min(int(position), rows - 2)
    return row, position - row


@njit(cache=True, nogil=True)
def levitation_scale(f, film):
    """The amplitude (µm p-p) at which a squeeze film carries the whole force ``f`` (N), or 1 without a
    film: the scale the squeeze-film table is stored in. ``film`` holds the area law's coefficient
    (mm²), exponent and cap (mm²), the film's fraction times the ambient pressure (Pa) and its gap (µm).
    Where the film's mean overpressure equals F / A_film, sqrt((1 + 1.5 eps²) / (1 - eps²)) = 1 + q with
    q = F / (fraction p_a A), so eps² = ((1 + q)² - 1) / ((1 + q)² + 1.5)."""
    if film[3] <= 0.0:
        return 1.0
    area_m2 = min(film[0] * f ** film[1], film[2]) * 1e-6
    q = f / (film[3] * area_m2)
    w = (1.0 + q) * (1.0 + q)
    return 2.0 * film[4] * np.sqrt((w - 1.0) / (w + 1.5))


@njit(cache=True, nogil=True)
def _grid_point(r, row, weight, power, per_column, table):
    """Bilinear reading of the table at z = sqrt(1 - r^power) (columns) between force rows ``row`` and
    ``row + 1``."""
    position = np.sqrt(1.0 - r**power) * per_column
    column = min(int(position), table.shape[1] - 2)
    fraction = position - column
    low = table[row, column] + fraction * (table[row, column + 1] - table[row, column])
    high = table[row + 1, column] + fraction * (table[row + 1, column + 1] - table[row + 1, column])
    return low + weight * (high - low)


@njit(cache=True, nogil=True)
def inverse_grid_forces(ratio, force, limit, log_start, per_log, min_force, max_force, power, per_column, table,
                        film, out):
    """Amplitudes from a table over log-spaced forces (rows) and z = sqrt(1 - ratio^power) (columns), stored
    in units of :func:`levitation_scale`, a force per sample; ratios >= 1 → 0. A ratio is clamped (and counted) where its amplitude reaches ``limit``; a bad
    ratio or force returns -1 - i."""
    clamped = 0
    rows = table.shape[0]
    last_force = -1.0
    row = 0
    weight = 0.0
    scale = 1.0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])
        f = force[i]
        if not (0.0 <= r < np.inf and 0.0 <= f < np.inf):
            return -1 - i
        if r >= 1.0:
            out[i] = 0.0
            continue
        if f != last_force:
            last_force = f
            row, weight = _grid_row(f, log_start, per_log, min_force, max_force, rows)
            scale = levitation_scale(min(max(f, min_force), max_force), film)
        a = _grid_point(r, row, weight, power, per_column, table) * scale
        if a >= limit:
            out[i] = limit
            clamped += 1
        else:
            out[i] = max(a, 0.0)
    return clamped


@njit(cache=True, nogil=True)
def inverse_grid_force(ratio, force, floor, limit, log_start, per_log, min_force, max_force, power, per_column,
                       table, film, out):
    """:func:`inverse_grid_forces` at one force for the whole block: ratios below ``floor`` → ``limit``
    (counted), as the other single-force inverses do."""
    clamped = 0
    row, weight = _grid_row(force, log_start, per_log, min_force, max_force, table.shape[0])
    scale = levitation_scale(min(max(force, min_force), max_force), film)
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])
        if not (0.0 <= r < np.inf):
            return -1 - i
        if r >= 1.0:
            out[i] = 0.0
        elif r < floor:
            out[i] = limit
            clamped += 1
        else:
            out[i] = min(max(_grid_point(r, row, weight, power, per_column, table) * scale, 0.0), limit)
    return clamped


@functools.cache
def warm_up() -> None:
    """Compile (or load from numba's cache) every inverse with the types the renderer passes."""
    f64 = np.zeros(4)
    f32 = np.zeros(4, dtype=np.float32)  # the texture's ratio comes as float32
    inverse_stretched(f64 + 0.5, 0.1, 6.0, 3.7, 0.5, 0.0, np.empty(4))
    inverse_stretched(f32 + 0.5, 0.1, 6.0, 3.7, 0.5, 0.0, np.empty(4))
    inverse_uniform(f32 + 0.5, 0.1, 6.0, 0.0, 4.0, np.zeros(5), np.zeros(4), 1.0, np.empty(4))
    inverse_stretched_forces(f64 + 0.5, f64 + 0.5, 6.0, 3.7, 0.5, 0.3, 0.5, 0.01, 10.0, 0.0, np.empty(4))
    inverse_uniform(f64 + 0.5, 0.1, 6.0, 0.0, 4.0, np.zeros(5), np.zeros(4), 1.0, np.empty(4))
    inverse_uniform_forces(f64 + 0.5, f64 + 0.5, 6.0, 0.0, 4.0, np.zeros(5), np.zeros(4), 1.0, 0.3, 2.4, 0.01, 10.0,
                           np.empty(4))
    for ratio in (f64 + 0.5, f32 + 0.5):
        inverse_table_force(ratio, 0.5, 6.0, 0.0, 4.0, np.zeros((2, 5)), np.zeros((2, 4)), np.array([0.2, 1.0]),
                            np.empty(4))
    inverse_table_forces(f64 + 0.5, f64 + 0.5, 6.0, 0.0, 4.0, np.zeros((2, 5)), np.zeros((2, 4)),
                         np.array([0.2, 0.6]), np.empty(4))
    grid = np.zeros((3, 5))
    film = np.array([138.1, 2.0 / 3.0, 250.0, 4e4, 10.0])
    for ratio in (f64 + 0.5, f32 + 0.5):
        inverse_grid_force(ratio, 0.5, 0.1, 6.0, -4.6, 8.7, 0.01, 10.0, 0.5, 4.0, grid, film, np.empty(4))
    inverse_grid_forces(f64 + 0.5, f64 + 0.5, 6.0, -4.6, 8.7, 0.01, 10.0, 0.5, 4.0, grid, film, np.empty(4))
