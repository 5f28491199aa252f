"""What the plate driver takes in from the link, on the reader thread: telemetry, SENSORS, acknowledgements and
refusals; the plate's buffer depth, its faults and counters over the run."""

from __future__ import annotations

import threading
import time

from ultraglide.devices import protocol as p
from ultraglide.devices.counter_check import WRAP, plausible_restart
from ultraglide.devices.protocol.ranges import (
    SAMPLE_GAP_S,
    clock_reply_out_of_range,
    sensors_out_of_range,
    telemetry_out_of_range,
)
from ultraglide.devices.serial.follow import SentHistory
from ultraglide.devices.serial.link import (
    CLEAR_RETRY_S,
    CUT_FAULTS,
    DEPTH_DEADBAND_S,
    DEPTH_WINDOW,
    LINK_COUNTERS,
    REENABLE_AFTER_S,
    TRACKING_DISTURBANCES,
    Pacing,
    SerialCounters,
)
from ultraglide.devices.serial.locks import DriverLocks
from ultraglide.devices.serial.report import RunAccount
from ultraglide.devices.serial.session import Session

FAULT_COUNTER_NAMES = tuple(f"fault count {p.FAULT_NAMES.get(1 << bit, bit)}" for bit in range(p.FAULT_BITS))


class DepthTracker:
    """v3 telemetry says how many values wait in the plate's buffer. Over DEPTH_WINDOW frames while it plays,
    a median depth off its target by more than the deadband (the plate's clock drifting from the host's, its
    playback restarted later than the host's clock) asks the writer to move its lead by the difference: the
    buffer, and the latency it costs, come back to the prefill and a frame. The median, not the mean: a
    few frames made while the plate caught up a stall of its own, or read a backlog late, report a
    buffer that is deep only for that moment; moving the lead for them would starve the plate after."""

    def __init__(self, pacing: Pacing, lock: threading.Lock):
        self.pacing, self._lock = pacing, lock
        self._request = 0.0  # values the writer's lead should move by
        self.stream_epoch = 0  # a new stream (wake, connection, re-anchoring): the window starts again (writer)
        self._epoch = -1
        self._depths, self._n = [0] * DEPTH_WINDOW, 0  # the present window's depths, values
        self.worst = 0.0  # the largest correction asked, values

    def new_stream(self) -> None:
        self.stream_epoch += 1

    def take(self) -> float:
        """The correction asked since the last take (values), and none pending after (writer thread)."""
        if not self._request:
            return 0.0
        with self._lock:
            request, self._request = self._request, 0.0
        return request

    def observe(self, telemetry: p.Telemetry, playing: bool) -> None:
        if (getattr(telemetry, "version", 2) < 3 or telemetry.playback != p.PLAYBACK_PLAYING or not playing
                or self._epoch != self.stream_epoch):
            self._n, self._epoch = 0, self.stream_epoch
            return
        self._depths[self._n] = telemetry.buffered_setpoints
        self._n += 1
        if self._n < DEPTH_WINDOW:
            return
        self._n = 0
        middle = sorted(self._depths)
        pacing = self.pacing
        error = (middle[(DEPTH_WINDOW - 1) // 2] + middle[DEPTH_WINDOW // 2]) / 2.0 - (pacing.lead - pacing.batch / 2.0)
        if abs(error) > DEPTH_DEADBAND_S * pacing.rate_hz:
            with self._lock:
                self._request -= error
            self.worst = max(self.worst, abs(error))


class FaultClearing:
    """Latched fault bits to clear (seen in telemetry, already counted): one CLEAR_FAULTS at a time, sent again
    only if it went unanswered, never again once refused. The reader adds and answers; the writer sends."""

    def __init__(self):
        self.pending = 0
        self.outstanding = False  # a CLEAR_FAULTS is on its way, not yet answered
        self.mask = 0
        self.sent_at = 0.0
        self.refused = False

    def due(self, now: float) -> int:
        """The bits to clear now (writer thread), 0 for none: a CLEAR_FAULTS unanswered for CLEAR_RETRY_S was lost
        on the link and its bits are asked again."""
        if self.outstanding and now - self.sent_at > CLEAR_RETRY_S:
            self.outstanding = False
            self.pending |= self.mask
        if not self.pending or self.outstanding or self.refused:
            return 0
        self.mask, self.pending = self.pending, 0
        self.outstanding, self.sent_at = True, now
        return self.mask


class DriveTally:
    """The commanded amplitude sent since the last telemetry (the resonance tracker's reference): the writer
    adds, the reader takes."""

    def __init__(self, lock: threading.Lock):
        self._lock = lock
        self._sum_um_pp = 0.0
        self._count = 0

    def add(self, total_um_pp: float, count: int) -> None:
        with self._lock:
            self._sum_um_pp += total_um_pp
            self._count += count

    def take(self) -> tuple[float, int]:
        with self._lock:
            taken = self._sum_um_pp, self._count
            self._sum_um_pp, self._count = 0.0, 0
        return taken


class Intake:
    """Every frame from the device, taken on the reader thread: answers to the session, telemetry counted."""

    def __init__(self, session: Session, account: RunAccount, counters: SerialCounters, locks: DriverLocks,
                 pacing: Pacing, tracker, kind_of):
        self.session, self.account, self.counters, self.tracker = session, account, counters, tracker
        self._kind_of = kind_of
        self.depth = DepthTracker(pacing, locks.trim)
        self.clearing = FaultClearing()
        self.drive = DriveTally(locks.drive)
        self.sent = SentHistory(pacing.rate_hz, session.profile.time_constant_s)  # by index, for the follow check
        self._arrived = locks.telemetry
        self.telemetry: p.Telemetry | None = None
        self.frames = 0  # TELEMETRY frames taken over the run
        self.sensors: p.Sensors | None = None  # the last SENSORS frame (v3, a device with sensors)
        self.sensors_frames = 0
        self.sensor_errors = 0
        self._sensor_listeners: tuple = ()
        self._clock_listeners: tuple = ()
        self._next_sample: int | None = None  # the sample number the last SENSORS frame leads to
        self._sensors_read_s = 0.0  # when the last SENSORS frame taken was read (perf_counter s)
        # the CLOCK request awaiting its reply: its seq (None: none outstanding), when it was sent, the sample number
        # the SENSORS read before it lead to, when the last of them was read. The writer sets them (no tuple made on
        # its path): the seq last, after None while it writes the rest; the reader takes them only if the seq is
        # the reply's before and after it reads them.
        self.clock_seq: int | None = None
        self._clock_asked_s = 0.0
        self._clock_sent_end: int | None = None
        self._clock_read_s = 0.0
        self.clock_replies = 0  # CLOCK_REPLY frames taken over the run
        self._may_begin_again = True  # a restarted device's sample count is believed once a connection
        self._clock_dropped_end: int | None = None  # the SENSORS' end a CLOCK_REPLY near 0 was dropped against
        self._fault_last: tuple[int, ...] | None = None  # the device's counters at the last telemetry
        self._frames_ok_last = 0
        self._handshakes_seen = 0  # the session's handshakes at the last telemetry taken
        self.fault_run = [0] * p.FAULT_BITS  # faults over the run
        self._link_last: dict[str, int] = {}
        self.link_run = dict.fromkeys(LINK_COUNTERS, 0)

    @property
    def has_baseline(self) -> bool:
        """The run's first telemetry has come: faults from here on are counted."""
        return self._fault_last is not None

    def frame(self, frame: p.Frame) -> None:
        state = self.session.state
        state.last_heard = time.monotonic()
        try:
            if frame.kind == p.TELEMETRY and state.active:
                telemetry = p.parse_telemetry(frame.payload)
                if state.device is None or self._believed("TELEMETRY", telemetry_out_of_range(telemetry, state.device)):
                    self.take_telemetry(telemetry)
            elif frame.kind == p.SENSORS and state.active:
                sensors = p.parse_sensors(frame.payload)
                expected, self._next_sample = self._next_sample, (sensors.first_sample + len(sensors.samples)) % WRAP
                device = state.device
                if self._began_again(sensors.first_sample, expected, device):
                    expected = None  # the device restarted: its samples are numbered from 0 again
                if device is None or self._believed("SENSORS", sensors_out_of_range(sensors, device, expected)):
                    self._sensors_read_s = time.perf_counter()
                    self._take_sensors(sensors)
            elif frame.kind == p.CLOCK_REPLY and state.active:
                self._take_clock(p.parse_clock_reply(frame.payload), time.perf_counter())
            elif frame.kind == p.HELLO_REPLY:
                self._next_sample = None  # a new connection: its samples are numbered afresh
                self.clock_seq = None
                self._may_begin_again = True
                self._clock_dropped_end = None
                self.session.replies.hello_arrived(frame.payload)
            elif frame.kind == p.ACK:
                seq = p.parse_ack(frame.payload)
                if self._kind_of(seq) == p.CLEAR_FAULTS:
                    self.clearing.outstanding = False
                self.session.replies.answer(seq, None)
            elif frame.kind == p.NAK:
                seq, reason = p.parse_nak(frame.payload)
                self.counters.naks += 1
                kind = self._kind_of(seq)
                if kind == p.CLEAR_FAULTS:
                    self.clearing.outstanding = False
                    self.clearing.refused = True
                self.account.refused(kind, reason)
                self.session.replies.answer(seq, reason)
        except p.ProtocolError:
            self.counters.bad_frames += 1

    def _began_again(self, first_sample: int, expected: int | None, device: p.HelloReply | None) -> bool:
        """Whether a SENSORS frame's sample count began again, once in a connection: a device that restarted
        numbers its samples from 0 (and its telemetry, 20 ms apart, may say so only after). A count back to within
        a second of samples from 0 is taken so once; again in the same connection, it is a value that cannot be."""
        if expected is None or device is None or not device.sensor_rate_hz or not self._may_begin_again:
            return False
        second = device.sensor_rate_hz * SAMPLE_GAP_S
        if first_sample <= second < (first_sample - expected) % WRAP:
            self._may_begin_again = False
            return True
        return False

    def _clock_began_again(self, reply: p.ClockReply, device: p.HelloReply | None, sent_end: int | None) -> bool:
        """Whether a CLOCK_REPLY is dropped (not a fault) as a restarted device's: a board that restarts without a
        new HELLO answers at once from a clock near 0, while the request carried the SENSORS' end from before the
        restart. While SENSORS may still begin again once (:meth:`_began_again`), a reply within a second of
        samples from 0 and behind that end is dropped; again only against the same end (no SENSORS frame read in
        between: one that was either began again, or leaves the next such reply a value that cannot be)."""
        if sent_end is None or device is None or not device.sensor_rate_hz or not self._may_begin_again \
                or self._clock_dropped_end not in (None, sent_end):
            return False
        if reply.sample <= device.sensor_rate_hz * SAMPLE_GAP_S < (reply.sample - sent_end) % WRAP:
            self._clock_dropped_end = sent_end
            return True
        return False

    def _believed(self, kind: str, impossible: list[tuple[str, str]]) -> bool:
        """Whether a frame can be believed; if not, it is a device fault, counted and said in the run's report."""
        if impossible:
            self.account.field_check.add(kind, impossible, self.account.now_s())
        return not impossible

    def add_sensor_listener(self, listener) -> None:
        self._sensor_listeners = (*self._sensor_listeners, listener)

    def add_clock_listener(self, listener) -> None:
        self._clock_listeners = (*self._clock_listeners, listener)

    @property
    def wants_clock(self) -> bool:
        """Someone listens for the device's clock."""
        return bool(self._clock_listeners)

    def asking_clock(self, seq: int, asked_s: float) -> None:
        """A CLOCK request with ``seq`` is about to be written at ``asked_s`` (perf_counter s; the writer thread):
        its reply is awaited. No tuple or float made: the writer's path."""
        self.clock_seq = None  # a reply read while the rest are written is not taken
        self._clock_asked_s = asked_s
        self._clock_sent_end = self._next_sample
        self._clock_read_s = self._sensors_read_s
        self.clock_seq = seq

    def _take_clock(self, reply: p.ClockReply, received_s: float) -> None:
        """A CLOCK_REPLY: believed against the SENSORS read before it was asked, it goes to the clock listeners as
        ``listener(samples, asked_s, received_s)``: the device's sensor clock (samples, not unwrapped) when it took
        a request sent at ``asked_s`` and answered by ``received_s`` (perf_counter s)."""
        seq, device = self.clock_seq, self.session.state.device
        if seq is None or seq != reply.asked_seq:
            return  # not the request awaited (a late reply to one given up on): its sending time is not known
        asked_s, sent_end, read_s = self._clock_asked_s, self._clock_sent_end, self._clock_read_s
        if self.clock_seq != seq:
            return  # the writer gave it up and asks anew meanwhile: what was read may be the new request's
        self.clock_seq = None
        if self._clock_began_again(reply, device, sent_end):
            return  # the device restarted: not a value that cannot be, nor its clock against SENSORS read since
        if device is not None and not self._believed(
                "CLOCK_REPLY", clock_reply_out_of_range(reply, device, sent_end, received_s - read_s)):
            return
        self.clock_replies += 1
        for listener in self._clock_listeners:
            try:
                listener(reply.samples, asked_s, received_s)
            except Exception:  # noqa: BLE001 - the link goes on; the listener goes
                self.sensor_errors += 1
                self._clock_listeners = tuple(other for other in self._clock_listeners if other is not listener)

    def _take_sensors(self, sensors: p.Sensors) -> None:
        self.sensors = sensors
        self.sensors_frames += 1
        for listener in self._sensor_listeners:
            try:
                listener(sensors)
            except Exception:  # noqa: BLE001 - the link goes on; the listener goes
                self.sensor_errors += 1
                self._sensor_listeners = tuple(other for other in self._sensor_listeners if other is not listener)

    def next(self, timeout_s: float) -> p.Telemetry | None:
        """The next TELEMETRY frame, or None if none comes within ``timeout_s``."""
        with self._arrived:
            seen = self.frames
            if not self._arrived.wait_for(lambda: self.frames > seen, timeout_s):
                return None
            return self.telemetry

    def take_telemetry(self, telemetry: p.Telemetry) -> None:
        """Add the faults since the previous telemetry to the run's counts (counters wrap at 2**32)."""
        state = self.session.state
        counts = telemetry.fault_counts
        previous = self._fault_last
        restarted = self._restarted(telemetry, previous)
        if restarted and state.handshakes != self._handshakes_seen:  # connected anew since its last telemetry:
            self.session.restarted_mid_run(state.device)  # the handshake came after the restart and says why
        elif restarted:
            state.restarted = True  # the writer connects anew: a restarted device's session began again, and its
            # handshake says why (devices/serial/session.py)
        self._handshakes_seen = state.handshakes
        check = self.account.counter_check  # u32 counters believed only as far as they can be true
        if previous is None:
            new_bits = telemetry.faults  # latched before this run: cleared once, not counted
        else:
            new = check.steps(FAULT_COUNTER_NAMES, counts, previous, restarted, self.account.now_s())
            self.fault_run = [run + n for run, n in zip(self.fault_run, new, strict=True)]
            new_bits = sum(1 << bit for bit, n in enumerate(new) if n)
            if new_bits:
                self.account.faults_seen(new_bits)
                if any(new_bits & bit for bit in CUT_FAULTS):
                    state.cut = True
        self._add_link_counters(telemetry, restarted)
        self.depth.observe(telemetry, state.output_on and not state.cut)
        if (state.output_on and not state.cut and not telemetry.enabled
                and time.perf_counter() - state.enabled_at > REENABLE_AFTER_S):
            state.reenable = True
        self._fault_last = counts
        self._frames_ok_last = telemetry.frames_ok
        # latched bits raised since the last look: cleared once each (a bit whose condition persists, set again at
        # once without a new raise, is not asked for again)
        self.clearing.pending |= new_bits & telemetry.faults
        with self._arrived:
            self.telemetry = telemetry
            self.frames += 1
            self._arrived.notify_all()
        total, count = self.drive.take()
        self.account.follow.observe(total, count, telemetry.measured_um_pp, self._judged(telemetry),
                                    self.account.now_s(), self._expected(telemetry))
        self.account.carrier_follow.observe(self.session.carrier_hz, telemetry.carrier_hz,
                                            state.output_on and not state.cut and bool(telemetry.enabled),
                                            self.account.now_s())
        if self.tracker is not None:
            if previous is None or any(counts[bit.bit_length() - 1] != previous[bit.bit_length() - 1]
                                       for bit in TRACKING_DISTURBANCES):
                self.tracker.disturbed(time.perf_counter())
            elif count:
                self.tracker.observe(telemetry.carrier_hz, telemetry.measured_um_pp, total / count, time.perf_counter())
        if state.first_telemetry is not None:
            state.first_telemetry.set()

    def _expected(self, telemetry: p.Telemetry) -> tuple[float, float] | None:
        """The lowest and highest a plate that follows may read at this frame's reading (µm p-p,
        serial/follow.SentHistory): at the index playing as the frame was made, the one before the values it
        buffers (under the amplitude loop, down or up to the values); None without a v3 stream."""
        if telemetry.version < 3 or not telemetry.stream_rate_hz or not telemetry.expected_index:
            return None
        return self.sent.expected_at_device(telemetry.expected_index - telemetry.buffered_setpoints - 1,
                                            telemetry.loop == p.LOOP_AMPLITUDE)

    def _judged(self, telemetry: p.Telemetry) -> bool:
        """Whether this frame's amplitude is judged against what was sent (serial/follow.py): the output on and
        playing, on a device that measures its amplitude (v3: it says so; v2: it once reported one above 0), and
        no resonance being tracked (the tracker moves the carrier about a drifting resonance: off it, a plate rightly
        plays less than it is sent)."""
        state, device = self.session.state, self.session.state.device
        self._amplitude_seen = getattr(self, "_amplitude_seen", False) or telemetry.measured_um_pp > 0.0
        sensed = bool(device.sensors & p.SENSOR_AMPLITUDE) if device is not None and device.version >= 3 else \
            self._amplitude_seen
        playing = telemetry.version < 3 or telemetry.playback == p.PLAYBACK_PLAYING
        return (sensed and playing and state.output_on and not state.cut and telemetry.enabled
                and self.tracker is None)

    def _add_link_counters(self, telemetry: p.Telemetry, restarted: bool) -> None:
        for name in LINK_COUNTERS:
            now = getattr(telemetry, name, 0)
            before = self._link_last.get(name)
            if before is not None:
                self.link_run[name] += self.account.counter_check.steps((name,), (now,), (before,), restarted,
                                                                        self.account.now_s())[0]
            self._link_last[name] = now

    def _restarted(self, telemetry: p.Telemetry, previous) -> bool:
        """Whether the device restarted since its last telemetry: its ``frames_ok`` fell, to no more than the frames
        sent since (a fall to more is no restart: its counters are then checked as they are, and found false)."""
        sent = self.counters.frames_sent
        since, self._frames_sent_last = sent - getattr(self, "_frames_sent_last", sent), sent
        return (previous is not None and telemetry.frames_ok < self._frames_ok_last
                and plausible_restart(telemetry.frames_ok, since))

    def fault_counts(self) -> dict[str, int]:
        """Each fault the device can report, by name, with how often it happened over this run."""
        return {name: self.fault_run[bit.bit_length() - 1] for bit, name in p.FAULT_NAMES.items()}
