"""Compiled inner loops of the output stage (numba): the drive limiter, the carrier and a first-order filter.

Like :mod:`ultraglide.render.kernels`, each function takes and fills numpy arrays, returns the state
to carry to the next block, and allocates nothing; :func:`warm_up` compiles them (or loads them from
numba's cache) when an output stage is built, never inside a real-time block.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def limit_drive(drive, limit, max_drive, gain, fast_plate, tolerance, out):
    """Clamp each drive sample to [0, max_drive] and so that a fast model of the plate stays under the limit.

    The fast plate model p[n] = p[n-1] + gain (u[n] - p[n-1]) must stay at or below ``limit``, so each
    request is lowered to u[n] <= p[n-1] + (limit - p[n-1]) / gain. NaN and negative requests become 0.

    Parameters
    ----------
    drive : numpy.ndarray of float64
        The requested drive amplitudes, µm peak-to-peak.
    limit : float
        The amplitude the plate may not exceed, µm peak-to-peak.
    max_drive : float
        The largest drive the amplifier takes, µm peak-to-peak.
    gain : float
        The fast plate model's step per sample, 0 < gain <= 1.
    fast_plate : float
        The fast plate model's amplitude before the first sample, µm peak-to-peak.
    tolerance : float
        A request lowered by more than this is counted, µm peak-to-peak.
    out : numpy.ndarray of float64
        Filled with the limited drive, as long as ``drive``.

    Returns
    -------
    tuple of (float, int, float)
        The fast plate model after the last sample (µm peak-to-peak), the samples lowered by more than
        ``tolerance``, and the worst excess: the most a request went above its ceiling (µm peak-to-peak).

    Examples
    --------
    With ``gain`` 1 the model follows the drive at once, so the ceiling is the limit, 6 µm:

    >>> import numpy as np
    >>> out = np.empty(4)
    >>> limit_drive(np.array([2.0, 10.0, -1.0, np.nan]), 6.0, 8.0, 1.0, 0.0, 0.006, out)
    (0.0, 1, 4.0)
    >>> out.tolist()
    [2.0, 6.0, 0.0, 0.0]
    """
    limited = 0
    worst = 0.0
    for i in range(drive.shape[0]):
        wanted = drive[i]
        if not wanted > 0.0:  # NaN, zero or negative
            wanted = 0.0
        ceiling = fast_plate + (limit - fast_plate) / gain
        if ceiling > max_drive:
            ceiling = max_drive
        if ceiling < 0.0:
            ceiling = 0.0
        if wanted > ceiling:
            if wanted - ceiling > tolerance:
                limited += 1
            if wanted - ceiling > worst:
                worst = wanted - ceiling
            wanted = ceiling
        fast_plate += gain * (wanted - fast_plate)
        out[i] = wanted
    return fast_plate, limited, worst


@njit(cache=True, nogil=True)
def modulate(knots, first_frame, up, scale, carrier, offset, out):
    """Carrier × envelope: the envelope interpolated linearly between control samples.

    Frame m (counted from ``first_frame`` within the knots' span) lies between knots m // up and
    m // up + 1; knot values are drive amplitudes, scaled by ``scale`` to a fraction of full scale
    and limited to [0, 1]. ``carrier`` is one exact period of the carrier, read from ``offset``.
    Every frame's value depends on its own index alone, so a span rendered in chunks (each with its
    own ``first_frame`` and ``offset``, on any thread) equals the span rendered at once.

    Parameters
    ----------
    knots : numpy.ndarray of float64
        The envelope at the control rate, drive amplitude in µm peak-to-peak.
    first_frame : int
        The first frame to render, counted in audio frames from the first knot.
    up : int
        Audio frames per control sample.
    scale : float
        Full-scale fraction per µm peak-to-peak (1 / the drive at full scale).
    carrier : numpy.ndarray of float32
        One exact period of the carrier, unit amplitude.
    offset : int
        Where in ``carrier`` the first frame reads.
    out : numpy.ndarray of float32
        Filled with the modulated signal, fractions of full scale.

    Returns
    -------
    int
        The carrier position after the last frame.

    Examples
    --------
    A two-sample carrier (+1, -1) under an envelope rising from 0 to 8 µm over two frames, at 1/8 of full
    scale per µm:

    >>> import numpy as np
    >>> out = np.empty(4, dtype=np.float32)
    >>> modulate(np.array([0.0, 8.0, 8.0]), 0, 2, 0.125, np.array([1.0, -1.0], dtype=np.float32), 0, out)
    0
    >>> out.tolist()
    [0.0, -0.5, 1.0, -1.0]
    """
    period = carrier.shape[0]
    position = offset
    frames = out.shape[0]
    index = first_frame // up  # one integer division per control period, not per frame
    within = first_frame - index * up
    m = 0
    while m < frames:
        a = min(max(knots[index] * scale, 0.0), 1.0)
        b = min(max(knots[index + 1] * scale, 0.0), 1.0)
        rise = b - a
        stop = min(frames, m + up - within)
        for k in range(m, stop):
            out[k] = (a + rise * ((within + k - m) / up)) * carrier[position]
            position += 1
            if position == period:
                position = 0
        m = stop
        index += 1
        within = 0
    return position


@njit(cache=True, nogil=True)
def sine_block(phase, increment, out):
    """sin(2π phase) for consecutive samples (carriers with no short exact period).

    Parameters
    ----------
    phase : float
        The phase of the first sample, in cycles (0 <= phase < 1).
    increment : float
        The phase step per sample, in cycles (carrier frequency / sample rate).
    out : numpy.ndarray of float32
        Filled with the sine, unit amplitude.

    Returns
    -------
    float
        The phase after the last sample, in cycles.

    Examples
    --------
    A quarter cycle a sample:

    >>> import numpy as np
    >>> out = np.empty(4, dtype=np.float32)
    >>> sine_block(0.0, 0.25, out)
    0.0
    >>> out.round(6).tolist()
    [0.0, 1.0, 0.0, -1.0]
    """
    for m in range(out.shape[0]):
        out[m] = np.sin(2.0 * np.pi * phase)
        phase += increment
        if phase >= 1.0:
            phase -= 1.0
    return phase


@njit(cache=True, nogil=True)
def first_order(b0, b1, a1, x, state, out):
    """y[n] = b0 x[n] + b1 x[n-1] - a1 y[n-1] in transposed direct form (as ``scipy.signal.lfilter``).

    y[n] = b0 x[n] + z, then z = b1 x[n] - a1 y[n].

    Parameters
    ----------
    b0, b1, a1 : float
        The filter's coefficients (``a0`` is 1).
    x : numpy.ndarray of float64
        The input, any unit.
    state : float
        z before the first sample.
    out : numpy.ndarray of float64
        Filled with the output, the input's unit.

    Returns
    -------
    float
        z after the last sample.

    Examples
    --------
    The impulse response of y[n] = x[n] / 2 + y[n-1] / 2 halves each sample:

    >>> import numpy as np
    >>> out = np.empty(4)
    >>> first_order(0.5, 0.0, -0.5, np.array([1.0, 0.0, 0.0, 0.0]), 0.0, out)
    0.03125
    >>> out.tolist()
    [0.5, 0.25, 0.125, 0.0625]
    """
    for n in range(x.shape[0]):
        y = b0 * x[n] + state
        state = b1 * x[n] - a1 * y
        out[n] = y
    return state


def first_order_filter(b, a, x, zi):
    """A first-order filter along the last axis of ``x``, as ``lfilter(b, a, x, axis=-1, zi=zi)`` gives it.

    Without importing scipy.signal (a second of a process's start).

    Parameters
    ----------
    b, a : sequence of float
        At most two taps each, ``a[0]`` = 1.
    x : numpy.ndarray
        The input, one row a channel (a 1-D signal is one), any unit.
    zi : sequence of float or numpy.ndarray
        The initial state, one value a row, in lfilter's form.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray)
        The output (``x``'s shape) and the final state (``zi``'s shape).

    Examples
    --------
    >>> import numpy as np
    >>> y, final = first_order_filter([0.5], [1.0, -0.5], np.array([1.0, 0.0, 0.0, 0.0]), [0.0])
    >>> y.tolist(), final.tolist()
    ([0.5, 0.25, 0.125, 0.0625], [0.03125])
    >>> y, final = first_order_filter([0.5], [1.0, -0.5], np.ones((2, 2)), np.array([[0.0], [1.0]]))
    >>> y.tolist(), final.tolist()
    ([[0.5, 0.75], [1.5, 1.25]], [[0.375], [0.625]])
    """
    b0 = float(b[0])
    b1 = float(b[1]) if len(b) > 1 else 0.0
    a1 = float(a[1]) if len(a) > 1 else 0.0
    if type(x) is np.ndarray and x.ndim == 1 and type(zi) is list and len(zi) == 1:
        # one channel, its state [z]: the simulated plate's every block (its drive in float32)
        x = np.ascontiguousarray(x, dtype=float)
        y = np.empty(x.shape[0])
        final = np.empty(1)
        final[0] = first_order(b0, b1, a1, x, float(zi[0]), y)
        return y, final
    x = np.ascontiguousarray(x, dtype=float)
    rows = x.reshape(-1, x.shape[-1])  # one row a channel (a 1-D signal is one)
    states = np.asarray(zi, dtype=float).reshape(rows.shape[0])
    y = np.empty_like(rows)
    final = np.empty(rows.shape[0])
    for row in range(rows.shape[0]):
        final[row] = first_order(b0, b1, a1, rows[row], states[row], y[row])
    return y.reshape(x.shape), final.reshape(np.shape(zi))


@functools.cache
def warm_up() -> None:
    """Compile every kernel here with the types the output stage passes (or load them from numba's cache).

    Called once a process (cached); never inside a real-time block.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up()
    >>> len(limit_drive.signatures) >= 1
    True
    """
    f32 = np.zeros(4, dtype=np.float32)
    limit_drive(np.zeros(4), 6.0, 8.0, 0.1, 0.0, 0.006, np.empty(4))
    modulate(np.zeros(3), 0, 2, 0.125, f32, 0, np.empty(4, dtype=np.float32))
    sine_block(0.0, 0.25, np.empty(4, dtype=np.float32))
    first_order(0.5, 0.0, -0.5, np.zeros(4), 0.0, np.empty(4))
