"""Compiled inner loops of the signal path (numba): the envelope recursion and a synthetic path's positions.

The envelope stages are recursions (each sample depends on the previous one, with clipping), which
numpy cannot vectorise exactly; compiled, one exact loop is both the simplest code and the fastest
at every block size, from 8 samples (a live block) to millions (an export). Functions here take
and fill numpy arrays and return the state to carry to the next block; they allocate nothing.
The model inverses' loops are the physics' (:mod:`ultraglide.render.physics.kernels`).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def envelope(target, gate_open, open_all, gain, goal, up_step, down_step, k, smoothed, limit,
             precompensate, alpha, drive_max, plate, amplitude_out, drive_out, plate_out):
    """Gate → one-pole smoother → limit → pre-compensation (or plain drive), sample by sample.

    The plate model is a[n] = alpha a[n-1] + (1 - alpha) d[n]; pre-compensation drives
    d[n] = (y[n] - alpha a[n-1]) / (1 - alpha) clipped to [0, drive_max], so the modelled plate
    never exceeds the smoothed target (on a rise) or its previous value (on a fall): never the limit.

    Parameters
    ----------
    target : numpy.ndarray of float64
        The amplitude wanted, µm peak-to-peak, one a control sample.
    gate_open : numpy.ndarray of uint8
        1 where the finger touches, per sample; read only when ``open_all`` is -1.
    open_all : int
        1 or 0: the gate is the same for every sample; -1: read ``gate_open``.
    gain, goal : float
        The gate's gain (0 to 1) and where it is heading, before the first sample.
    up_step, down_step : float
        The gate's rise and fall per sample.
    k : float
        The smoother's coefficient per sample (1: no smoothing).
    smoothed : float
        The smoother's state before the first sample, µm peak-to-peak.
    limit : float
        The amplitude the plate may not exceed, µm peak-to-peak.
    precompensate : bool
        Drive the plate model onto the smoothed target (True) or drive the target itself.
    alpha : float
        The plate model's pole per sample, 0 <= alpha < 1.
    drive_max : float
        The largest drive, µm peak-to-peak.
    plate : float
        The plate model before the first sample, µm peak-to-peak.
    amplitude_out, drive_out, plate_out : numpy.ndarray of float64
        Filled with the limited target, the drive and the modelled plate, µm peak-to-peak.

    Returns
    -------
    tuple
        (gain, goal, smoothed, plate, ramps started, drive samples clipped), the state to carry to the next
        block and two counts.

    Examples
    --------
    A step from 4 µm to 10 µm under a 6 µm limit, the plate model halfway to its drive each sample
    (alpha 0.5): pre-compensation drives 8 µm to reach 4 µm at once, and the plate never passes 6 µm:

    >>> import numpy as np
    >>> amplitude, drive, plate = np.empty(4), np.empty(4), np.empty(4)
    >>> envelope(np.array([4.0, 4.0, 10.0, 10.0]), np.zeros(0, dtype=np.uint8), 1, 1.0, 1.0, 0.1, 0.1, 1.0,
    ...          0.0, 6.0, True, 0.5, 8.0, 0.0, amplitude, drive, plate)
    (1.0, 1.0, 10.0, 6.0, 0, 0)
    >>> amplitude.tolist(), drive.tolist(), plate.tolist()
    ([4.0, 4.0, 6.0, 6.0], [8.0, 4.0, 8.0, 6.0], [4.0, 4.0, 6.0, 6.0])
    """
    ramps = 0
    clipped = 0
    inverse_gain = 1.0 / (1.0 - alpha)
    for i in range(target.shape[0]):
        wanted = float(open_all) if open_all >= 0 else float(gate_open[i])
        if wanted != goal:
            goal = wanted
            ramps += 1
        if gain < goal:
            gain = min(gain + up_step, goal)
        elif gain > goal:
            gain = max(gain - down_step, goal)
        smoothed += k * (target[i] * gain - smoothed)
        y = min(max(smoothed, 0.0), limit)
        amplitude_out[i] = y
        if precompensate:
            d = (y - alpha * plate) * inverse_gain
            if d < 0.0:
                d = 0.0
                clipped += 1
            elif d > drive_max:
                d = drive_max
                clipped += 1
        else:
            d = y
        plate = alpha * plate + (1.0 - alpha) * d
        drive_out[i] = d
        plate_out[i] = plate
    return gain, goal, smoothed, plate, ramps, clipped


@njit(cache=True, nogil=True)
def swipe_path(kind, times, duration_s, speed_mm_s, x0, y0, cos_h, sin_h, radius_mm, width_mm, pitch_mm,
               x_out, y_out, down_out):
    """Positions along a constant-speed path at ``times`` (held at the ends), and whether the finger touches.

    Kind 0 straight, 1 circle (from its left, counter-clockwise on screen), 2 zig-zag (back and forth over
    ``width_mm``, stepping ``pitch_mm`` sideways at each end). One pass.

    Parameters
    ----------
    kind : int
        0 straight, 1 circle, 2 zig-zag.
    times : numpy.ndarray of float64
        The times, s from the swipe's start.
    duration_s : float
        The swipe's length in time, s.
    speed_mm_s : float
        The finger's speed, mm/s.
    x0, y0 : float
        Where the swipe starts, mm.
    cos_h, sin_h : float
        The cosine and sine of the heading (straight and zig-zag).
    radius_mm, width_mm, pitch_mm : float
        The circle's radius; the zig-zag's width and its step sideways, mm.
    x_out, y_out : numpy.ndarray of float64
        Filled with the positions, mm.
    down_out : numpy.ndarray of bool
        Filled with whether the finger touches (0 <= time <= ``duration_s``).

    Returns
    -------
    None

    Examples
    --------
    At 10 mm/s for 1 s to the right, then a zig-zag 4 mm wide stepping 1 mm at each end:

    >>> import numpy as np
    >>> x, y, down = np.empty(4), np.empty(4), np.empty(4, dtype=np.bool_)
    >>> swipe_path(0, np.array([0.0, 0.5, 1.0, 2.0]), 1.0, 10.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, x, y, down)
    >>> x.tolist(), y.tolist(), down.tolist()
    ([0.0, 5.0, 10.0, 10.0], [0.0, 0.0, 0.0, 0.0], [True, True, True, False])
    >>> swipe_path(2, np.array([0.0, 0.2, 0.6, 1.0]), 1.0, 10.0, 0.0, 0.0, 1.0, 0.0, 1.0, 4.0, 1.0, x, y, down)
    >>> x.tolist(), y.tolist()
    ([0.0, 2.0, 2.0, 2.0], [0.0, 0.0, 1.0, 2.0])
    """
    for i in range(times.shape[0]):
        t = times[i]
        down_out[i] = 0.0 <= t <= duration_s
        distance = speed_mm_s * min(max(t, 0.0), duration_s)
        if kind == 1:
            angle = distance / radius_mm
            x_out[i] = x0 + radius_mm * (1.0 - math.cos(angle))
            y_out[i] = y0 - radius_mm * math.sin(angle)
            continue
        along = distance
        across = 0.0
        if kind == 2:
            cycle = 2.0 * width_mm
            phase = distance % cycle
            along = phase if phase < width_mm else cycle - phase
            across = math.floor(distance / width_mm) * pitch_mm
        x_out[i] = x0 + along * cos_h - across * sin_h
        y_out[i] = y0 + along * sin_h + across * cos_h


@njit(cache=True, nogil=True)
def _pchip_slope(t, v, k, last):
    """PCHIP's derivative at record ``k`` of records 0..``last`` (Fritsch–Carlson's weighted harmonic mean
    inside, the shape-preserving three-point formula at the ends), as scipy's PchipInterpolator has it."""
    if last == 1:
        return (v[1] - v[0]) / (t[1] - t[0])
    if k == 0 or k == last:
        if k == 0:
            h0, h1 = t[1] - t[0], t[2] - t[1]
            m0, m1 = (v[1] - v[0]) / h0, (v[2] - v[1]) / h1
        else:
            h0, h1 = t[last] - t[last - 1], t[last - 1] - t[last - 2]
            m0, m1 = (v[last] - v[last - 1]) / h0, (v[last - 1] - v[last - 2]) / h1
        d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
        if np.sign(d) != np.sign(m0):
            return 0.0
        if np.sign(m0) != np.sign(m1) and abs(d) > 3.0 * abs(m0):
            return 3.0 * m0
        return d
    h0, h1 = t[k] - t[k - 1], t[k + 1] - t[k]
    m0, m1 = (v[k] - v[k - 1]) / h0, (v[k + 1] - v[k]) / h1
    if np.sign(m0) != np.sign(m1) or m0 == 0.0 or m1 == 0.0:
        return 0.0
    w1, w2 = 2.0 * h1 + h0, h1 + 2.0 * h0
    return (w1 + w2) / (w1 / m0 + w2 / m1)


@njit(cache=True, nogil=True)
def _hermite(t, v, k, last):
    """The interval [t[k], t[k+1]]'s cubic in powers of (time − t[k]), highest first, as scipy's PPoly has it."""
    h = t[k + 1] - t[k]
    d0, d1 = _pchip_slope(t, v, k, last), _pchip_slope(t, v, k + 1, last)
    slope = (v[k + 1] - v[k]) / h
    c = (d0 + d1 - 2.0 * slope) / h
    return c / h, (slope - d0) / h - c, d0, v[k]


@njit(cache=True, nogil=True)
def recorded_path(t, x, y, force, has_force, start_s, end_s, times, x_out, y_out, force_out, down_out):
    """A recorded path at ``times`` in one pass: PCHIP positions, the force linear between records.

    Each time is held within [``start_s``, ``end_s``] (the finger touches where it lay within); the position
    there is the monotone piecewise-cubic (PCHIP) interpolation of records ``t`` (increasing, at least two;
    the times within ``t[0]..t[-1]``), ``x``, ``y``: what scipy's PchipInterpolator over the same records
    gives (the same slopes, the same Horner form), without building an interpolator per block, each
    interval's slopes from its neighbours alone (PCHIP is local). The force is interpolated linearly
    between records as ``numpy.interp`` does it, to the bit (NaN without one).

    Parameters
    ----------
    t : numpy.ndarray of float64
        The records' times, s, increasing.
    x, y : numpy.ndarray of float64
        The records' positions, mm.
    force : numpy.ndarray of float64
        The records' normal force, N (read only with ``has_force``).
    has_force : bool
        Whether the recording has a force.
    start_s, end_s : float
        When the finger touches, s.
    times : numpy.ndarray of float64
        The times wanted, s.
    x_out, y_out : numpy.ndarray of float64
        Filled with the positions, mm.
    force_out : numpy.ndarray of float64
        Filled with the force, N (NaN without one).
    down_out : numpy.ndarray of bool
        Filled with whether the finger touches.

    Returns
    -------
    int
        The record interval of the last time.

    Examples
    --------
    Records on a straight line (x = t, y = 2t, mm) interpolate to the line; the force is linear between its
    records and held after the last:

    >>> import numpy as np
    >>> t = np.array([0.0, 1.0, 3.0])
    >>> x, y, force, down = np.empty(3), np.empty(3), np.empty(3), np.empty(3, dtype=np.bool_)
    >>> recorded_path(t, t, 2 * t, np.array([1.0, 2.0, 2.0]), True, 0.0, 3.0, np.array([0.5, 2.0, 4.0]),
    ...               x, y, force, down)
    1
    >>> x.tolist(), y.tolist(), force.tolist(), down.tolist()
    ([0.5, 2.0, 3.0], [1.0, 4.0, 6.0], [1.5, 2.0, 2.0], [True, True, False])
    """
    last = len(t) - 1
    k = 0
    cached = -1
    a3 = a2 = a1 = a0 = b3 = b2 = b1 = b0 = 0.0
    for i in range(len(times)):
        requested = times[i]
        down_out[i] = start_s <= requested <= end_s
        s = requested  # held at the ends; NaN stays NaN, as numpy.clip leaves it
        if s < start_s:
            s = start_s
        if s > end_s:
            s = end_s
        if k > last - 1 or t[k] > s or (k < last - 1 and t[k + 1] <= s):
            k = np.searchsorted(t, s, side="right") - 1
            k = min(max(k, 0), last - 1)
        if k != cached:
            a3, a2, a1, a0 = _hermite(t, x, k, last)
            b3, b2, b1, b0 = _hermite(t, y, k, last)
            cached = k
        u = s - t[k]
        x_out[i] = ((a3 * u + a2) * u + a1) * u + a0
        y_out[i] = ((b3 * u + b2) * u + b1) * u + b0
        if not has_force:
            force_out[i] = np.nan
        elif s != s:
            force_out[i] = s
        elif s <= t[0]:  # numpy.interp: the first value at or before the first record
            force_out[i] = force[0]
        elif s >= t[last]:
            force_out[i] = force[last]
        elif t[k] == s:
            force_out[i] = force[k]
        else:
            slope = (force[k + 1] - force[k]) / (t[k + 1] - t[k])
            value = slope * (s - t[k]) + force[k]
            if value != value:  # numpy.interp's way out of a NaN: from the other end, then the flat value
                value = slope * (s - t[k + 1]) + force[k + 1]
                if value != value and force[k] == force[k + 1]:
                    value = force[k]
            force_out[i] = value
    return k


@njit(cache=True, nogil=True)
def motion(x, y, x_before, y_before, dx_out, dy_out, step_out):
    """Each sample's move from the sample before, and its length, as ``numpy.diff`` and ``numpy.hypot`` give them.

    The first move is from (``x_before``, ``y_before``), then, when there are two samples or more, replaced
    by the second's: a jump between blocks is not motion.

    Parameters
    ----------
    x, y : numpy.ndarray of float64
        The block's positions, mm.
    x_before, y_before : float
        The position before the block, mm.
    dx_out, dy_out, step_out : numpy.ndarray of float64
        Filled with each sample's move along x and y and its length, mm.

    Returns
    -------
    None

    Examples
    --------
    A jump of 5 mm between blocks does not count; the moves inside do:

    >>> import numpy as np
    >>> dx, dy, step = np.empty(3), np.empty(3), np.empty(3)
    >>> motion(np.array([1.0, 4.0, 8.0]), np.array([0.0, 4.0, 7.0]), 1.0, -5.0, dx, dy, step)
    >>> dx.tolist(), dy.tolist(), step.tolist()
    ([3.0, 3.0, 4.0], [4.0, 4.0, 3.0], [5.0, 5.0, 5.0])
    """
    n = x.shape[0]
    previous_x, previous_y = x_before, y_before
    for i in range(n):
        dx_out[i] = x[i] - previous_x
        dy_out[i] = y[i] - previous_y
        previous_x, previous_y = x[i], y[i]
    if n > 1:
        dx_out[0], dy_out[0] = dx_out[1], dy_out[1]
    for i in range(n):
        step_out[i] = math.hypot(dx_out[i], dy_out[i])


@njit(cache=True, nogil=True)
def _target_at(index, target, ahead, first_ahead, stride):
    """The target ratio at sample ``index`` of the block (``target``), or past its end at the grid of ``ahead``
    (its first point at sample ``first_ahead``, then every ``stride`` samples; held after its last)."""
    if index < target.shape[0]:
        return np.float64(target[index])
    if ahead.shape[0] == 0:
        return np.float64(target[target.shape[0] - 1])
    j = (index - first_ahead) // stride
    if j < 0:
        j = 0
    if j >= ahead.shape[0]:
        j = ahead.shape[0] - 1
    return np.float64(ahead[j])


PLAN_WORK_ROWS = 21  # rows of the planner's workspace (each at least its steps long): the programme's vectors, the
# iterations the last decision took (work[19, 0]) and the horizon's goals (the last row)
PLAN_ITERATIONS = 40  # the most interior-point iterations a decision takes (6-22 seen)


@njit(cache=True, nogil=True)
def _solve_tridiagonal(diag, off, rhs, n, scratch, out):
    """Solve the symmetric tridiagonal system (``diag``; ``off[j]`` joins j - 1 and j) for ``rhs`` into ``out``
    (Thomas's algorithm; the system is positive definite)."""
    scratch[0] = off[1] / diag[0] if n > 1 else 0.0
    out[0] = rhs[0] / diag[0]
    for j in range(1, n):
        pivot = diag[j] - off[j] * scratch[j - 1]
        if pivot == 0.0:  # lost to rounding (never seen): a hair off zero rather than a raise in a block
            pivot = 1e-300
        scratch[j] = off[j + 1] / pivot if j + 1 < n else 0.0
        out[j] = (rhs[j] - off[j] * out[j - 1]) / pivot
    for j in range(n - 2, -1, -1):
        out[j] -= scratch[j] * out[j + 1]


@njit(cache=True, nogil=True)
def _qp_direction(n, hold_on, hold_rec, work):
    """One Newton direction of the planner's programme for the complementarity targets in work[17] (falls) and
    work[18] (rises): work[11] (dx), work[12], work[13] (slacks), work[14], work[15] (multipliers)."""
    sf, sr, zf, zr = work[1], work[2], work[3], work[4]
    rf, rr, rd, diag, off, rhs = work[5], work[6], work[7], work[8], work[9], work[10]
    dx, dsf, dsr, dzf, dzr, scratch, rcf, rcr = work[11], work[12], work[13], work[14], work[15], work[16], work[17], \
        work[18]
    for j in range(n):  # v = D r + rc / s, kept in dsf, dsr for the moment
        dsf[j] = (zf[j] * rf[j] + rcf[j]) / sf[j]
        dsr[j] = (zr[j] * rr[j] + rcr[j]) / sr[j]
    for j in range(n):
        value = -rd[j] + dsf[j] - dsr[j]
        if j + 1 < n:
            value -= hold_on * dsf[j + 1] - hold_rec * dsr[j + 1]
        rhs[j] = value
    _solve_tridiagonal(diag, off, rhs, n, scratch, dx)
    for j in range(n):
        before = dx[j - 1] if j > 0 else 0.0
        dzf[j] = zf[j] / sf[j] * (hold_on * before - dx[j] + rf[j]) + rcf[j] / sf[j]
        dzr[j] = zr[j] / sr[j] * (dx[j] - hold_rec * before + rr[j]) + rcr[j] / sr[j]
        dsf[j] = (rcf[j] - sf[j] * dzf[j]) / zf[j]
        dsr[j] = (rcr[j] - sr[j] * dzr[j]) / zr[j]


@njit(cache=True, nogil=True)
def _qp_step(n, work):
    """The longest step (at most 1) along the direction in work[12:16] that keeps slacks and multipliers >= 0."""
    step = 1.0
    for row in range(4):
        values, moves = work[1 + row], work[12 + row]
        for j in range(n):
            if moves[j] < 0.0:
                limit = -values[j] / moves[j]
                if limit < step:
                    step = limit
    return step


@njit(cache=True, nogil=True)
def _plan_qp(felt, goals, steps, floor, ceiling, hold_on, hold_rec, work):
    """The command for the next step of the plan whose felt ratio at the ends of the horizon's ``steps`` steps has
    the least squared error to ``goals``, each step's command held within [floor, ceiling].

    From a felt ratio y, a command held over a step reaches exactly the ratios within
    [hold_on y + (1 - hold_on) floor, hold_rec y + (1 - hold_rec) ceiling] (falling with the onset, rising with the
    recovery), so the plans' felt ratios over the horizon form a convex set, two linear constraints a step: the
    least squared error is a convex quadratic programme of ``steps`` unknowns, solved by a primal-dual interior
    point (Mehrotra's predictor and corrector) whose Newton systems are tridiagonal. The command follows from the
    first step's felt ratio (the one that reaches it). ``work``: ``PLAN_WORK_ROWS`` rows of at least ``steps``;
    work[19, 0] is left with the iterations taken (``PLAN_ITERATIONS``: stopped at the cap).
    """
    n = steps
    floor = min(floor, ceiling)  # a floor above the ceiling: the ceiling is all the plate reaches
    if n < 1:  # no horizon: nothing to plan over; hold the felt ratio, within the reachable range
        return min(max(felt, floor), ceiling)
    low = min(floor, felt)  # a felt ratio outside the reachable range (the floor moved): the programme starts there
    high = max(ceiling, felt)
    c_on, c_rec = 1.0 - hold_on, 1.0 - hold_rec
    x, sf, sr, zf, zr = work[0], work[1], work[2], work[3], work[4]
    rf, rr, rd, diag, off = work[5], work[6], work[7], work[8], work[9]
    dsf, dsr, dzf, dzr, rcf, rcr = work[12], work[13], work[14], work[15], work[17], work[18]
    for j in range(n):
        x[j] = felt
        sf[j] = max(c_on * (felt - low), 1e-3)
        sr[j] = max(c_rec * (high - felt), 1e-3)
        zf[j] = 1.0
        zr[j] = 1.0
    work[19, 0] = PLAN_ITERATIONS  # the cap, unless solved before it
    for iteration in range(PLAN_ITERATIONS):
        worst = 0.0
        gap = 0.0
        for j in range(n):  # residuals: G x + s - h (falls, rises) and 2 (x - goals) + G^T z
            before = x[j - 1] if j > 0 else felt
            rf[j] = hold_on * before - x[j] + sf[j] + c_on * low
            rr[j] = x[j] - hold_rec * before + sr[j] - c_rec * high
            value = 2.0 * (x[j] - goals[j]) - zf[j] + zr[j]
            if j + 1 < n:
                value += hold_on * zf[j + 1] - hold_rec * zr[j + 1]
            rd[j] = value
            worst = max(worst, abs(rf[j]), abs(rr[j]), abs(value))
            gap += sf[j] * zf[j] + sr[j] * zr[j]
        mu = gap / (2 * n)
        if (worst < 1e-9 and mu < 1e-12) or not mu > 1e-15:  # solved, or as far as the arithmetic goes
            work[19, 0] = iteration
            break
        for j in range(n):  # the Newton matrix 2 I + G^T (Z / S) G
            df, dr = zf[j] / sf[j], zr[j] / sr[j]
            diag[j] = 2.0 + df + dr
            off[j] = -(hold_on * df + hold_rec * dr)
            if j > 0:
                diag[j - 1] += hold_on * hold_on * df + hold_rec * hold_rec * dr
            rcf[j] = -sf[j] * zf[j]
            rcr[j] = -sr[j] * zr[j]
        _qp_direction(n, hold_on, hold_rec, work)
        step = _qp_step(n, work)
        after = 0.0
        for j in range(n):
            after += (sf[j] + step * dsf[j]) * (zf[j] + step * dzf[j])
            after += (sr[j] + step * dsr[j]) * (zr[j] + step * dzr[j])
        sigma = (after / (2 * n) / mu) ** 3
        for j in range(n):
            rcf[j] = -sf[j] * zf[j] - dsf[j] * dzf[j] + sigma * mu
            rcr[j] = -sr[j] * zr[j] - dsr[j] * dzr[j] + sigma * mu
        _qp_direction(n, hold_on, hold_rec, work)
        step = min(1.0, 0.99 * _qp_step(n, work))
        dx = work[11]
        for j in range(n):
            x[j] += step * dx[j]
            sf[j] += step * dsf[j]
            sr[j] += step * dsr[j]
            zf[j] += step * dzf[j]
            zr[j] += step * dzr[j]
    change = x[0] - felt
    command = felt + (change / c_on if change < 0.0 else change / c_rec)
    if not math.isfinite(command):  # never seen: hold the felt ratio rather than pass a NaN on
        command = felt
    span = (ceiling - floor) * 1e-4  # within 1e-4 of an end: the end (the interior point stops just inside, by
    # up to 1e-6 where the goal lies on the end itself, which the division by a step's c magnifies)
    if command < floor + span:
        return floor
    if command > ceiling - span:
        return ceiling
    return command


@njit(cache=True, nogil=True)
def plan_friction(target, ahead, first_ahead, floor, ceiling, k_onset, k_recovery, stride, steps, felt,
                  phase, command, gate, out, work):
    """The command that makes the felt friction follow ``target`` as closely as the dynamics allow.

    The felt ratio y follows the command x (a static friction ratio) through y += k (x - y), k = ``k_onset``
    where x < y, ``k_recovery`` where x > y (per sample). Every ``stride`` samples (``phase`` counts the
    samples since the last decision, carried between blocks) the planner finds, over ``steps`` steps of
    ``stride`` samples, the commands (each held a step, within [floor, ceiling]) whose predicted felt ratio has the
    least squared error to the target at the steps' ends (a convex programme: see ``_plan_qp``), and keeps the
    first, held until the next decision. A step's target is the mean of the block's targets over it; past the
    block it comes from ``ahead`` (one a step from sample ``first_ahead``, which the caller band-limits to the
    step's length). Targets are taken within the ratios the felt friction can reach (an infinite one is its end);
    a NaN is left out of its step's mean, and a step with none keeps the step's before (the first, the latest
    target in the block, else the felt ratio). A floor above the ceiling is the ceiling.

    Parameters
    ----------
    target : numpy.ndarray of float64 or float32
        The friction ratio wanted, one a sample.
    ahead : numpy.ndarray of float32
        The friction ratios past the block, one a step.
    first_ahead : int
        The sample of ``ahead``'s first point, counted from the block's first.
    floor, ceiling : float
        The friction ratios the plate can reach.
    k_onset, k_recovery : float
        The felt ratio's step per sample towards a lower and a higher command, 0 < k <= 1.
    stride, steps : int
        Samples between decisions, and steps looked ahead.
    felt : float
        The felt ratio before the block.
    phase : int
        Samples since the last decision.
    command : float
        The command held since then, friction ratio.
    gate : int
        0: the finger is off (the command is the target, the felt ratio 1); 1: on.
    out : numpy.ndarray of float64
        Filled with the command, friction ratio.
    work : numpy.ndarray of float64
        ``PLAN_WORK_ROWS`` × at least ``steps``: the horizon's targets (its last row) and the programme's vectors.

    Returns
    -------
    tuple
        (felt, phase, command, targets below the floor): the state to carry and a count.

    Examples
    --------
    With dynamics that follow at once (k = 1) the command is the target, held at the 0.1 floor where the
    target lies below it:

    >>> import numpy as np
    >>> out = np.empty(4)
    >>> felt, phase, command, below = plan_friction(np.array([0.5, 0.5, 0.05, 0.05]), np.full(3, 0.5, dtype=np.float32),
    ...                                             5, 0.1, 1.0, 1.0, 1.0, 1, 3, 1.0, 0, 1.0, 1, out,
    ...                                             np.empty((PLAN_WORK_ROWS, 3)))
    >>> (felt, phase, command, below), out.round(9).tolist()
    ((0.1, 0, 0.1, 2), [0.5, 0.5, 0.1, 0.1])
    """
    floor = min(floor, ceiling)  # a floor above the ceiling: the ceiling is all the plate reaches
    hold_on = (1.0 - k_onset) ** stride
    hold_rec = (1.0 - k_recovery) ** stride
    goals = work[PLAN_WORK_ROWS - 1]
    below = 0
    known = felt  # the latest target that is not NaN (before the first, the felt ratio)
    for i in range(target.shape[0]):
        r_now = np.float64(target[i])
        if r_now == r_now:
            known = r_now
        if r_now < floor:
            below += 1
        if gate == 0:
            out[i] = r_now
            felt = 1.0
            phase = 0
            continue
        if phase == 0:
            # goals within the ratios the felt friction can take (an infinite target is its end); a NaN (no
            # target) is left out of a step's mean, a step without one keeps the step's before (the first: the
            # latest target): one NaN does not make the whole decision hold the felt ratio
            low, high = min(floor, felt), max(ceiling, felt)
            previous = min(max(known, low), high)
            if steps < 1:  # no horizon (the Planner never asks it): the target at once
                command = min(max(previous, floor), ceiling)
            end0 = i + stride - 1
            for j in range(steps):  # each step's mean target within the block (no aliasing), else the lookahead's
                end = end0 + j * stride
                goal = previous
                if end < target.shape[0]:
                    total = 0.0
                    count = 0
                    for m in range(end - stride + 1, end + 1):
                        value = np.float64(target[m])
                        if value == value:
                            total += min(max(value, low), high)
                            count += 1
                    if count > 0:
                        goal = total / count
                else:
                    value = _target_at(end, target, ahead, first_ahead, stride)
                    if value == value:
                        goal = min(max(value, low), high)
                goals[j] = goal
                previous = goal
            if steps >= 1:
                command = _plan_qp(felt, goals, steps, floor, ceiling, hold_on, hold_rec, work)
        x = command
        felt += (k_onset if x < felt else k_recovery) * (x - felt)
        out[i] = x
        phase += 1
        if phase >= stride:
            phase = 0
    return felt, phase, command, below


@functools.cache
def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel of the signal path with the types the renderer passes.

    So the first real-time block never waits for the compiler. Called when a renderer is built, beside its
    model's own :meth:`~ultraglide.render.physics.model_base.FrictionModel.warm_up` (once a process: cached).

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up()
    >>> len(envelope.signatures) >= 1
    True
    """
    f64 = np.zeros(4)
    envelope(f64, np.zeros(0, dtype=np.uint8), 1, 0.0, 0.0, 0.1, 0.1, 0.5, 0.0, 6.0, True, 0.9, 8.0, 0.0,
             np.empty(4), np.empty(4), np.empty(4))
    three = np.array([0.0, 1.0, 3.0])
    for has_force in (True, False):
        recorded_path(three, three, three, three, has_force, 0.0, 3.0, f64 + 0.5, np.empty(4), np.empty(4),
                      np.empty(4), np.empty(4, dtype=np.bool_))
    motion(f64, f64, 0.0, 0.0, np.empty(4), np.empty(4), np.empty(4))
    for ratio in (f64 + 0.5, np.zeros(4, dtype=np.float32) + 0.5):
        plan_friction(ratio, np.zeros(3, dtype=np.float32) + 0.5, 5, 0.1, 1.0, 0.02, 0.002, 2, 3, 1.0, 0, 1.0, 1,
                      np.empty(4), np.empty((PLAN_WORK_ROWS, 3)))
    for kind in range(3):
        swipe_path(kind, f64, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, np.empty(4), np.empty(4),
                   np.empty(4, dtype=np.bool_))
