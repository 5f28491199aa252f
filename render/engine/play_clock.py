"""When each stream value plays on the plate, on the host's clock, from the plate's own SENSORS frames.

A plate driver's SENSORS frame carries ``n`` consecutive sensor samples from its sample ``first_sample`` (numbered
on the device's clock at ``sensor_rate_hz``) and names the stream index playing at the first one
(``setpoint_index``); the host reads it at ``received_s`` (perf_counter s). Two things follow:

- *Where the device's clock is.* A frame cannot arrive before its last sample was taken, so::

      received_s - (first_sample + n) / sensor_rate_hz  >=  the host time of the device's sample 0

  (the clock's *origin*), and the excess is the frame's delay: the link, the device's send loop, the reader thread;
  never negative. A link whose rate is known (``link_bytes_per_s``, as a device states it in its handshake) carries
  a frame in no less than its bytes' time, ``18 + 12 n`` bytes (docs/protocol.md), which is taken off too, ``n``
  counted up to one ``SENSORS_PERIOD_MS`` of samples (a longer frame was sent at once on a link that does not pace
  its bytes: the simulated plate's pty). The lowest bound over the frames read from ``window_s`` before a time to
  ``ahead_s`` after it is the origin there, within the fastest frame's delay, each bound moved to that time by the
  plate's clock drift against the host's: the slope of the lower hull of every bound kept (the line under all of
  them that passes closest to them, the linear-programming estimate of a clock's skew), believed once the bounds
  span ``DRIFT_SPAN_S`` and within ``MAX_DRIFT`` (a crystal's tolerance is tens of parts per million).
- *When each index plays on it.* Index ``k`` plays ``(k - setpoint_index) / stream_rate_hz`` after the first sample
  of the last frame that named an index at or below it, and no later than ``(next index - k) / stream_rate_hz``
  before the next frame's first sample: where the two differ, a stall (the index held while the samples went on)
  or a skip came between, at a sample the frames do not say, and the later of the two is taken (never early; an
  index a frame names plays at its sample).
  Every later index moves by exactly what the device's own counts say: no window to wait out.
- *A device that states its clock* (``FEATURE_CLOCK_STATED``, docs/protocol.md) answers a CLOCK request at once
  with its sensor clock when it took it, ``c`` samples (never ahead, at most ``MAX_CLOCK_LAG_MS`` behind): a
  request written at ``asked_s`` and answered by ``received_s`` brackets the origin,
  ``asked_s - c / sensor_rate_hz - MAX_CLOCK_LAG_MS <= origin <= received_s - c / sensor_rate_hz``, whatever
  the device's send loop, its blocks or its link do to its SENSORS frames. The upper bound joins the frames' (the
  lowest of all places the clock; the fastest round trip, not the fastest frame, decides how late it can be), and
  :meth:`PlayClock.late_at_most_s` says how late that is at most: the tightest bracket's width. With replies, the
  frames' bounds take no byte time off: a link that does not pace its bytes (the simulated plate's pty) brings a
  frame in less than its bytes' time at the stated rate, which made the clock early by up to 0.15 ms there.

:class:`PlayClock` keeps each frame in a ring (the reader thread: a few float stores, no allocation) and places
indices on request (:meth:`PlayClock.times_s`, a record's writer thread). A device that restarts numbers its samples
from 0 again: the frames before are a clock of their own, and only the present one's are used.

Examples
--------
Frames read a random, positive 0.1–3 ms after their last sample; an index is placed within the fastest frame's
delay:

>>> import numpy as np
>>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
>>> rng = np.random.default_rng(1)
>>> for frame in range(300):                          # 3 s of 10-sample frames; the device's sample 0 at 100.0 s
...     clock.take(120 * frame, 10, 100.0 + frame * 0.01 + 0.01 + rng.uniform(0.1e-3, 3e-3), 10 * frame)
>>> late_s = clock.times_s(np.array([18000]), 101.5)[0] - 101.5   # index 18 000 plays at 101.5 s
>>> bool(0.0 <= late_s < 0.2e-3)
True
"""

from __future__ import annotations

import threading
import time

import numpy as np
from ultraglide.devices.protocol.spec import MAX_CLOCK_LAG_MS, NOT_PLAYING, SENSORS_PERIOD_MS

SENSORS_BYTES = (18, 12)  # a SENSORS frame on the wire: 18 bytes and 12 a sample (n <= 19; docs/protocol.md)
WINDOW_S = 8.0  # frames read up to this long before a time give the origin there (decided from sim runs: docs)
AHEAD_S = 4.0  # ... and up to this long after it (a record's writer waits that long, its ring allowing)
KEPT = 4096  # frames kept (41 s at 100 a second): the drift's span
DRIFT_SPAN_S = 8.0  # the drift is believed once the kept frames span this much
MAX_DRIFT = 100e-6  # a slope beyond this is no crystal's drift: the drift is then taken as 0
HULL_BIN_S = 0.1  # the drift's hull is taken over each 0.1 s's lowest bound (its vertices, within 10 µs)
WRAP = 1 << 32  # the device's sample numbers and stream indices are u32
MAX_GAP_S = 10.0  # frames further apart on the device's clock (or back) belong to another clock (a restart)


class PlayClock:
    """See the module docstring.

    Parameters
    ----------
    stream_rate_hz : float
        The stream's values a second (the device's setpoint rate), Hz.
    sensor_rate_hz : float
        The device's sensor samples a second, Hz (settable later: a device says it in its handshake).
    window_s, ahead_s : float
        Frames read from ``window_s`` before a time to ``ahead_s`` after it (s) give the origin there.
    link_bytes_per_s : float
        The link's bytes a second (0: unknown, no delay assumed); settable later.

    Raises
    ------
    ValueError
        A rate or a window that is not positive, a look ahead or a link rate that is negative.

    Examples
    --------
    No frame yet, no clock (the record keeps the renderer's plan):

    >>> import numpy as np
    >>> clock = PlayClock(stream_rate_hz=12000.0)
    >>> print(clock.times_s(np.arange(3), 5.0), clock.frames)
    None 0
    """

    def __init__(self, stream_rate_hz: float, sensor_rate_hz: float = 1000.0, window_s: float = WINDOW_S,
                 link_bytes_per_s: float = 0.0, ahead_s: float = AHEAD_S):
        if not (stream_rate_hz > 0 and sensor_rate_hz > 0):
            raise ValueError(f"the play clock needs positive rates, not {stream_rate_hz:g} Hz and "
                             f"{sensor_rate_hz:g} Hz")
        if not window_s > 0 or not ahead_s >= 0 or not link_bytes_per_s >= 0:
            raise ValueError(f"the play clock needs a positive window, a look ahead and a link rate >= 0, not "
                             f"{window_s:g} s, {ahead_s:g} s and {link_bytes_per_s:g} bytes/s")
        self.stream_rate_hz = float(stream_rate_hz)
        self.sensor_rate_hz = float(sensor_rate_hz)
        self.window_s = float(window_s)
        self.ahead_s = float(ahead_s)
        self.link_bytes_per_s = float(link_bytes_per_s)
        self._received = np.zeros(KEPT)  # perf_counter s
        self._first = np.zeros(KEPT)  # the frame's first sample number (u32)
        self._index = np.zeros(KEPT)  # the stream index playing at it (u32)
        self._samples = np.zeros(KEPT)  # its samples
        self.frames = 0  # frames taken (the reader thread's count)
        self._clock_received = np.zeros(KEPT)  # a CLOCK_REPLY's arrival, perf_counter s
        self._clock_asked = np.zeros(KEPT)  # ... its request's sending
        self._clock_sample = np.zeros(KEPT)  # ... the device's sensor clock it states, samples (not unwrapped)
        self.clocks = 0  # CLOCK_REPLY frames taken (the reader thread's count)
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
        A frame packed and parsed as the wire carries it: samples 40 and 41 with index 480 at the first, read at
        1.0 s: index 480 played at 1.0 - 2 ms at the latest:

        >>> import numpy as np
        >>> from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
        >>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
        >>> clock.take_frame(parse_sensors(sensors_payload(40, 480, sensor_samples([3.0, 3.2]))), 1.0)
        >>> clock.times_s(np.array([480, 492]), 1.0).round(6).tolist()
        [0.998, 0.999]
        """
        self.take(frame.setpoint_index, len(frame.samples),
                  time.perf_counter() if received_s is None else received_s, frame.first_sample)

    def take(self, setpoint_index: int, samples: int, received_s: float, first_sample: int) -> None:
        """One frame: the index playing at its first sample, its samples, when it was read (perf_counter s), its
        first sample's number. A frame while nothing plays (``NOT_PLAYING``) or without samples says nothing.

        Parameters
        ----------
        setpoint_index : int
            The stream index playing at the frame's first sample.
        samples : int
            Its sensor samples.
        received_s : float
            When it was read, perf_counter s.
        first_sample : int
            Its first sample's number on the device's clock.

        Examples
        --------
        >>> import numpy as np
        >>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
        >>> clock.take(NOT_PLAYING, 10, 1.0, 0); clock.frames
        0
        >>> clock.take(1200, 10, 1.0, 990); clock.times_s(np.array([1200]), 1.0).round(6).tolist()
        [0.99]
        """
        if setpoint_index == NOT_PLAYING or samples <= 0:
            return
        slot = self.frames % KEPT
        self._received[slot] = received_s
        self._first[slot] = first_sample
        self._index[slot] = setpoint_index
        self._samples[slot] = samples
        self.frames += 1  # after the slot is whole: a reader takes only slots below the count

    def take_clock(self, samples: float, asked_s: float, received_s: float) -> None:
        """A CLOCK_REPLY, as a plate driver's reader thread hands it over (a clock listener): the device's sensor
        clock when it took a request written at ``asked_s`` and answered by ``received_s``.

        Parameters
        ----------
        samples : float
            The device's sensor clock, samples (numbered as SENSORS' ``first_sample``, wrapping at 2**32).
        asked_s, received_s : float
            When the request was written and the reply read, perf_counter s.

        Examples
        --------
        Frames read 2 ms after their last sample (a device that sends late), and a round trip of 0.2 ms to a device
        whose sample 0 was at 10.0 s: the clock places index 1200, played at sample 100, 0.2 ms late at most, not 2:

        >>> import numpy as np
        >>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
        >>> for frame in range(20):
        ...     clock.take(120 * frame, 10, 10.0 + (10 * frame + 10) / 1000.0 + 2e-3, 10 * frame)
        >>> clock.take_clock(150.5, 10.1505, 10.1507)
        >>> late_s = float(clock.times_s(np.array([1200]), 10.1)[0] - 10.1)
        >>> round(late_s * 1e3, 3), round(clock.late_at_most_s(10.1) * 1e3, 3)
        (0.2, 1.2)
        """
        slot = self.clocks % KEPT
        self._clock_received[slot] = received_s
        self._clock_asked[slot] = asked_s
        self._clock_sample[slot] = samples
        self.clocks += 1

    # ---- readers (a record's writer thread) ----
    def _kept(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The frames of the device's present clock, oldest first: when each was read, its bound on the origin, its
        first sample's time after the origin (s, unwrapped) and its index (unwrapped); with the rates as they are
        now (a device states them in its handshake, after its first frames may have come). Then the CLOCK replies
        of that clock: when each was read, its upper bound on the origin and its lower one."""
        with self._lock:
            count = self.frames
            n = min(count, KEPT - 1)  # not the oldest slot: the next frame is written over it meanwhile
            order = np.arange(count - n, count) % KEPT
            received, first = self._received[order], self._first[order]
            index, samples = self._index[order], self._samples[order]
            clocks = self.clocks
            m = min(clocks, KEPT - 1)
            order = np.arange(clocks - m, clocks) % KEPT
            clock_received, clock_asked = self._clock_received[order], self._clock_asked[order]
            clock_sample = self._clock_sample[order]
        if n == 0:
            return received, received, received, received, received, received, received
        steps = (np.diff(first) % WRAP) if n > 1 else np.zeros(0)
        broken = (steps < samples[:-1]) | (steps > MAX_GAP_S * self.sensor_rate_hz)  # back, or too far: a restart
        start = int(np.flatnonzero(broken)[-1]) + 1 if broken.any() else 0
        received, samples = received[start:], samples[start:]
        sample = first[start] + np.concatenate(([0.0], np.cumsum(steps[start:])))  # unwrapped
        moved = (np.diff(index[start:]) + WRAP // 2) % WRAP - WRAP // 2  # signed: a device may play one again
        index = index[start] + np.concatenate(([0.0], np.cumsum(moved)))
        bound = received - (sample + samples) / self.sensor_rate_hz
        # the replies of this clock: read after its first frame, numbered within MAX_GAP_S of its frames
        stamp = first[start] + (clock_sample - first[start] + WRAP // 2) % WRAP - WRAP // 2
        ours = (clock_received >= received[0]) & (stamp >= sample[0] - MAX_GAP_S * self.sensor_rate_hz) & \
            (stamp <= sample[-1] + MAX_GAP_S * self.sensor_rate_hz)
        if self.link_bytes_per_s > 0 and not ours.any():  # (with replies, no frame's byte time is assumed: a link
            regular = max(1.0, round(self.sensor_rate_hz * SENSORS_PERIOD_MS / 1000.0))  # that does not pace its
            bound -= (SENSORS_BYTES[0] + SENSORS_BYTES[1] * np.minimum(samples, regular)) / self.link_bytes_per_s
        stamp_s = stamp[ours] / self.sensor_rate_hz  # bytes, the simulated plate's pty, brings frames in less)
        clock_received = clock_received[ours]
        return (received, bound, sample / self.sensor_rate_hz, index, clock_received, clock_received - stamp_s,
                clock_asked[ours] - stamp_s - MAX_CLOCK_LAG_MS / 1000.0)

    def drift(self) -> float:
        """The plate's clock against the host's (s a host second): the slope of the lower hull of every bound kept,
        0 until they span ``DRIFT_SPAN_S`` or beyond ``MAX_DRIFT``.

        Returns
        -------
        float
            The origin's slope (positive: the plate's clock runs slower than the host's).

        Examples
        --------
        A plate 60 ppm slow, frames every 10 ms with a random delay of 0 to 2 ms, 20 s:

        >>> import numpy as np
        >>> clock = PlayClock(stream_rate_hz=12000.0)
        >>> rng = np.random.default_rng(0)
        >>> for frame in range(2000):
        ...     sampled = (frame + 1) * 0.01 * (1 + 60e-6)                   # its last sample ends here
        ...     clock.take(120 * frame, 10, sampled + rng.uniform(0, 2e-3), 10 * frame)
        >>> abs(clock.drift() * 1e6 - 60) < 5                                # parts per million
        True
        """
        received, bound, _, _, clock_received, clock_bound, _ = self._kept()
        return _hull_slope(np.concatenate((received, clock_received)), np.concatenate((bound, clock_bound)))

    def times_s(self, index: np.ndarray, at_s: float) -> np.ndarray | None:
        """When each stream index plays (perf_counter s), by the device's clock placed with the frames read from
        ``window_s`` before ``at_s`` to ``ahead_s`` after it; None when none was.

        Parameters
        ----------
        index : numpy.ndarray
            Stream indices, in the host's count (the device's, unwrapped).
        at_s : float
            Where on the host's clock they play (roughly: the plan's time), perf_counter s.

        Returns
        -------
        numpy.ndarray or None
            Their times, perf_counter s; None without a frame near ``at_s``.

        Examples
        --------
        Index 10 at sample 100 (1 kHz), read 0.5 ms after it; the next frame names index 20 at sample 113, not 110:
        the plate stalled 3 ms between them. Index 22 plays 3 ms later than the first frame alone would say; index 15,
        between, is placed at the latest it can have played (3 ms earlier if the stall came after it):

        >>> import numpy as np
        >>> clock = PlayClock(stream_rate_hz=1000.0, sensor_rate_hz=1000.0)
        >>> clock.take(10, 1, 0.1015, 100); clock.take(20, 1, 0.1145, 113)
        >>> (clock.times_s(np.array([10, 15, 22]), 0.1) * 1e3).round(3).tolist(), clock.times_s(np.array([1]), 9.0)
        ([100.5, 108.5, 115.5], None)
        """
        received, bound, sampled_s, at_index, clock_received, clock_bound, _ = self._kept()
        near = (received >= at_s - self.window_s) & (received <= at_s + self.ahead_s)  # (none without frames)
        if not near.any():
            return None
        every_received, every_bound = np.concatenate((received, clock_received)), np.concatenate((bound, clock_bound))
        slope = _hull_slope(every_received, every_bound)
        near = (every_received >= at_s - self.window_s) & (every_received <= at_s + self.ahead_s)
        origin = float(np.min(every_bound[near] + slope * (at_s - every_received[near])))
        index = np.asarray(index, dtype=float)
        frame = np.clip(np.searchsorted(np.maximum.accumulate(at_index), index, side="right") - 1, 0,
                        len(at_index) - 1)
        after = origin + sampled_s[frame] + (index - at_index[frame]) / self.stream_rate_hz  # from its frame on
        following = np.minimum(frame + 1, len(at_index) - 1)  # ... and back from the next frame, where there is one
        before = origin + sampled_s[following] - (at_index[following] - index) / self.stream_rate_hz
        named = (following == frame) | (index == at_index[frame])  # the frame named it: it played at its sample
        return np.where(named, after, np.maximum(after, before))

    def late_at_most_s(self, at_s: float) -> float | None:
        """How much later than the truth :meth:`times_s` places an index at ``at_s`` at most (s), by the CLOCK
        replies read in the same window: the tightest bracket on the origin they give (the lowest upper bound less
        the highest lower one, each moved to ``at_s`` by the drift); None without a reply there (a device that does
        not state its clock: the frames alone say no lower bound).

        Parameters
        ----------
        at_s : float
            Where on the host's clock (perf_counter s).

        Returns
        -------
        float or None
            Seconds (at least 0 from an honest device: its brackets overlap).

        Examples
        --------
        Two round trips to a device whose sample 0 was at 10.0 s, 0.3 and 0.2 ms long: the origin lies within 0.2 ms
        and the clock's lag of up to 1 ms:

        >>> clock = PlayClock(stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
        >>> clock.take(0, 10, 10.012, 0)
        >>> clock.take_clock(50.0, 10.0499, 10.0502); clock.take_clock(80.0, 10.0800, 10.0802)
        >>> round(clock.late_at_most_s(10.05) * 1e3, 3)
        1.2
        """
        received, bound, _, _, clock_received, clock_bound, clock_low = self._kept()
        near = (clock_received >= at_s - self.window_s) & (clock_received <= at_s + self.ahead_s)
        if len(received) == 0 or not near.any():
            return None
        slope = _hull_slope(np.concatenate((received, clock_received)), np.concatenate((bound, clock_bound)))
        moved = slope * (at_s - clock_received[near])
        return float(np.min(clock_bound[near] + moved) - np.max(clock_low[near] + moved))


def _hull_slope(received: np.ndarray, bound: np.ndarray) -> float:
    """The slope of the lower hull's edge above the frames' mean time (the line under every bound that minimises the
    sum of the gaps to them), over each ``HULL_BIN_S``'s lowest bound; 0 over less than ``DRIFT_SPAN_S`` or beyond
    ``MAX_DRIFT``."""
    if len(received) < 2 or received.max() - received.min() < DRIFT_SPAN_S:
        return 0.0
    t0 = float(received.min())
    bins = ((received - t0) / HULL_BIN_S).astype(np.int64)
    order = np.lexsort((bound, bins))  # by bin, lowest first
    lowest = order[np.concatenate(([True], np.diff(bins[order]) != 0))]
    xs, ys = (received[lowest] - t0).tolist(), bound[lowest].tolist()
    hull: list[int] = []
    for i in range(len(xs)):  # Andrew's monotone chain, lower part
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            if (xs[b] - xs[a]) * (ys[i] - ys[a]) - (ys[b] - ys[a]) * (xs[i] - xs[a]) <= 0:
                hull.pop()
            else:
                break
        hull.append(i)
    mean = float(np.mean(received)) - t0
    for a, b in zip(hull[:-1], hull[1:], strict=True):
        if xs[a] <= mean <= xs[b] and xs[b] > xs[a]:
            slope = (ys[b] - ys[a]) / (xs[b] - xs[a])
            return slope if abs(slope) <= MAX_DRIFT else 0.0
    return 0.0
