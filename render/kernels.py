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

    ``gate_open`` holds 0/1 per sample unless ``open_all`` is 0 or 1 (the same for all samples).
    Returns (gain, goal, smoothed, plate, ramps started, drive samples clipped).
    The plate model is a[n] = alpha a[n-1] + (1 - alpha) d[n]; pre-compensation drives
    d[n] = (y[n] - alpha a[n-1]) / (1 - alpha) clipped to [0, drive_max], so the modelled plate
    never exceeds the smoothed target (on a rise) or its previous value (on a fall): never the limit.
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
    """Positions (mm) along a constant-speed path at ``times`` (s; held at the ends), and whether the
    finger touches: kind 0 straight, 1 circle (from its left, counter-clockwise on screen), 2 zig-zag
    (back and forth over ``width_mm``, stepping ``pitch_mm`` sideways at each end). One pass."""
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
    """A recorded path at ``times`` (s) in one pass. Each time is held within [``start_s``, ``end_s``] (the
    finger touches where it lay within); the position there is the monotone piecewise-cubic (PCHIP)
    interpolation of records ``t`` (increasing, at least two; the times within ``t[0]..t[-1]``), ``x``,
    ``y``: what scipy's PchipInterpolator over the same records gives (the same slopes, the same Horner
    form), without building an interpolator per block, each interval's slopes from its neighbours alone
    (PCHIP is local). The force (N) is interpolated linearly between records as ``numpy.interp`` does it,
    to the bit (NaN without one). Returns the record interval of the last time."""
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
    """Each sample's move from the sample before (mm; the first from (``x_before``, ``y_before``), then, when
    there are two samples or more, replaced by the second's: a jump between blocks is not motion), and its
    length, as ``numpy.diff`` and ``numpy.hypot`` give them."""
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


@njit(cache=True, nogil=True)
def _greedy(y, r, floor, ceiling, hold_on, hold_rec):
    """The command (static ratio) held over one step that brings the felt ratio ``y`` to ``r`` at its end, within
    [floor, ceiling] (where out of reach: the nearest reachable)."""
    hold = hold_on if r < y else hold_rec
    x = (r - y * hold) / (1.0 - hold)
    return min(max(x, floor), ceiling)


@njit(cache=True, nogil=True)
def _held(y, x, hold_on, hold_rec):
    """The felt ratio after a step of command ``x`` from ``y`` (onset where it falls, recovery where it rises)."""
    hold = hold_on if x < y else hold_rec
    return x + (y - x) * hold


@njit(cache=True, nogil=True)
def plan_friction(target, ahead, first_ahead, floor, ceiling, k_onset, k_recovery, stride, steps, levels, felt,
                  phase, command, gate, out, goals):
    """The command (static friction ratio, one a sample into ``out``) that makes the felt ratio follow
    ``target`` as closely as the dynamics allow, and the felt ratio the dynamics predict.

    The felt ratio y follows the command x through y += k (x - y), k = ``k_onset`` where x < y, ``k_recovery``
    where x > y (per sample). Every ``stride`` samples (``phase`` counts the samples since the last decision,
    carried between blocks) the planner compares, over ``steps`` steps of ``stride`` samples, the squared error
    between the predicted felt ratio and the target at each step's end for: holding one of ``levels`` commands
    evenly spaced in [floor, ceiling], or the greedy command (the one reaching the next step's target, clipped),
    for 1, 2, 4, ... steps and then following the greedy command; it keeps the first step of the best, held until
    the next decision. A step's target is the mean of the block's targets over it; past the block it comes from
    ``ahead`` (one a step from sample ``first_ahead``, which the caller band-limits to the step's length).
    ``gate`` 0: the finger is off (the command is the target, the felt ratio 1).
    ``goals``: room for ``steps`` floats (the horizon's targets, gathered once a decision).
    Returns (felt, phase, command, targets below the floor)."""
    hold_on = (1.0 - k_onset) ** stride
    hold_rec = (1.0 - k_recovery) ** stride
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
                    goals[j] = total / stride
                else:
                    goals[j] = _target_at(end, target, ahead, first_ahead, stride)
            r0 = goals[0]
            for c in range(levels + 1):
                if c < levels:
                    level = floor + (ceiling - floor) * c / (levels - 1)
                else:
                    level = _greedy(felt, r0, floor, ceiling, hold_on, hold_rec)
                span = 1
                while True:
                    cost = 0.0
                    y = felt
                    for j in range(steps):
                        r = goals[j]
                        x = level if j < span else _greedy(y, r, floor, ceiling, hold_on, hold_rec)
                        y = _held(y, x, hold_on, hold_rec)
                        cost += (y - r) * (y - r)
                        if cost >= best_cost:
                            break
                    if cost < best_cost:
                        best_cost = cost
                        best = level
                    if span >= steps or c == levels:
                        break
                    span *= 2
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
    """Compile (or load from numba's cache) every kernel of the signal path with the types the renderer
    passes, so the first real-time block never waits for the compiler. Called when a renderer is built,
    beside its model's own :meth:`~ultraglide.render.physics.model_base.FrictionModel.warm_up`."""
    f64 = np.zeros(4)
    envelope(f64, np.zeros(0, dtype=np.uint8), 1, 0.0, 0.0, 0.1, 0.1, 0.5, 0.0, 6.0, True, 0.9, 8.0, 0.0,
             np.empty(4), np.empty(4), np.empty(4))
    three = np.array([0.0, 1.0, 3.0])
    for has_force in (True, False):
        recorded_path(three, three, three, three, has_force, 0.0, 3.0, f64 + 0.5, np.empty(4), np.empty(4),
                      np.empty(4), np.empty(4, dtype=np.bool_))
    motion(f64, f64, 0.0, 0.0, np.empty(4), np.empty(4), np.empty(4))
    for ratio in (f64 + 0.5, np.zeros(4, dtype=np.float32) + 0.5):
        plan_friction(ratio, np.zeros(3, dtype=np.float32) + 0.5, 5, 0.1, 1.0, 0.02, 0.002, 2, 3, 5, 1.0, 0, 1.0, 1,
                      np.empty(4), np.empty(3))
    for kind in range(3):
        swipe_path(kind, f64, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, np.empty(4), np.empty(4),
                   np.empty(4, dtype=np.bool_))
