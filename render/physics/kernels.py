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
    """Amplitudes for friction ratios under the stretched exponential law at one force.

    The law: mu/mu0 = d + (1 - d) exp(-(a / scale)^shape) (d: ``residual``); ratios >= 1 → 0, below
    ``floor`` → ``limit``.

    Parameters
    ----------
    ratio : numpy.ndarray of float64 or float32
        The friction ratios wanted.
    floor : float
        The lowest ratio within reach (the ratio at ``limit``).
    limit : float
        The largest amplitude, µm peak-to-peak.
    scale : float
        The law's amplitude scale, µm peak-to-peak.
    inverse_shape : float
        1 / the law's shape (0.5: the Gaussian law).
    residual : float
        The friction ratio left at full levitation, d.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many ratios were below the floor, or -1 - i if ratio i is NaN, negative or infinite (the
        caller raises).

    Examples
    --------
    The Gaussian law (shape 2) with a 2 µm scale: a ratio of exp(-1) needs 2 µm, exp(-4) needs 4 µm, and
    0.005 lies below the floor (the limit, counted):

    >>> import numpy as np
    >>> out = np.empty(4)
    >>> inverse_stretched(np.array([1.0, np.exp(-1), np.exp(-4), 0.005]), 0.01, 6.0, 2.0, 0.5, 0.0, out)
    1
    >>> out.round(9).tolist()
    [0.0, 2.0, 4.0, 6.0]
    >>> inverse_stretched(np.array([0.5, np.nan]), 0.01, 6.0, 2.0, 0.5, 0.0, out)
    -2
    """
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
    """As :func:`inverse_stretched` with a force per sample: the scale grows as scale × (F / reference)^force_exponent.

    A ratio is clamped (and counted) when the amplitude it needs exceeds ``limit`` (or it lies at or below the
    floor ``residual``); a bad ratio or force (NaN, negative, infinite) returns -1 - i.

    Parameters
    ----------
    ratio : numpy.ndarray of float64
        The friction ratios wanted.
    force : numpy.ndarray of float64
        The normal force per sample, N.
    limit : float
        The largest amplitude, µm peak-to-peak.
    scale : float
        The law's amplitude scale at the reference force, µm peak-to-peak.
    inverse_shape : float
        1 / the law's shape.
    force_exponent : float
        How the scale grows with force.
    reference_force, min_force, max_force : float
        The force the scale is given at, and the range forces are clipped to, N.
    residual : float
        The friction ratio left at full levitation.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were clamped, or -1 - i for a bad ratio or force at i.

    Examples
    --------
    A ratio of exp(-1) needs the scale itself: 2 µm at the 0.5 N reference, twice that at four times the
    force (exponent 0.5), and 8 µm (over the 6 µm limit) at 8 N:

    >>> import numpy as np
    >>> out = np.empty(3)
    >>> inverse_stretched_forces(np.full(3, np.exp(-1)), np.array([0.5, 2.0, 8.0]), 6.0, 2.0, 0.5, 0.5, 0.5,
    ...                          0.01, 10.0, 0.0, out)
    1
    >>> out.round(9).tolist()
    [2.0, 4.0, 6.0]
    """
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
    """Amplitudes from a uniform-grid table of the inverse, times ``amplitude_scale``.

    The table holds the amplitude at ratio ``start + i / per_step``, linear between; ratios >= 1 → the
    table's last value, below ``floor`` → ``limit``.

    Parameters
    ----------
    ratio : numpy.ndarray of float64 or float32
        The friction ratios wanted.
    floor : float
        The lowest ratio within reach.
    limit : float
        The largest amplitude, µm peak-to-peak.
    start, per_step : float
        The table's first ratio and its points per unit of ratio.
    values : numpy.ndarray of float64
        The table's amplitudes (before ``amplitude_scale``), µm peak-to-peak.
    slopes : numpy.ndarray of float64
        ``numpy.diff(values)``.
    amplitude_scale : float
        The factor the table's values are multiplied by.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were below the floor, or -1 - i if ratio i is NaN, negative or infinite.

    Examples
    --------
    A table of a = 6 (1 - ratio) µm at ratios 0, 0.25, ... 1:

    >>> import numpy as np
    >>> values = 6.0 * (1.0 - np.linspace(0.0, 1.0, 5))
    >>> out = np.empty(4)
    >>> inverse_uniform(np.array([1.0, 0.5, 0.6, 0.05]), 0.1, 5.0, 0.0, 4.0, values, np.diff(values), 1.0, out)
    1
    >>> out.round(9).tolist()
    [0.0, 3.0, 2.4, 5.0]
    """
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
    """As :func:`inverse_uniform` with a force per sample.

    The table's value is multiplied by scale_at_1n × F^force_exponent, which grows as F instead above
    ``saturation_force`` (the contact area is then a fingertip's). Clamped (and counted) where that exceeds
    ``limit``.

    Parameters
    ----------
    ratio : numpy.ndarray of float64
        The friction ratios wanted.
    force : numpy.ndarray of float64
        The normal force per sample, N.
    limit : float
        The largest amplitude, µm peak-to-peak.
    start, per_step : float
        The table's first ratio and its points per unit of ratio.
    values, slopes : numpy.ndarray of float64
        The table's values (µm peak-to-peak at 1 N before the scale) and ``numpy.diff(values)``.
    scale_at_1n : float
        The factor at 1 N.
    force_exponent : float
        How the factor grows with force below saturation.
    saturation_force, min_force, max_force : float
        Where the growth turns linear, and the range forces are clipped to, N.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were clamped, or -1 - i for a bad ratio or force at i.

    Examples
    --------
    Ratio 0.5 reads 0.5 from a table of 1 - ratio; the factor 2 F^0.5 reaches 4 at the 4 N saturation and
    grows as F beyond (8 at 8 N):

    >>> import numpy as np
    >>> values = 1.0 - np.linspace(0.0, 1.0, 5)
    >>> out = np.empty(3)
    >>> inverse_uniform_forces(np.full(3, 0.5), np.array([1.0, 4.0, 8.0]), 6.0, 0.0, 4.0, values, np.diff(values),
    ...                        2.0, 0.5, 4.0, 0.01, 10.0, out)
    0
    >>> out.tolist()
    [1.0, 2.0, 4.0]
    """
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

    Linear between the neighbouring measured forces, held beyond the ends. A ratio is clamped (and counted)
    where the amplitude reaches ``limit``; a bad ratio or force returns -1 - i.

    Parameters
    ----------
    ratio : numpy.ndarray of float64
        The friction ratios wanted.
    force : numpy.ndarray of float64
        The normal force per sample, N.
    limit : float
        The largest amplitude, µm peak-to-peak.
    start, per_step : float
        The tables' first ratio and their points per unit of ratio.
    values, slopes : numpy.ndarray of float64, shape (forces, points)
        One inverse a row, µm peak-to-peak, and ``numpy.diff(values, axis=1)``.
    force_nodes : numpy.ndarray of float64
        The measured forces of the rows, N, increasing.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were clamped, or -1 - i for a bad ratio or force at i.

    Examples
    --------
    Ratio 0.5 needs 2 µm at 0.2 N and 4 µm at 1 N: 3 µm halfway between, 4 µm held above 1 N:

    >>> import numpy as np
    >>> values = np.outer([4.0, 8.0], 1.0 - np.linspace(0.0, 1.0, 5))
    >>> out = np.empty(4)
    >>> inverse_table_forces(np.array([0.5, 0.5, 0.5, 1.0]), np.array([0.2, 0.6, 2.0, 0.6]), 6.0, 0.0, 4.0,
    ...                      values, np.diff(values, axis=1), np.array([0.2, 1.0]), out)
    0
    >>> out.round(9).tolist()
    [2.0, 3.0, 4.0, 0.0]
    """
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
    """:func:`inverse_table_forces` at one force for the whole block (a panel that does not sense pressure).

    No force array to allocate.

    Parameters
    ----------
    ratio : numpy.ndarray of float64 or float32
        The friction ratios wanted.
    force : float
        The normal force, N.
    limit : float
        The largest amplitude, µm peak-to-peak.
    start, per_step : float
        The tables' first ratio and their points per unit of ratio.
    values, slopes : numpy.ndarray of float64, shape (forces, points)
        One inverse a row, µm peak-to-peak, and ``numpy.diff(values, axis=1)``.
    force_nodes : numpy.ndarray of float64
        The measured forces of the rows, N.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were clamped at ``limit``, or -1 - i if ratio i is bad.

    Examples
    --------
    At 0.2 N a ratio of 0.25 needs 3 µm, over a 2.5 µm limit:

    >>> import numpy as np
    >>> values = np.outer([4.0, 8.0], 1.0 - np.linspace(0.0, 1.0, 5))
    >>> out = np.empty(3)
    >>> inverse_table_force(np.array([0.5, 0.25, 1.0]), 0.2, 2.5, 0.0, 4.0, values, np.diff(values, axis=1),
    ...                     np.array([0.2, 1.0]), out)
    1
    >>> out.tolist()
    [2.0, 2.5, 0.0]
    """
    clamped = 0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])
        if not (0.0 <= r < np.inf):
            return -1 - i
        clamped += _table_sample(r, force, limit, start, per_step, values, slopes, force_nodes, out, i)
    return clamped


# The squeeze-film model's parameters, packed for the kernels (see render.physics.squeeze_film):
FILM_LIFT, FILM_GAP, AREA_K, AREA_EXPONENT, AREA_MAX, DETACH_AT_1N, DETACH_EXPONENT, SATURATION, FRICTION_N, \
    U_MAX, MIN_F, MAX_F, EPS_MAX = range(13)


@njit(cache=True, nogil=True)
def film_forward(a, f, p, ratio_nodes):
    """Friction over friction at rest of the squeeze-film model at amplitude ``a`` and force ``f``.

    The ridges' share of the load to the power n times the paper's R(a / W_c(F_c)), read from its table over
    u (nodes u_max (k / (N - 1))², linear in u between them).

    Parameters
    ----------
    a : float
        The amplitude, µm peak-to-peak.
    f : float
        The normal force, N (clipped to the models' range).
    p : numpy.ndarray of float64
        The model's parameters packed in the order of this module's constants (``FILM_LIFT`` ... ``EPS_MAX``).
    ratio_nodes : numpy.ndarray of float64
        R at the table's nodes.

    Returns
    -------
    float
        The friction ratio.

    Examples
    --------
    Without lift (``FILM_LIFT`` 0) the ratio is the table's: at rest 1, at u = 10 (a = 10 × W_c, W_c 1.6 µm at
    1 N) the third node, past u_max the last. The inverses call it compiled; from Python its source runs as
    ``film_forward.py_func`` (calling the kernel itself from Python would compile an entry of its own):

    >>> import numpy as np
    >>> p = np.array([0.0, 10.0, 138.1, 2 / 3, 250.0, 1.6, 1 / 3, 2.4, 2 / 3, 40.0, 0.01, 10.0, 0.95])
    >>> nodes = np.linspace(1.0, 0.6, 5)
    >>> forward = film_forward.py_func
    >>> [round(float(forward(a, 1.0, p, nodes)), 9) for a in (0.0, 16.0, 80.0)]
    [1.0, 0.8, 0.6]
    """
    f = min(max(f, p[MIN_F]), p[MAX_F])
    share = 1.0
    if p[FILM_LIFT] > 0.0 and a > 0.0:
        eps = min(0.5 * a / p[FILM_GAP], p[EPS_MAX])
        square = eps * eps
        pressure = np.sqrt((1.0 + 1.5 * square) / (1.0 - square)) - 1.0
        area_m2 = min(p[AREA_K] * f ** p[AREA_EXPONENT], p[AREA_MAX]) * 1e-6
        share = 1.0 - p[FILM_LIFT] * area_m2 * pressure / f
        if share <= 0.0:
            return 0.0
    contact = share * f
    detach = p[DETACH_AT_1N] * min(contact, p[SATURATION]) ** p[DETACH_EXPONENT] * max(contact / p[SATURATION], 1.0)
    u = a / detach
    last = ratio_nodes.shape[0] - 1
    if u >= p[U_MAX]:
        rolling = ratio_nodes[last]
    else:
        k = min(int(np.sqrt(u / p[U_MAX]) * last), last - 1)
        low = p[U_MAX] * (k / last) ** 2
        if low > u and k > 0:  # rounding of the square root: step back to the node below
            k -= 1
            low = p[U_MAX] * (k / last) ** 2
        high = p[U_MAX] * ((k + 1) / last) ** 2
        rolling = ratio_nodes[k] + (u - low) / (high - low) * (ratio_nodes[k + 1] - ratio_nodes[k])
    return share ** p[FRICTION_N] * rolling


@njit(cache=True, nogil=True)
def _film_root(r, f, limit, p, ratio_nodes):
    """The smallest amplitude in [0, limit] whose ratio is at most ``r``: regula falsi with the Illinois
    step on the bracket (about ten evaluations), then bisection until it closes to 1e-13 of the limit.
    ``limit`` when even that leaves more friction than ``r``."""
    low, high = 0.0, limit
    g_low, g_high = 1.0 - r, film_forward(limit, f, p, ratio_nodes) - r
    if g_high > 0.0:
        return limit
    side = 0
    tolerance = 1e-13 * limit  # near levitation the ratio may fall from 1 to 0 within nanometres
    for _ in range(60):
        if high - low <= tolerance:
            return high
        if g_low - g_high > 0.0:
            middle = high - g_high * (high - low) / (g_high - g_low)
        else:
            middle = 0.5 * (low + high)
        if not (low < middle < high):
            middle = 0.5 * (low + high)
        g = film_forward(middle, f, p, ratio_nodes) - r
        if g > 0.0:
            low, g_low = middle, g
            if side == -1:
                g_high *= 0.5
            side = -1
        else:
            high, g_high = middle, g
            if side == 1:
                g_low *= 0.5
            side = 1
    while high - low > tolerance:
        middle = 0.5 * (low + high)
        if film_forward(middle, f, p, ratio_nodes) > r:
            low = middle
        else:
            high = middle
    return high


@njit(cache=True, nogil=True)
def inverse_film_forces(ratio, force, limit, p, ratio_nodes, out):
    """Amplitudes of the squeeze-film model, a force per sample, by root-finding on its forward model.

    Ratios >= 1 → 0. A ratio is clamped (and counted) where even ``limit`` leaves more friction; a bad ratio
    or force returns -1 - i.

    Parameters
    ----------
    ratio : numpy.ndarray of float64
        The friction ratios wanted.
    force : numpy.ndarray of float64
        The normal force per sample, N.
    limit : float
        The largest amplitude, µm peak-to-peak.
    p : numpy.ndarray of float64
        The model's packed parameters (see :func:`film_forward`).
    ratio_nodes : numpy.ndarray of float64
        R at the table's nodes.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were clamped, or -1 - i for a bad ratio or force at i.

    Examples
    --------
    The inverse of :func:`film_forward`'s example: 0.8 at 16 µm; 0.5 is out of reach under a 64 µm limit:

    >>> import numpy as np
    >>> p = np.array([0.0, 10.0, 138.1, 2 / 3, 250.0, 1.6, 1 / 3, 2.4, 2 / 3, 40.0, 0.01, 10.0, 0.95])
    >>> out = np.empty(3)
    >>> inverse_film_forces(np.array([1.0, 0.8, 0.5]), np.ones(3), 64.0, p, np.linspace(1.0, 0.6, 5), out)
    1
    >>> out.round(9).tolist()
    [0.0, 16.0, 64.0]
    """
    clamped = 0
    for i in range(ratio.shape[0]):
        r = np.float64(ratio[i])
        f = force[i]
        if not (0.0 <= r < np.inf and 0.0 <= f < np.inf):
            return -1 - i
        if r >= 1.0:
            out[i] = 0.0
        elif film_forward(limit, f, p, ratio_nodes) > r + 1e-12:  # rounding at the floor itself: in reach
            out[i] = limit
            clamped += 1
        else:
            out[i] = _film_root(r, f, limit, p, ratio_nodes)
    return clamped


@njit(cache=True, nogil=True)
def inverse_film_force(ratio, force, floor, limit, p, ratio_nodes, out):
    """:func:`inverse_film_forces` at one force for the whole block.

    Ratios below ``floor`` (the ratio at ``limit``) → ``limit``, counted.

    Parameters
    ----------
    ratio : numpy.ndarray of float64 or float32
        The friction ratios wanted.
    force : float
        The normal force, N.
    floor : float
        The ratio at ``limit``.
    limit : float
        The largest amplitude, µm peak-to-peak.
    p : numpy.ndarray of float64
        The model's packed parameters (see :func:`film_forward`).
    ratio_nodes : numpy.ndarray of float64
        R at the table's nodes.
    out : numpy.ndarray of float64
        Filled with amplitudes, µm peak-to-peak.

    Returns
    -------
    int
        How many were below the floor, or -1 - i if ratio i is bad.

    Examples
    --------
    Without lift, 0.9 is the table's second node, u = 2.5: 2.5 × 1.6 µm:

    >>> import numpy as np
    >>> p = np.array([0.0, 10.0, 138.1, 2 / 3, 250.0, 1.6, 1 / 3, 2.4, 2 / 3, 40.0, 0.01, 10.0, 0.95])
    >>> out = np.empty(3)
    >>> inverse_film_force(np.array([1.0, 0.9, 0.5]), 1.0, 0.6, 64.0, p, np.linspace(1.0, 0.6, 5), out)
    1
    >>> out.round(9).tolist()
    [0.0, 4.0, 64.0]
    """
    clamped = 0
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
            out[i] = _film_root(r, force, limit, p, ratio_nodes)
    return clamped


@njit(cache=True, nogil=True)
def friction_response(static, speed, one_speed, rate_hz, onset_s, recovery_s, reference_speed, speed_exponent,
                      slowest_speed, longest_s, felt, out):
    """The felt friction ratio following the static ratio through asymmetric first-order dynamics.

    Time constant ``onset_s`` where friction falls (static below felt), the recovery's where it rises:
    recovery_s (reference_speed / v)^speed_exponent at the sliding speed v (``one_speed`` >= 0 for all
    samples, else ``speed`` per sample; speeds below ``slowest_speed`` count as it; at most ``longest_s``).
    Each sample holds its static value for one period (exact for a held input): out[i] is the felt ratio at
    the end of sample i.

    Parameters
    ----------
    static : numpy.ndarray of float64 or float32
        The static friction ratio per sample.
    speed : numpy.ndarray of float64
        The sliding speed per sample, mm/s (read when ``one_speed`` < 0).
    one_speed : float
        One sliding speed for every sample, mm/s, or -1.
    rate_hz : float
        The samples' rate, Hz.
    onset_s, recovery_s : float
        The time constants of a fall and of a rise at the reference speed, s.
    reference_speed, speed_exponent, slowest_speed : float
        The recovery's speed law (mm/s, exponent, mm/s).
    longest_s : float
        The longest recovery time constant, s.
    felt : float
        The felt ratio before the block.
    out : numpy.ndarray of float64
        Filled with the felt ratio.

    Returns
    -------
    float
        The felt ratio to carry to the next block.

    Examples
    --------
    A fall from 1 to 0.5 and back at 1 kHz, 1 ms onset and 70 ms recovery at the reference speed, against
    the step responses' closed forms:

    >>> import numpy as np
    >>> out = np.empty(4)
    >>> felt = friction_response(np.array([0.5, 0.5, 1.0, 1.0]), np.zeros(4), 22.0, 1000.0, 0.001, 0.07, 22.0,
    ...                          0.5, 2.0, 1.0, 1.0, out)
    >>> fallen = 0.5 + 0.5 * np.exp(-np.array([1.0, 2.0]))
    >>> risen = 1.0 - (1.0 - fallen[1]) * np.exp(-np.array([1.0, 2.0]) / 70.0)
    >>> bool(np.allclose(out, np.concatenate([fallen, risen]))), felt == float(out[-1])
    (True, True)
    """
    period = 1.0 / rate_hz
    k_onset = 1.0 - np.exp(-period / onset_s)
    k_recovery = 0.0
    if one_speed >= 0.0:
        tau = recovery_s * (reference_speed / max(one_speed, slowest_speed)) ** speed_exponent
        k_recovery = 1.0 - np.exp(-period / min(tau, longest_s))
    for i in range(static.shape[0]):
        x = np.float64(static[i])
        if x < felt:
            felt += k_onset * (x - felt)
        else:
            k = k_recovery
            if one_speed < 0.0:
                tau = recovery_s * (reference_speed / max(speed[i], slowest_speed)) ** speed_exponent
                k = 1.0 - np.exp(-period / min(tau, longest_s))
            felt += k * (x - felt)
        out[i] = felt
    return felt


# Each model loads only its own inverses (from numba's cache, or compiles them once per machine) with the types
# the renderer passes: loading one costs tens of milliseconds, and a command uses one model.
F64, F32 = np.zeros(4), np.zeros(4, dtype=np.float32)  # the texture's ratio comes as float32


@njit(cache=True, nogil=True)
def scale_within(amplitude, scale, reached, limit):  # pragma: no cover - compiled
    """In place: each amplitude (µm p-p) times ``scale``, within ``limit``; one at the inverse's own limit
    (``reached``, clamped there) becomes ``limit`` exactly (the most the plate may give, not 0.1 % less): the speed
    law's inverse (render/physics/speed_law.py).

    Examples
    --------
    >>> amplitude = np.array([1.0, 2.5, 2.997])      # µm p-p, the last clamped at the inverse's own limit
    >>> scale_within(amplitude, 2.0, 2.997, 6.0)
    >>> amplitude.tolist()
    [2.0, 5.0, 6.0]
    """
    for i in range(amplitude.shape[0]):
        value = amplitude[i]
        if value >= reached:
            amplitude[i] = limit
        else:
            amplitude[i] = min(value * scale, limit)


@functools.cache
def warm_up_stretched() -> None:
    """The stretched (and exponential) model's inverses, for one force and one force a sample.

    Loaded from numba's cache (or compiled once a machine) with the types the renderer passes; once a process.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up_stretched()
    >>> len(inverse_stretched.signatures) >= 2
    True
    """
    for ratio in (F64 + 0.5, F32 + 0.5):
        inverse_stretched(ratio, 0.1, 6.0, 3.7, 0.5, 0.0, np.empty(4))
    inverse_stretched_forces(F64 + 0.5, F64 + 0.5, 6.0, 3.7, 0.5, 0.3, 0.5, 0.01, 10.0, 0.0, np.empty(4))


@functools.cache
def warm_up_uniform() -> None:
    """The paper model's table inverses, loaded or compiled with the renderer's types; once a process.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up_uniform()
    >>> len(inverse_uniform.signatures) >= 2
    True
    """
    for ratio in (F64 + 0.5, F32 + 0.5):
        inverse_uniform(ratio, 0.1, 6.0, 0.0, 4.0, np.zeros(5), np.zeros(4), 1.0, np.empty(4))
    inverse_uniform_forces(F64 + 0.5, F64 + 0.5, 6.0, 0.0, 4.0, np.zeros(5), np.zeros(4), 1.0, 0.3, 2.4, 0.01, 10.0,
                           np.empty(4))


@functools.cache
def warm_up_table() -> None:
    """A measured table's inverses, loaded or compiled with the renderer's types; once a process.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up_table()
    >>> len(inverse_table_force.signatures) >= 2
    True
    """
    for ratio in (F64 + 0.5, F32 + 0.5):
        inverse_table_force(ratio, 0.5, 6.0, 0.0, 4.0, np.zeros((2, 5)), np.zeros((2, 4)), np.array([0.2, 1.0]),
                            np.empty(4))
    inverse_table_forces(F64 + 0.5, F64 + 0.5, 6.0, 0.0, 4.0, np.zeros((2, 5)), np.zeros((2, 4)),
                         np.array([0.2, 0.6]), np.empty(4))


@functools.cache
def warm_up_film() -> None:
    """The squeeze-film model's inverses, loaded or compiled with the renderer's types; once a process.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up_film()
    >>> len(inverse_film_force.signatures) >= 2
    True
    """
    film = np.array([4e4, 10.0, 138.1, 2.0 / 3.0, 250.0, 1.6, 1.0 / 3.0, 2.4, 2.0 / 3.0, 40.0, 0.01, 10.0, 0.95])
    nodes = np.linspace(1.0, 0.6, 5)
    for ratio in (F64 + 0.5, F32 + 0.5):
        inverse_film_force(ratio, 0.5, 0.1, 6.0, film, nodes, np.empty(4))
    inverse_film_forces(F64 + 0.5, F64 + 0.5, 6.0, film, nodes, np.empty(4))


@functools.cache
def warm_up_dynamics() -> None:
    """The friction dynamics' response, for one speed and one speed a sample; once a process.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up_dynamics()
    >>> len(friction_response.signatures) >= 2
    True
    """
    for ratio in (F64 + 0.5, F32 + 0.5):
        friction_response(ratio, F64, 22.0, 12000.0, 0.005, 0.07, 22.0, 0.5, 2.0, 1.0, 1.0, np.empty(4))
        friction_response(ratio, F64 + 1.0, -1.0, 12000.0, 0.005, 0.07, 22.0, 0.5, 2.0, 1.0, 1.0, np.empty(4))


def warm_up() -> None:
    """Every model's inverses (the models load their own: :meth:`FrictionModel.warm_up`).

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up()
    >>> all(len(kernel.signatures) >= 2 for kernel in (inverse_stretched, inverse_uniform, inverse_film_force))
    True
    """
    warm_up_dynamics()
    warm_up_stretched()
    warm_up_uniform()
    warm_up_table()
    warm_up_film()
    scale_within(np.zeros(1), 2.0, 1.0, 2.0)
