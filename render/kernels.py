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
def line_path(times, latest_s, shift_s, vx, vy, x_ref, y_ref, x_out, y_out):
    """Positions (mm) on a straight line at ``times`` (s), each held at ``latest_s`` past which the line is not
    followed: x = x_ref + vx (min(t, latest_s) + shift_s), the same for y (a live finger's prediction, ``shift_s``
    its lookahead less the line's reference time). Fills ``x_out`` and ``y_out``.

    Parameters
    ----------
    times : numpy.ndarray of float64
        The instants, s.
    latest_s, shift_s : float
        The last instant followed, and the shift added to each instant, s.
    vx, vy : float
        The line's velocity, mm/s.
    x_ref, y_ref : float
        Its position at the reference time, mm.
    x_out, y_out : numpy.ndarray of float64
        The times' length, filled with the positions, mm.

    Returns
    -------
    None

    Examples
    --------
    From (10, 5) mm at 100 mm/s along x, held after 0.05 s:

    >>> import numpy as np
    >>> x, y = np.empty(3), np.empty(3)
    >>> line_path(np.array([0.0, 0.02, 0.1]), 0.05, 0.0, 100.0, 0.0, 10.0, 5.0, x, y)
    >>> x.tolist(), y.tolist()
    ([10.0, 12.0, 15.0], [5.0, 5.0, 5.0])
    """
    for i in range(times.shape[0]):
        horizon = min(times[i], latest_s) + shift_s
        x_out[i] = vx * horizon + x_ref
        y_out[i] = vy * horizon + y_ref


@njit(cache=True, nogil=True)
def spaced_times(start_s, first, stride, rate_hz, out):
    """Fills ``out`` with the times (s) of samples ``first``, ``first + stride``, ... counted from ``start_s`` at
    ``rate_hz``: the ends of the planner's steps past a block.

    Parameters
    ----------
    start_s : float
        The time of sample 0, s.
    first, stride : int
        The first sample, and the samples between two.
    rate_hz : float
        The sample rate, Hz.
    out : numpy.ndarray of float64
        Filled, one time a point.

    Returns
    -------
    None

    Examples
    --------
    >>> import numpy as np
    >>> out = np.empty(3)
    >>> spaced_times(1.0, 2, 4, 1000.0, out)
    >>> out.tolist()
    [1.002, 1.006, 1.01]
    """
    step = 1.0 / rate_hz
    for i in range(out.shape[0]):
        out[i] = (i * stride + first) * step + start_s


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


@njit(cache=True, nogil=True)
def _held(y, x, hold_on, hold_rec):
    """The felt ratio after a step of command ``x`` from ``y`` (onset where it falls, recovery where it rises)."""
    hold = hold_on if x < y else hold_rec
    return x + (y - x) * hold


@njit(cache=True, nogil=True)
def _step_sums(k, stride):
    """(S1, S2) / ``stride``: the means over a step's samples m = 1..stride of h^m and h^2m, h = 1 - k the share of
    the way left after a sample (the felt ratio within a held step is x + (y0 - x) h^m)."""
    h = 1.0 - k
    if h <= 0.0:
        return 0.0, 0.0
    s1 = h * (1.0 - h ** stride) / (1.0 - h) if h < 1.0 else float(stride)
    s2 = h * h * (1.0 - h ** (2 * stride)) / (1.0 - h * h) if h < 1.0 else float(stride)
    return s1 / stride, s2 / stride


# rows of the planner's scratch (plan_friction's ``work``), each steps + 1 long: the horizon's targets, their
# prefix sums and squares, their suffix sums weighted by the hold's powers (onset, recovery), the holds' powers and
# the sums of their powers and squares, the greedy command's cost from each step on a settled finger (NaN until
# needed), the greedy path from the felt ratio (its felt ratio and cost so far), and the walks that fill the tails
_GOAL, _SUM, _SQUARES, _WEIGHTED, _POWER, _POWER_SUM, _SQUARE_SUM, _TAIL, _GREEDY_FELT, _GREEDY_COST, _WALK = (
    0, 1, 2, 3, 5, 7, 9, 11, 12, 13, 14)
PLAN_ROWS = 16


@njit(cache=True, nogil=True)
def _greedy_step(y, r, floor, ceiling, hold_on, hold_rec, sums):
    """One step of the greedy command from the felt ratio ``y`` towards ``r`` (the command held over the step that
    brings the felt ratio to ``r`` at its end, within [floor, ceiling]): (command, its step's squared error
    summed over its samples as the planner weighs a step, the felt ratio after, whether the command was within
    reach)."""
    hold = hold_on if r < y else hold_rec
    wanted = (r - y * hold) / (1.0 - hold)
    x = min(max(wanted, floor), ceiling)
    o = 0 if x < y else 2
    d, e = x - r, y - x
    return x, d * d + 2.0 * d * e * sums[o] + e * e * sums[o + 1], _held(y, x, hold_on, hold_rec), x == wanted


@njit(cache=True, nogil=True)
def _greedy_tail(work, start, y, steps, floor, ceiling, hold_on, hold_rec, sums, enough):
    """The squared error of following the greedy command from step ``start`` (felt ratio ``y``) to the horizon.
    After its first step within reach the felt ratio is that step's target, and the rest is the settled finger's
    (:func:`_settled_tail` from the next step). Stops once the error reaches ``enough`` (a plan already beaten)."""
    cost = 0.0
    for j in range(start, steps):
        _, step_cost, y, reached = _greedy_step(y, work[_GOAL, j], floor, ceiling, hold_on, hold_rec, sums)
        cost += step_cost
        if reached:
            return cost + _settled_tail(work, j + 1, steps, floor, ceiling, hold_on, hold_rec, sums)
        if cost >= enough:
            break
    return cost


@njit(cache=True, nogil=True)
def _settled_tail(work, start, steps, floor, ceiling, hold_on, hold_rec, sums):
    """The squared error of the greedy command from step ``start`` on, the felt ratio settled at the step before's
    target: the ``_TAIL`` row, filled where first needed. A walk from a step ends where the greedy command reaches
    a target, and the tail from the step after is the rest; the walks are kept (``_WALK``: where each began, its
    error) until one ends on a tail already known or at the horizon, then the tails are summed back."""
    walks = 0
    j = start
    while j < steps and math.isnan(work[_TAIL, j]):
        y = work[_GOAL, j - 1]
        cost = 0.0
        k = j
        while k < steps:
            _, step_cost, y, reached = _greedy_step(y, work[_GOAL, k], floor, ceiling, hold_on, hold_rec, sums)
            cost += step_cost
            k += 1
            if reached:
                break
        work[_WALK, walks] = j
        work[_WALK + 1, walks] = cost
        walks += 1
        j = k
    total = work[_TAIL, j] if j < steps else 0.0
    for walk in range(walks - 1, -1, -1):
        total += work[_WALK + 1, walk]
        work[_TAIL, int(work[_WALK, walk])] = total
    return work[_TAIL, start] if start < steps else 0.0


@njit(cache=True, nogil=True)
def _hold_cost(work, start, stop, x, y, sums):
    """The squared error of holding the command ``x`` over steps ``start`` to ``stop`` - 1 from the felt ratio ``y``,
    and the felt ratio after, in closed form: step j's felt ratio is x + (y - x) h^(j - start), h the hold of one
    step in the direction the finger moves (onset towards a lower command), so its error sums to
    n x^2 - 2 x sum(r) + sum(r^2) + 2 m1 (y - x) (x sum(h^i) - sum(r_j h^(j - start))) + m2 (y - x)^2 sum(h^2i)."""
    n = stop - start
    if n <= 0:
        return 0.0, y
    e = y - x
    o = 0 if x < y else 1
    m1, m2 = sums[2 * o], sums[2 * o + 1]
    total = work[_SUM, stop] - work[_SUM, start]
    squares = work[_SQUARES, stop] - work[_SQUARES, start]
    power = work[_POWER + o, n]
    weighted = work[_WEIGHTED + o, start] - power * work[_WEIGHTED + o, stop]
    cost = (n * x * x - 2.0 * x * total + squares + 2.0 * m1 * e * (x * work[_POWER_SUM + o, n] - weighted)
            + m2 * e * e * work[_SQUARE_SUM + o, n])
    return cost, x + e * power


@njit(cache=True, nogil=True)
def _prepare_decision(work, steps, felt, floor, ceiling, hold_on, hold_rec, sums):
    """Fills ``work``'s rows from its targets (``_GOAL``) for one decision over ``steps`` steps."""
    work[_SUM, 0] = 0.0
    work[_SQUARES, 0] = 0.0
    for o in range(2):
        hold = hold_on if o == 0 else hold_rec
        work[_POWER + o, 0] = 1.0
        work[_POWER_SUM + o, 0] = 0.0
        work[_SQUARE_SUM + o, 0] = 0.0
        work[_WEIGHTED + o, steps] = 0.0
        for n in range(steps):
            power = work[_POWER + o, n]
            work[_POWER + o, n + 1] = power * hold
            work[_POWER_SUM + o, n + 1] = work[_POWER_SUM + o, n] + power
            work[_SQUARE_SUM + o, n + 1] = work[_SQUARE_SUM + o, n] + power * power
        for j in range(steps - 1, -1, -1):
            work[_WEIGHTED + o, j] = work[_GOAL, j] + hold * work[_WEIGHTED + o, j + 1]
    for j in range(steps):
        r = work[_GOAL, j]
        work[_SUM, j + 1] = work[_SUM, j] + r
        work[_SQUARES, j + 1] = work[_SQUARES, j] + r * r
    work[_TAIL, :steps] = np.nan
    work[_TAIL, steps] = 0.0
    work[_GREEDY_FELT, 0] = felt
    work[_GREEDY_COST, 0] = 0.0
    for j in range(steps):
        _, step_cost, y, _ = _greedy_step(work[_GREEDY_FELT, j], work[_GOAL, j], floor, ceiling, hold_on, hold_rec,
                                          sums)
        work[_GREEDY_FELT, j + 1] = y
        work[_GREEDY_COST, j + 1] = work[_GREEDY_COST, j] + step_cost


@njit(cache=True, nogil=True)
def plan_friction(target, ahead, first_ahead, floor, ceiling, k_onset, k_recovery, stride, steps, levels, felt,
                  phase, command, gate, out, work):
    """The command that makes the felt friction follow ``target`` as closely as the dynamics allow.

    The felt ratio y follows the command x (a static friction ratio) through y += k (x - y), k = ``k_onset``
    where x < y, ``k_recovery`` where x > y (per sample). Every ``stride`` samples (``phase`` counts the
    samples since the last decision, carried between blocks) the planner compares, over ``steps`` steps of
    ``stride`` samples, the squared error between the predicted felt ratio and each step's target, summed over
    the step's samples (in closed form: within a held step the felt ratio is an exponential), for: holding one
    of ``levels`` commands evenly spaced in [floor, ceiling], or the greedy command (the one reaching the next
    step's target, clipped), for 1, 2, 4, ... steps and then following the greedy command;
    it keeps the first step of the best, held until the next decision. Each plan's error is weighed in closed
    form over its held stretches (:func:`_hold_cost`) and its greedy ones end, once a target is reached, in the
    greedy path's error from there, worked out once a decision: a decision costs a few passes over the horizon,
    not one per plan. A step's target is the mean of the
    block's targets over it; past the block it comes from ``ahead`` (one a step from sample ``first_ahead``,
    which the caller band-limits to the step's length).

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
    stride, steps, levels : int
        Samples between decisions, steps looked ahead, and levels tried.
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
        Room for a decision's sums: :data:`PLAN_ROWS` rows of at least ``steps`` + 1.

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
    >>> plan_friction(np.array([0.5, 0.5, 0.05, 0.05]), np.full(3, 0.5, dtype=np.float32), 5, 0.1, 1.0, 1.0, 1.0,
    ...               1, 3, 5, 1.0, 0, 1.0, 1, out, np.empty((PLAN_ROWS, 4)))
    (0.1, 0, 0.1, 2)
    >>> out.tolist()
    [0.5, 0.5, 0.1, 0.1]
    """
    hold_on = (1.0 - k_onset) ** stride
    hold_rec = (1.0 - k_recovery) ** stride
    on1, on2 = _step_sums(k_onset, stride)
    rec1, rec2 = _step_sums(k_recovery, stride)
    sums = (on1, on2, rec1, rec2)
    below = 0
    for i in range(target.shape[0]):
        r_now = np.float64(target[i])
        if r_now < floor:
            below += 1
        if gate == 0:
            out[i] = r_now
            felt = 1.0
            phase = 0
            continue
        if phase == 0:
            best_cost = np.inf
            best = command
            end0 = i + stride - 1
            for j in range(steps):  # each step's mean target within the block (no aliasing), else the lookahead's
                end = end0 + j * stride
                if end < target.shape[0]:
                    total = 0.0
                    for m in range(end - stride + 1, end + 1):
                        total += np.float64(target[m])
                    work[_GOAL, j] = total / stride
                else:
                    work[_GOAL, j] = _target_at(end, target, ahead, first_ahead, stride)
            _prepare_decision(work, steps, felt, floor, ceiling, hold_on, hold_rec, sums)
            greedy_first = _greedy_step(felt, work[_GOAL, 0], floor, ceiling, hold_on, hold_rec, sums)[0]
            for c in range(levels + 1):  # hold a level (or the greedy command) for 1, 2, 4, ... steps, then greedy
                if c < levels:
                    level = floor + (ceiling - floor) * c / (levels - 1)
                else:
                    level = greedy_first
                span = 1
                while True:
                    held = min(span, steps)
                    cost, y = _hold_cost(work, 0, held, level, felt, sums)
                    if held < steps and cost < best_cost:  # (a tail adds error: a plan already beaten stays so)
                        cost += _greedy_tail(work, held, y, steps, floor, ceiling, hold_on, hold_rec, sums,
                                             best_cost - cost)
                    if cost < best_cost:
                        best_cost = cost
                        best = level
                    if span >= steps or c == levels:
                        break
                    span *= 2
            delay = 1  # or follow the greedy command for 1, 2, 4, ... steps first, then hold a level: a rise begun
            while delay < steps:  # later than now (holding a level from now is either too early or never)
                for c in range(levels):
                    level = floor + (ceiling - floor) * c / (levels - 1)
                    cost, _ = _hold_cost(work, delay, steps, level, work[_GREEDY_FELT, delay], sums)
                    cost += work[_GREEDY_COST, delay]
                    if cost < best_cost:
                        best_cost = cost
                        best = greedy_first
                delay *= 2
            command = best
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
    line_path(f64, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, np.empty(4), np.empty(4))
    spaced_times(0.0, 1, 2, 12000.0, np.empty(4))
    for ratio in (f64 + 0.5, np.zeros(4, dtype=np.float32) + 0.5):
        plan_friction(ratio, np.zeros(3, dtype=np.float32) + 0.5, 5, 0.1, 1.0, 0.02, 0.002, 2, 3, 5, 1.0, 0, 1.0, 1,
                      np.empty(4), np.empty((PLAN_ROWS, 4)))
    for kind in range(3):
        swipe_path(kind, f64, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, np.empty(4), np.empty(4),
                   np.empty(4, dtype=np.bool_))
