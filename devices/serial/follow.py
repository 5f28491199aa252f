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

import threading

WINDOW_FRAMES = 50  # telemetry frames a window (50 a second: 1 s)
FOLLOW_FACTOR = 3.0  # the measured mean within 1/3..3x the sent mean
MIN_SENT_UM_PP = 0.5  # a window whose mean sent amplitude is below this is judged only as "stopped" (below)
STOPPED_UM_PP = 0.05  # sent less than this on average: the plate should be still ...
STILL_UM_PP = 1.0  # ... measuring less than this
WINDOWS_RUNNING = 2  # windows outside the bound in a row: a fault


class AmplitudeFollow:
    """The comparison over a run (see the module's docstring); fed from the telemetry reader, read by others."""

    def __init__(self):
        self._lock = threading.Lock()
        self._sent = 0.0
        self._values = 0
        self._measured = 0.0
        self._frames = 0
        self._start_s = 0.0
        self._running = 0  # windows outside the bound in a row
        self._pending: tuple | None = None  # the first window of the present run outside the bound
        self.first: tuple[float, float, float] | None = None  # (at s, sent mean, measured mean) of the fault
        self.windows = 0  # windows outside the bound, counted once the fault stood
        self.judging = True  # off while the carrier is swept: off resonance a plate rightly plays less than sent

    def observe(self, sent_um_pp: float, sent_values: int, measured_um_pp: float, judged: bool, at_s: float) -> None:
        """One telemetry frame: the amplitudes sent since the last (their sum, µm p-p, and count), what the plate
        measured, whether this frame is judged (output on and playing), when (s into the run)."""
        if not (judged and self.judging):  # (its values sent are left out with it: the window holds judged frames only)
            return
        if not self._frames:
            self._start_s = at_s
        self._sent += sent_um_pp
        self._values += sent_values
        self._measured += measured_um_pp
        self._frames += 1
        if self._frames < WINDOW_FRAMES:
            return
        sent = self._sent / self._values if self._values else 0.0
        measured = self._measured / self._frames
        self._sent, self._values, self._measured, self._frames = 0.0, 0, 0.0, 0
        if sent >= MIN_SENT_UM_PP:
            outside = not sent / FOLLOW_FACTOR <= measured <= sent * FOLLOW_FACTOR
        elif sent < STOPPED_UM_PP:
            outside = measured >= STILL_UM_PP
        else:
            return  # between: too little sent to judge a plate by
        with self._lock:
            if not outside:
                self._running, self._pending = 0, None
                return
            self._running += 1
            if self._running == 1:
                self._pending = (self._start_s, sent, measured)
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
            at_s, sent, measured = self.first
            windows = self.windows
        return (f"the plate does not follow the amplitude it is sent: from {at_s:.2f} s it was sent {sent:.2f} µm p-p "
                f"on average over a second and measured {measured:.2f} (the bound: within 1/{FOLLOW_FACTOR:g} to "
                f"{FOLLOW_FACTOR:g} times what is sent, over seconds sent at least {MIN_SENT_UM_PP:g} µm p-p; under "
                f"{STILL_UM_PP:g} when sent nothing); {windows} such second{'s' if windows != 1 else ''}")

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
