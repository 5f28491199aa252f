"""Compiled inner loops of the renderer (numba): the envelope recursion and the model inverses.

The envelope stages are recursions (each sample depends on the previous one, with clipping), which
numpy cannot vectorise exactly; compiled, one exact loop is both the simplest code and the fastest
at every block size, from 8 samples (a live block) to millions (an export). Functions here take
and fill numpy arrays and return the state to carry to the next block; they allocate nothing.
"""

from __future__ import annotations

import functools

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
def inverse_exponential(ratio, floor, limit, factor, out):
    """Amplitudes for ratios under mu/mu0 = exp(factor a²): NaN → 0, below ``floor`` → ``limit``.
    Returns how many were below the floor."""
    clamped = 0
    for i in range(ratio.shape[0]):
        r = ratio[i]
        if r != r or r >= 1.0:  # NaN or at rest
            out[i] = 0.0
        elif r < floor:
            out[i] = limit
            clamped += 1
        else:
            out[i] = min(np.sqrt(np.log(r) / factor), limit)
    return clamped


@njit(cache=True, nogil=True)
def inverse_uniform(ratio, floor, limit, start, per_step, values, slopes, amplitude_scale, out):
    """Amplitudes from a uniform-grid table of the inverse (value at ratio ``start + i / per_step``),
    times ``amplitude_scale``; NaN → 0, below ``floor`` → ``limit``. Returns how many were below."""
    clamped = 0
    last = values.shape[0] - 2
    for i in range(ratio.shape[0]):
        r = ratio[i]
        if r != r:
            out[i] = 0.0
            continue
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


@functools.cache
def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel here with the types the renderer passes,
    so the first real-time block never waits for the compiler. Called when a renderer is built."""
    f64 = np.zeros(4)
    envelope(f64, np.zeros(0, dtype=np.uint8), 1, 0.0, 0.0, 0.1, 0.1, 0.5, 0.0, 6.0, True, 0.9, 8.0, 0.0,
             np.empty(4), np.empty(4), np.empty(4))
    inverse_exponential(f64 + 0.5, 0.1, 6.0, -0.1, np.empty(4))
    inverse_uniform(f64 + 0.5, 0.1, 6.0, 0.0, 4.0, np.zeros(5), np.zeros(4), 1.0, np.empty(4))
