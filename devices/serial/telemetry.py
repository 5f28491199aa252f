"""What the plate driver takes in from the link: telemetry, SENSORS, acknowledgements and refusals, the
plate's buffer depth, faults and counters."""

from __future__ import annotations

import time

from ultraglide.devices import protocol as p
from ultraglide.devices.serial.link import (  # noqa: F401 - IDLE_AFTER_S, open_port: the driver's names
    COMMAND_NAMES,
    CUT_FAULTS,
    DEPTH_DEADBAND_S,
    DEPTH_WINDOW,
    IDLE_AFTER_S,
    LINK_COUNTERS,
    MAX_OUTAGES,
    REENABLE_AFTER_S,
    REST_ACK_S,
    SILENCE_S,
    TRACKING_DISTURBANCES,
    FrameReader,
    Outage,
    SerialCounters,
    check_link_budget,
    open_port,
)


class TelemetryIntake:
    """What comes back from the plate: a part of :class:`~ultraglide.devices.serial.plate.SerialPlate`."""

    def _frame(self, frame: p.Frame) -> None:
        self._last_heard = time.monotonic()
        try:
            if frame.kind == p.TELEMETRY and self._session:
                self._take_telemetry(p.parse_telemetry(frame.payload))
            elif frame.kind == p.SENSORS and self._session:
                self._take_sensors(p.parse_sensors(frame.payload))
            elif frame.kind == p.HELLO_REPLY:
                with self._reply:
                    self._hello = frame.payload
                    self._reply.notify_all()
            elif frame.kind == p.ACK:
                seq = p.parse_ack(frame.payload)
                if self._sent_kinds[seq] == p.CLEAR_FAULTS:
                    self._clear_outstanding = False
                self._answer(seq, None)
            elif frame.kind == p.NAK:
                seq, reason = p.parse_nak(frame.payload)
                self.counters.naks += 1
                if self._sent_kinds[seq] == p.CLEAR_FAULTS:
                    self._clear_outstanding = False
                self._refused(seq, reason)
                self._answer(seq, reason)
        except p.ProtocolError:
            self.counters.bad_frames += 1

    def add_sensor_listener(self, listener) -> None:
        """Call ``listener(sensors)`` with each SENSORS frame (a :class:`protocol.Sensors`), on the reader thread:
        it must return quickly. A listener that raises is counted (``sensor_errors``) and left out from then on."""
        self._sensor_listeners = (*self._sensor_listeners, listener)

    def _take_sensors(self, sensors: p.Sensors) -> None:
        self.sensors = sensors
        self.sensors_frames += 1
        for listener in self._sensor_listeners:
            try:
                listener(sensors)
            except Exception:  # noqa: BLE001 - the link goes on; the listener goes
                self.sensor_errors += 1
                self._sensor_listeners = tuple(other for other in self._sensor_listeners if other is not listener)

    def _answer(self, seq: int, reason: int | None) -> None:
        with self._reply:
            if seq in self._awaiting:
                self._answers[seq] = reason
                self._reply.notify_all()

    def _refused(self, seq: int, reason: int) -> None:
        """A NAK: counted by what it refused and why (a refused CLEAR_FAULTS is not asked again)."""
        kind = self._sent_kinds[seq]
        command = COMMAND_NAMES.get(kind, f"command {kind:#04x}")
        if kind == p.CLEAR_FAULTS:
            self._clear_refused = True
        words = p.NAK_REASONS.get(reason, f"reason {reason}")
        with self._account_lock:
            entry = self._refusals.setdefault((command, words), [0, self._now_s()])
            entry[0] += 1

    def _bad_frames_received(self, count: int, crc_errors: int, framing_errors: int) -> None:
        self.counters.bad_frames += count
        with self._account_lock:
            if self._bad_received[2] is None:
                self._bad_received[2] = self._now_s()
            self._bad_received[0], self._bad_received[1] = crc_errors, framing_errors

    def _take_telemetry(self, telemetry: p.Telemetry) -> None:
        """Add the faults since the previous telemetry to the run's counts (counters wrap at 2**32)."""
        counts = telemetry.fault_counts
        previous = self._fault_last
        restarted = previous is not None and telemetry.frames_ok < self._frames_ok_last
        if previous is None:
            new_bits = telemetry.faults  # latched before this run: cleared once, not counted
        else:
            new = counts if restarted else [(now - before) & 0xFFFFFFFF
                                            for now, before in zip(counts, previous, strict=True)]
            self._fault_run = [run + n for run, n in zip(self._fault_run, new, strict=True)]
            new_bits = sum(1 << bit for bit, n in enumerate(new) if n)
            if new_bits:
                self._note_faults(new_bits)
        self._add_link_counters(telemetry, restarted)
        self._track_depth(telemetry)
        if (self._output_on and not self._cut and not telemetry.enabled
                and time.perf_counter() - self._enabled_at > REENABLE_AFTER_S):
            self._reenable = True
        self._fault_last = counts
        self._frames_ok_last = telemetry.frames_ok
        # latched bits raised since the last look: cleared once each (a bit whose condition persists, set again at
        # once without a new raise, is not asked for again)
        self._clear_pending |= new_bits & telemetry.faults
        with self._telemetry_arrived:
            self.telemetry = telemetry
            self.telemetry_frames += 1
            self._telemetry_arrived.notify_all()
        if self.tracker is not None:
            with self._drive_lock:
                total, count = self._drive_sum_um_pp, self._drive_count
                self._drive_sum_um_pp, self._drive_count = 0.0, 0
            if previous is None or any(counts[bit.bit_length() - 1] != previous[bit.bit_length() - 1]
                                       for bit in TRACKING_DISTURBANCES):
                self.tracker.disturbed(time.perf_counter())
            elif count:
                self.tracker.observe(telemetry.carrier_hz, telemetry.measured_um_pp, total / count, time.perf_counter())
        if self._first_telemetry is not None:
            self._first_telemetry.set()

    def _track_depth(self, telemetry: p.Telemetry) -> None:
        """v3 telemetry says how many values wait in the plate's buffer. Over DEPTH_WINDOW frames while it plays,
        a median depth off its target by more than the deadband (the plate's clock drifting from the host's, its
        playback restarted later than the host's clock) asks the writer to move its lead by the difference: the
        buffer, and the latency it costs, come back to the prefill and a frame. The median, not the mean: a
        few frames made while the plate caught up a stall of its own, or read a backlog late, report a
        buffer that is deep only for that moment; moving the lead for them would starve the plate after."""
        if (getattr(telemetry, "version", 2) < 3 or telemetry.playback != p.PLAYBACK_PLAYING or not self._output_on
                or self._cut or self._depth_epoch != self._stream_epoch):
            self._depth_n, self._depth_epoch = 0, self._stream_epoch
            return
        self._depths[self._depth_n] = telemetry.buffered_setpoints
        self._depth_n += 1
        if self._depth_n < DEPTH_WINDOW:
            return
        self._depth_n = 0
        middle = sorted(self._depths)
        error = (middle[(DEPTH_WINDOW - 1) // 2] + middle[DEPTH_WINDOW // 2]) / 2.0 - (self.lead - self._batch / 2.0)
        if abs(error) > DEPTH_DEADBAND_S * self.rate_hz:
            with self._trim_lock:
                self._trim_request -= error
            self._depth_worst = max(self._depth_worst, abs(error))

    def _note_faults(self, bits: int) -> None:
        """Faults newly counted: the first time of each, and the cut (trip, overheat) that ends streaming."""
        now = self._now_s()
        with self._account_lock:
            for bit, name in p.FAULT_NAMES.items():
                if bits & bit:
                    self._fault_first_s.setdefault(name, now)
            for bit in CUT_FAULTS:
                if bits & bit and self._cut_at is None:
                    self._cut_at = (now, p.FAULT_NAMES[bit])
        if any(bits & bit for bit in CUT_FAULTS):
            self._cut = True

    def _add_link_counters(self, telemetry: p.Telemetry, restarted: bool) -> None:
        for name in LINK_COUNTERS:
            now = getattr(telemetry, name, 0)
            before = self._link_last.get(name)
            if before is not None:
                self._link_run[name] += now if restarted else (now - before) & 0xFFFFFFFF
            self._link_last[name] = now
