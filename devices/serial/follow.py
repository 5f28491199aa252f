"""Whether the plate's measured amplitude follows the amplitude it is sent: a plate that does not is a device fault.

The host sends amplitudes (setpoints, µm p-p at resonance); the plate's telemetry says the amplitude it measures
(its sensing piezo). A plate that ignores what it is sent (a firmware that does not play the stream, a sensor
stuck, a drive stage dead, a resonance far off the carrier) looks from the host like one that plays: so the two
are compared, over windows of a second (:data:`WINDOW_FRAMES` telemetry frames), while the output plays:

* the bound: the window's mean measured amplitude within 1/:data:`FOLLOW_FACTOR` to :data:`FOLLOW_FACTOR` (3)
  times the mean amplitude sent, where that mean is at least :data:`MIN_SENT_UM_PP` (0.5 µm p-p: below it a
  sensor's noise and offset are a large part of what it reads); and, sent less than :data:`STOPPED_UM_PP`, a
  measured mean under :data:`STILL_UM_PP` (1 µm p-p). Why a second and 3x: the values sent play a buffer later
  (up to 250 ms; a second's means barely notice), a plate's resonant response lags by its time constant
  (Q / (pi f), 2 ms at Q 180 and 25 kHz), and an honest plate whose full scale or resonance is off by the
  profile's tolerance reads within 2x (the resonance 60 Hz off at Q 180: 0.76x); a plate outside 3x for two
  seconds running does not follow;
* what is sent, at the readings' instants: a frame's measured amplitude is one reading, not a mean, and an output
  modulated at a multiple of the frames' 50 Hz is read at one phase of it every frame (a plan's pulses on a 1 mm
  grating at 100 mm/s: an honest plate read 0.06 or 2.5 µm p-p a second where it was sent 0.7 on average, and was
  found at fault in 2 of 6 runs). On a v3 device, whose frames say the index playing, each reading is set against
  the lowest and highest a following plate may read then (:class:`SentHistory`): the window's mean measured
  within 1/3 of the lowest's mean to 3 times the highest's (only the high side where the lowest is under
  :data:`MIN_SENT_UM_PP`); a v2 device's against the mean sent, as above;
* two windows running outside the bound are a fault: said once (the first window's figures), each such window
  counted. A window holds only frames judged: while the output is on and (v3) playing (a frame while the plate's
  buffer ran dry, or the output was off, is left out with the values sent before it); a device without an
  amplitude sensor (v3: no SENSOR_AMPLITUDE; v2: it never reported a measured amplitude above 0) is not judged.

Examples
--------
>>> follow = AmplitudeFollow()
>>> for second in range(3):
...     for frame in range(WINDOW_FRAMES):
...         follow.observe(sent_um_pp=3.0 * 40, sent_values=40, measured_um_pp=0.1, judged=True, at_s=second)
>>> follow.windows, follow.words() is not None
(3, True)
"""

from __future__ import annotations

import math
import threading

import numpy as np

WINDOW_FRAMES = 50  # telemetry frames a window (50 a second: 1 s)
FOLLOW_FACTOR = 3.0  # the measured mean within 1/3..3x the sent mean
MIN_SENT_UM_PP = 0.5  # a window whose mean sent amplitude is below this is judged only as "stopped" (below)
STOPPED_UM_PP = 0.05  # sent less than this on average: the plate should be still ...
STILL_UM_PP = 1.0  # ... measuring less than this
WINDOWS_RUNNING = 2  # windows outside the bound in a row: a fault


HISTORY_VALUES = 1 << 14  # values sent kept by stream index (1.4 s at 12 kHz: more than the plate buffers)
HISTORY_TAUS = 8.0  # the plate's response at an index is made from this many time constants of values before it
READING_WITHIN_S = 0.001  # a reading is taken within this of the index said playing (a block of the device's)


class SentHistory:
    """The amplitudes sent by stream index, and what a plate that follows them may read while it plays one.

    TELEMETRY's measured amplitude is one reading, taken as its frame is made (50 a second), not a mean: an
    output modulated at a multiple of 50 Hz (a 1 mm grating at 100 mm/s, whose plan pulses the plate once a period)
    is read at the same phase of each period, so a second's readings can be far from the second's mean sent (an
    honest plate read at its pulses' foot measured 0.06 µm p-p a second where it was sent 0.68 on average). The
    frame says the index the device expects next and the values it buffers (v3), so the index playing as the
    reading was taken is known, within a block: a plate that follows reads then its resonant envelope's response
    to the values sent up to it (time constant ``time_constant_s``, the profile's Q / (pi f0)), a millisecond
    either side (the reading's place within its block); under its amplitude loop, which drives it onto the values
    faster, anything between that response and the values themselves.

    The writer puts the values it sends (:meth:`put`, a copy into a ring made once); the reader asks
    :meth:`expected` at each frame.

    Parameters
    ----------
    rate_hz : float
        The stream's rate, values per second.
    time_constant_s : float
        The plate's envelope time constant, s.

    Examples
    --------
    >>> import numpy as np
    >>> history = SentHistory(12000.0, 0.0025)
    >>> history.put(0, np.full(600, 3.0))            # 50 ms at 3 µm p-p, then 10 ms at 0
    >>> history.put(600, np.zeros(120))
    >>> history.expected(500)                        # steady: 3 whichever way the plate follows
    (3.0, 3.0)
    >>> [round(v, 3) for v in history.expected(647)]  # 47 values after the fall: 3 e^-(60 / 30) to 3 e^-(36 / 30)
    [0.406, 0.904]
    >>> [round(v, 3) for v in history.expected(647, driven=True)]  # an amplitude loop may have brought it to 0
    [0.0, 0.904]
    >>> history.expected(800) is None                # not sent yet: nothing to say
    True
    """

    def __init__(self, rate_hz: float, time_constant_s: float):
        alpha = math.exp(-1.0 / (rate_hz * time_constant_s)) if time_constant_s > 0 else 0.0
        span = max(1, min(HISTORY_VALUES // 4, math.ceil(HISTORY_TAUS * rate_hz * time_constant_s)))
        self._around = max(1, round(rate_hz * READING_WITHIN_S))
        # the response at an index to the values before it, newest last: (1 - alpha) alpha^k, from rest
        self._weights = (1.0 - alpha) * alpha ** np.arange(span - 1, -1, -1, dtype=float)
        self._weights[0] += alpha ** span  # the value before the span held since (the plate at it)
        self._values = np.zeros(HISTORY_VALUES)
        self._scratch = np.empty(span + 2 * self._around)
        self._next: int | None = None  # the index after the last value put
        self._lock = threading.Lock()

    def put(self, first_index: int, values: np.ndarray) -> None:
        """Values sent from stream index ``first_index`` on (µm p-p). Indices skipped since the last hold the last
        value sent (a plate whose buffer runs dry holds it; one told to rest is not judged).

        Parameters
        ----------
        first_index : int
            The stream index of ``values[0]``.
        values : numpy.ndarray
            The amplitudes sent, µm p-p.

        Examples
        --------
        >>> import numpy as np
        >>> history = SentHistory(1000.0, 0.001)
        >>> history.put(0, np.full(20, 2.0))
        >>> history.put(20, np.zeros(5))
        >>> history.put(30, np.full(20, 2.0))        # 5 skipped: the plate held the last value, 0
        >>> [round(v, 4) for v in history.expected(27)]   # highest: 2 e^-7, 7 values of 0 played by index 26
        [0.0, 0.0018]
        """
        n, ring = len(values), self._values
        with self._lock:
            if self._next is None:
                ring[:] = 0.0
            elif first_index > self._next:
                held = ring[(self._next - 1) % HISTORY_VALUES]
                start, gap = self._next % HISTORY_VALUES, min(first_index - self._next, HISTORY_VALUES)
                ring[start:start + gap] = held
                ring[:max(0, start + gap - HISTORY_VALUES)] = held
            if n > HISTORY_VALUES:
                values, first_index, n = values[-HISTORY_VALUES:], first_index + n - HISTORY_VALUES, HISTORY_VALUES
            start = first_index % HISTORY_VALUES
            head = min(n, HISTORY_VALUES - start)
            ring[start:start + head] = values[:head]
            ring[:n - head] = values[head:]
            self._next = first_index + n

    def expected(self, index: int, driven: bool = False) -> tuple[float, float] | None:
        """What a following plate may read while index ``index`` plays: (lowest, highest), µm p-p; None where the
        values that make it were not all sent here (not yet, or no longer held).

        Parameters
        ----------
        index : int
            The stream index playing.
        driven : bool
            The plate is under its amplitude loop (it may be anywhere between its response and the values).

        Returns
        -------
        tuple of (float, float) or None
            The lowest and highest reading of a plate that follows, µm p-p.

        Examples
        --------
        >>> import numpy as np
        >>> history = SentHistory(1000.0, 0.001)
        >>> history.put(0, np.full(50, 2.0))
        >>> history.expected(40)
        (2.0, 2.0)
        """
        span, around = len(self._weights), self._around
        with self._lock:
            if self._next is None:
                return None
            last = min(index + around, self._next - 1)
            first = last - span - 2 * around + 1
            if index >= self._next or first < self._next - HISTORY_VALUES:
                return None
            start = first % HISTORY_VALUES
            head = min(len(self._scratch), HISTORY_VALUES - start)
            scratch = self._scratch
            scratch[:head] = self._values[start:start + head]
            scratch[head:] = self._values[:len(scratch) - head]
        responses = [float(scratch[k:k + span] @ self._weights) for k in (0, around, 2 * around)]
        low, high = min(responses), max(responses)
        if driven:  # with the values within a millisecond either side of the index (the last at `last`)
            now = scratch[span - 1:]
            low, high = min(low, float(now.min())), max(high, float(now.max()))
        return low, high

    def expected_at_device(self, device_index: int, driven: bool = False) -> tuple[float, float] | None:
        """:meth:`expected` at an index as a device numbers it (u32: the host's index modulo 2**32).

        Parameters
        ----------
        device_index : int
            The index playing, as the device's u32 counts it.
        driven : bool
            As :meth:`expected`.

        Returns
        -------
        tuple of (float, float) or None
            As :meth:`expected`.

        Examples
        --------
        >>> import numpy as np
        >>> history = SentHistory(1000.0, 0.001)
        >>> history.put(2**32 + 10, np.full(50, 2.0))   # the host's index past the device's wrap
        >>> history.expected_at_device(40)
        (2.0, 2.0)
        """
        with self._lock:
            last = None if self._next is None else self._next - 1
        if last is None:
            return None
        return self.expected(last - (last - device_index) % (1 << 32), driven)


class AmplitudeFollow:
    """The comparison over a run (see the module's docstring); fed from the telemetry reader, read by others."""

    def __init__(self):
        self._lock = threading.Lock()
        self._sent = 0.0
        self._values = 0
        self._lowest = 0.0  # what a following plate may read at each frame's reading (SentHistory), summed ...
        self._highest = 0.0
        self._expected_frames = 0  # ... over the frames that say it
        self._measured = 0.0
        self._frames = 0
        self._start_s = 0.0
        self._running = 0  # windows outside the bound in a row
        self._pending: tuple | None = None  # the first window of the present run outside the bound
        self.first: tuple | None = None  # (at s, sent mean, measured mean, lowest and highest means) of the fault
        self.windows = 0  # windows outside the bound, counted once the fault stood
        self.judged = 0  # windows judged (inside or outside the bound)
        self.judging = True  # off while the carrier is swept: off resonance a plate rightly plays less than sent

    def observe(self, sent_um_pp: float, sent_values: int, measured_um_pp: float, judged: bool, at_s: float,
                expected_um_pp: tuple[float, float] | None = None) -> None:
        """One telemetry frame: the amplitudes sent since the last (their sum, µm p-p, and count), what the plate
        measured, whether this frame is judged (output on and playing), when (s into the run), and the lowest and
        highest a plate that follows may read at this reading (:class:`SentHistory`; None: not known, v2)."""
        if not (judged and self.judging):  # (its values sent are left out with it: the window holds judged frames only)
            return
        if not self._frames:
            self._start_s = at_s
        self._sent += sent_um_pp
        self._values += sent_values
        self._measured += measured_um_pp
        if expected_um_pp is not None:
            self._lowest += expected_um_pp[0]
            self._highest += expected_um_pp[1]
            self._expected_frames += 1
        self._frames += 1
        if self._frames < WINDOW_FRAMES:
            return
        # each reading is one instant's: where every frame says what a following plate may read then, the window's
        # readings are judged against that, at the same instants (SentHistory); else against the mean sent
        sent = self._sent / self._values if self._values else 0.0
        instants = self._expected_frames == self._frames
        low, high = (self._lowest / self._frames, self._highest / self._frames) if instants else (sent, sent)
        measured = self._measured / self._frames
        self._sent, self._values, self._measured, self._frames = 0.0, 0, 0.0, 0
        self._lowest, self._highest, self._expected_frames = 0.0, 0.0, 0
        if high < STOPPED_UM_PP:
            outside = measured >= STILL_UM_PP
        elif low >= MIN_SENT_UM_PP:
            outside = not low / FOLLOW_FACTOR <= measured <= high * FOLLOW_FACTOR
        elif high >= MIN_SENT_UM_PP:
            outside = measured > high * FOLLOW_FACTOR  # too little may be read to judge a plate low by
        else:
            return  # between: too little sent to judge a plate by
        with self._lock:
            self.judged += 1
            if not outside:
                self._running, self._pending = 0, None
                return
            self._running += 1
            if self._running == 1:
                self._pending = (self._start_s, sent, measured, low, high) if instants else \
                    (self._start_s, sent, measured, None, None)
            if self._running == WINDOWS_RUNNING:
                self.first = self.first or self._pending
                self.windows += WINDOWS_RUNNING
            elif self._running > WINDOWS_RUNNING:
                self.windows += 1

    def words(self) -> str | None:
        """One sentence for the run's report, or None if the plate followed (or was never judged)."""
        with self._lock:
            if self.first is None:
                return None
            at_s, sent, measured, low, high = self.first
            windows = self.windows
        instants = "" if low is None else \
            f"; a plate that follows reads {low:.2f} to {high:.2f} on average at the readings' instants"
        return (f"the plate does not follow the amplitude it is sent: from {at_s:.2f} s it was sent {sent:.2f} µm p-p "
                f"on average over a second and measured {measured:.2f} (the bound: within 1/{FOLLOW_FACTOR:g} to "
                f"{FOLLOW_FACTOR:g} times what is sent, over seconds sent at least {MIN_SENT_UM_PP:g} µm p-p; under "
                f"{STILL_UM_PP:g} when sent nothing{instants}); {windows} such second{'s' if windows != 1 else ''}")

    def first_s(self) -> float:
        with self._lock:
            return 0.0 if self.first is None else self.first[0]


CARRIER_TOLERANCE_HZ = 0.01  # a carrier reported within this of one sent is that carrier (plate sweep's, R-CARRIER's)
CARRIER_LAG_S = 0.25  # a carrier sent this recently may still be what telemetry says (a frame or two in flight)
CARRIER_RUNNING_S = 1.0  # telemetry saying another carrier than any sent for this long: the plate does not follow


class CarrierFollow:
    """Whether the carrier the plate reports is the one it was sent: a plate that says another for a second running
    while its output plays is a device fault, said once (its first such second's figures) and counted in frames.

    The carrier is sent at the handshake (SET_CARRIER, acknowledged), by ``set_carrier`` (``plate sweep``) and by
    the resonance tracker (``--track-resonance``, unacknowledged); telemetry, 50 frames a second, says the carrier
    in force. A frame is believed to follow when its carrier is, within :data:`CARRIER_TOLERANCE_HZ`, the carrier
    sent now or one sent in the last :data:`CARRIER_LAG_S` (frames in flight when it changed); a plate whose frames
    do not, for :data:`CARRIER_RUNNING_S` running, plays a carrier nobody asked for (a firmware that ignores
    SET_CARRIER, a synthesiser stuck) at a resonance-sharp plate's cost of most of its amplitude.

    Examples
    --------
    >>> follow = CarrierFollow()
    >>> for frame in range(60):  # 1.2 s of telemetry saying 24 kHz while 25 kHz was sent
    ...     follow.observe(sent_hz=25000.0, reported_hz=24000.0, judged=True, at_s=0.02 * frame)
    >>> follow.words()[:74]
    'the plate does not follow the carrier it is sent: from 0.00 s it was sent '
    >>> follow.words()[74:]
    '25000.00 Hz and said it played 24000.00 Hz for 1.00 s running; 9 frames after that'
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._sent: list[tuple[float, float]] = []  # (since s, Hz) of the carriers sent in the last CARRIER_LAG_S
        self._since_s: float | None = None  # when the present run of frames off every carrier sent began
        self.first: tuple[float, float, float] | None = None  # (at s, sent Hz, reported Hz) of the fault
        self.frames = 0  # frames off the carrier after the fault stood

    def observe(self, sent_hz: float, reported_hz: float, judged: bool, at_s: float) -> None:
        """One telemetry frame: the carrier sent now (Hz), the carrier it reports (Hz), whether it is judged (the
        output on and playing: not while the handshake sets the carrier), when (s into the run)."""
        if not self._sent or self._sent[-1][1] != sent_hz:
            self._sent.append((at_s, sent_hz))
        while len(self._sent) > 1 and at_s - self._sent[1][0] > CARRIER_LAG_S:
            del self._sent[0]  # the carrier before the next was replaced more than the lag ago
        if not judged:
            self._since_s = None
            return
        if any(abs(reported_hz - hz) <= CARRIER_TOLERANCE_HZ for _, hz in self._sent):
            self._since_s = None
            return
        with self._lock:
            if self._since_s is None:
                self._since_s = at_s
            if self.first is not None:
                self.frames += 1
            elif at_s - self._since_s >= CARRIER_RUNNING_S:
                self.first = (self._since_s, sent_hz, reported_hz)

    def words(self) -> str | None:
        """One sentence for the run's report, or None if the plate played the carrier it was sent."""
        with self._lock:
            if self.first is None:
                return None
            at_s, sent_hz, reported_hz = self.first
            frames = self.frames
        return (f"the plate does not follow the carrier it is sent: from {at_s:.2f} s it was sent {sent_hz:.2f} Hz "
                f"and said it played {reported_hz:.2f} Hz for {CARRIER_RUNNING_S:.2f} s running; {frames} "
                f"frame{'s' if frames != 1 else ''} after that")

    def first_s(self) -> float:
        with self._lock:
            return 0.0 if self.first is None else self.first[0]
