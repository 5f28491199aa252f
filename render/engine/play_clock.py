"""When each stream value plays on the plate, on the host's clock, from the plate's own SENSORS frames.

A plate driver's SENSORS frame names the stream index that was playing at its first sample (``setpoint_index``)
and carries ``n`` samples of ``1 / sensor_rate_hz`` each; the host reads it at ``received_s`` (perf_counter s).
A frame cannot arrive before its last sample was taken, so::

    received_s - n / sensor_rate_hz - setpoint_index / stream_rate_hz  >=  the host time index 0 played

(the *origin* of the play clock: index ``k`` plays at ``origin + k / stream_rate_hz``), and the excess is the
frame's delay (the link, the device's send loop, the reader thread) plus the part of a value's period already played
at the first sample (< ``1 / stream_rate_hz``): never negative. The lowest bound over recent frames is the origin
within the fastest frame's delay. :class:`PlayClock` keeps every frame's bound in a ring (the reader thread: a few
float stores, no allocation) and answers, for a time ``at_s``, the lowest bound of the frames read within
``window_s`` around it (:meth:`PlayClock.origin_s`), each moved to ``at_s`` by the plate's clock drift against the
host's: the slope of the lower hull of every bound kept (the line under all of them that passes closest to them,
the linear-programming estimate of a clock's skew), believed once the bounds span ``DRIFT_SPAN_S`` and within
``MAX_DRIFT`` (a crystal's tolerance is tens of parts per million).

A plate whose playback stalls (an underrun) plays every later index later: the origin moves up, and the bounds
follow once the window has passed the stall. A link whose rate is known (``link_bytes_per_s``, as a device states
it in its handshake) carries a frame of ``n`` samples in no less than its bytes' time, ``(18 + 12 n)`` bytes
(docs/protocol.md), which is taken off its bound; ``n`` counted up to one ``SENSORS_PERIOD_MS`` of samples (a frame
that took longer to fill was sent at once on a link that does not pace its bytes, the simulated plate's pty).

Example: frames read a random, positive 0.1–3 ms after their last sample; the origin is found within the fastest
frame's delay:

>>> import numpy as np
>>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
>>> rng = np.random.default_rng(1)
>>> for frame in range(300):                                      # 3 s of 10-sample frames, every 10 ms
...     index = 120 * frame                                       # index 0 played at 100.0 s
...     clock.take(index, 10, 100.0 + frame * 0.01 + 0.01 + rng.uniform(0.1e-3, 3e-3))
>>> round((clock.origin_s(101.5) - 100.0) * 1e3, 1)                # ms late: the fastest frame's delay
0.1
"""

from __future__ import annotations

import threading
import time

import numpy as np
from ultraglide.devices.protocol.spec import NOT_PLAYING, SENSORS_PERIOD_MS

SENSORS_BYTES = (18, 12)  # a SENSORS frame on the wire: 18 bytes and 12 a sample (n <= 19; docs/protocol.md)
WINDOW_S = 2.0  # frames read within this window around a time give its origin (decided from sim runs: docs)
KEPT = 4096  # frames kept (41 s at 100 a second): the drift's span
DRIFT_SPAN_S = 8.0  # the drift is believed once the kept frames span this much
MAX_DRIFT = 100e-6  # a slope beyond this is no crystal's drift (a stall's step): the drift is then taken as 0


class PlayClock:
    """See the module docstring.

    Parameters
    ----------
    stream_rate_hz : float
        The stream's values a second (the device's setpoint rate), Hz.
    sensor_rate_hz : float
        The device's sensor samples a second, Hz (settable later: a device says it in its handshake).
    window_s : float
        Frames read within this window around a time (s) give the origin there.
    link_bytes_per_s : float
        The link's bytes a second (0: unknown, no delay assumed); settable later.

    Raises
    ------
    ValueError
        A rate or a window that is not positive, a link rate that is negative.

    Examples
    --------
    No frame yet, no clock (the record keeps the renderer's plan):

    >>> clock = PlayClock(stream_rate_hz=12000.0)
    >>> print(clock.origin_s(5.0), clock.frames)
    None 0
    """

    def __init__(self, stream_rate_hz: float, sensor_rate_hz: float = 1000.0, window_s: float = WINDOW_S,
                 link_bytes_per_s: float = 0.0):
        if not (stream_rate_hz > 0 and sensor_rate_hz > 0):
            raise ValueError(f"the play clock needs positive rates, not {stream_rate_hz:g} Hz and "
                             f"{sensor_rate_hz:g} Hz")
        if not window_s > 0 or not link_bytes_per_s >= 0:
            raise ValueError(f"the play clock needs a positive window and a link rate >= 0, not {window_s:g} s and "
                             f"{link_bytes_per_s:g} bytes/s")
        self.stream_rate_hz = float(stream_rate_hz)
        self.sensor_rate_hz = float(sensor_rate_hz)
        self.window_s = float(window_s)
        self.link_bytes_per_s = float(link_bytes_per_s)
        self._received = np.zeros(KEPT)  # perf_counter s
        self._index = np.zeros(KEPT)  # the stream index at the frame's first sample
        self._samples = np.zeros(KEPT)  # its samples
        self.frames = 0  # frames taken (bounds written: the reader thread's count)
        self._lock = threading.Lock()  # the readers' (a record's writer and a caller): not the reader thread's

    # ---- the device's reader thread ----
    def take_frame(self, frame, received_s: float | None = None) -> None:
        """A decoded SENSORS frame, as a device's reader thread hands it over (a sensor listener).

        Parameters
        ----------
        frame : Sensors
            A decoded SENSORS frame (``devices.protocol.Sensors``).
        received_s : float, optional
            When it was read, perf_counter s (default: now).

        Examples
        --------
        A frame packed and parsed as the wire carries it: 2 samples from index 480, read at 1.0 s:

        >>> from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
        >>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
        >>> clock.take_frame(parse_sensors(sensors_payload(40, 480, sensor_samples([3.0, 3.2]))), 1.0)
        >>> round(clock.origin_s(1.0), 6)                          # 1.0 - 2 ms - 480 / 12 kHz
        0.958
        """
        self.take(frame.setpoint_index, len(frame.samples),
                  time.perf_counter() if received_s is None else received_s)

    def take(self, setpoint_index: int, samples: int, received_s: float) -> None:
        """One frame: the index playing at its first sample, its samples, when it was read (perf_counter s). A
        frame while nothing plays (``NOT_PLAYING``) or without samples says nothing of the clock.

        Parameters
        ----------
        setpoint_index : int
            The stream index playing at the frame's first sample.
        samples : int
            Its sensor samples.
        received_s : float
            When it was read, perf_counter s.

        Examples
        --------
        >>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
        >>> clock.take(NOT_PLAYING, 10, 1.0); clock.frames
        0
        >>> clock.take(1200, 10, 1.0); round(clock.origin_s(1.0), 6)
        0.89
        """
        if setpoint_index == NOT_PLAYING or samples <= 0:
            return
        slot = self.frames % KEPT
        self._received[slot] = received_s
        self._index[slot] = setpoint_index
        self._samples[slot] = samples
        self.frames += 1  # after the slot is whole: a reader takes only slots below the count

    # ---- readers (a record's writer thread) ----
    def _kept(self) -> tuple[np.ndarray, np.ndarray]:
        """The frames kept, oldest first: when each was read and its bound on the origin (perf_counter s; with the
        rates as they are now: a device states them in its handshake, after its first frames may have come)."""
        with self._lock:
            count = self.frames
            n = min(count, KEPT)
            order = np.arange(count - n, count) % KEPT
            received, samples = self._received[order], self._samples[order]
            bound = received - samples / self.sensor_rate_hz - self._index[order] / self.stream_rate_hz
            if self.link_bytes_per_s > 0:
                regular = max(1.0, round(self.sensor_rate_hz * SENSORS_PERIOD_MS / 1000.0))
                bound -= (SENSORS_BYTES[0] + SENSORS_BYTES[1] * np.minimum(samples, regular)) / self.link_bytes_per_s
            return received, bound

    def drift(self) -> float:
        """The plate's clock against the host's (s a host second): the slope of the lower hull of every bound kept,
        0 until they span ``DRIFT_SPAN_S`` or beyond ``MAX_DRIFT``.

        Returns
        -------
        float
            The origin's slope (positive: the plate plays slower than the host counts).

        Examples
        --------
        A plate 100 ppm slow, frames every 10 ms with a random delay of 0 to 2 ms, 20 s:

        >>> import numpy as np
        >>> clock = PlayClock(stream_rate_hz=12000.0)
        >>> rng = np.random.default_rng(0)
        >>> for frame in range(2000):
        ...     played = frame * 0.01 * (1 + 100e-6)                      # index 120 * frame starts here
        ...     clock.take(120 * frame, 10, played + 0.01 + rng.uniform(0, 2e-3))
        >>> abs(clock.drift() * 1e6 - 100) < 5                        # parts per million
        True
        """
        received, bound = self._kept()
        return _hull_slope(received, bound)

    def origin_s(self, at_s: float) -> float | None:
        """When index 0 plays (perf_counter s) by the frames read within ``window_s`` around ``at_s``; None when
        none was.

        Parameters
        ----------
        at_s : float
            The time the origin is wanted at, perf_counter s.

        Returns
        -------
        float or None
            The origin, perf_counter s; None without a frame near ``at_s``.

        Examples
        --------
        >>> clock = PlayClock(stream_rate_hz=1000.0, sensor_rate_hz=1000.0)
        >>> clock.take(0, 1, 0.0015); clock.take(10, 1, 0.0112)             # read 0.5 ms and 0.2 ms late
        >>> round(clock.origin_s(0.02) * 1e3, 3), clock.origin_s(10.0)
        (0.2, None)
        """
        received, bound = self._kept()
        near = np.abs(received - at_s) <= self.window_s / 2
        if not near.any():
            return None
        slope = _hull_slope(received, bound)
        return float(np.min(bound[near] + slope * (at_s - received[near])))

    def times_s(self, index: np.ndarray, at_s: float) -> np.ndarray | None:
        """When each stream index plays (perf_counter s) by the clock around ``at_s``; None without one.

        Parameters
        ----------
        index : numpy.ndarray
            Stream indices.
        at_s : float
            Where on the host's clock they play (roughly: the plan's time), perf_counter s.

        Returns
        -------
        numpy.ndarray or None
            Their times, perf_counter s.

        Examples
        --------
        >>> import numpy as np
        >>> clock = PlayClock(stream_rate_hz=1000.0, sensor_rate_hz=1000.0)
        >>> clock.take(0, 1, 0.0105)
        >>> clock.times_s(np.array([0, 1, 2]), 0.0).round(4).tolist()
        [0.0095, 0.0105, 0.0115]
        """
        origin = self.origin_s(at_s)
        if origin is None:
            return None
        return origin + np.asarray(index, dtype=float) / self.stream_rate_hz


def _hull_slope(received: np.ndarray, bound: np.ndarray) -> float:
    """The slope of the lower hull's edge above the frames' mean time (the line under every bound that minimises the
    sum of the gaps to them), 0 over less than ``DRIFT_SPAN_S`` or beyond ``MAX_DRIFT``."""
    if len(received) < 2 or received.max() - received.min() < DRIFT_SPAN_S:
        return 0.0
    order = np.argsort(received, kind="stable")
    t0 = float(received[order[0]])
    xs, ys = (received[order] - t0).tolist(), bound[order].tolist()
    hull: list[int] = []
    for i in range(len(xs)):  # Andrew's monotone chain, lower part
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            if (xs[b] - xs[a]) * (ys[i] - ys[a]) - (ys[b] - ys[a]) * (xs[i] - xs[a]) <= 0:
                hull.pop()
            else:
                break
        hull.append(i)
    mean = sum(xs) / len(xs)
    for a, b in zip(hull[:-1], hull[1:], strict=True):
        if xs[a] <= mean <= xs[b] and xs[b] > xs[a]:
            slope = (ys[b] - ys[a]) / (xs[b] - xs[a])
            return slope if abs(slope) <= MAX_DRIFT else 0.0
    return 0.0

