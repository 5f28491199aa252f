"""The plate driver's writer thread: setpoints at the plate's clock, the lead, rest and wake, stalls,
heartbeats and fault clearing."""

from __future__ import annotations

import math
import time

import numpy as np
import serial
import serial.threaded
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.serial.link import (
    BACKOFF_S,
    CLEAR_RETRY_S,
    IDLE_AFTER_S,
    STALL_S,
    ZERO_FRACTION,
    port_failure,
)


def skipped(source, n: int) -> None:
    """Tell a source that counts the stream's values (``OutputStage.skip``) that ``n`` indices went by unpulled,
    so what it numbers (a record's rows, the friction loop's targets) stays the wire's index."""
    skip = getattr(source, "skip", None)
    if skip is not None:
        skip(n)


class StreamWriter:
    """The writer thread that streams setpoints: a part of :class:`~ultraglide.devices.serial.plate.SerialPlate`."""

    def _run(self) -> None:
        source = self._source
        rate = self.rate_hz
        batch, lead = self._batch, self.lead
        started = time.perf_counter()
        position = 0  # values taken from the source; value k plays at started + k / rate
        planned = None  # when the writer meant to wake from its last sleep
        attempt = 0
        retry_at = 0.0
        wake = np.empty(lead + 4 * batch)
        dry_s = self.buffer_lasts_s
        trim = 0  # values the lead moved by: how far the plate's playback lags the host's clock (v3 telemetry)
        heartbeat_s = self._watchdog_s() / 4.0
        trim_range = (-int(self._buffer_ms() * rate / 1000), int(0.1 * rate))
        last_sent = None
        quiet_since = None  # when the run of all-zero setpoints began (perf_counter s)
        try:
            while not self._stop.is_set():
                now = time.perf_counter()
                if planned is not None and now - planned > STALL_S:  # it overslept: this process did not run
                    self._host_stalled(now - planned, now)  # (not a write that blocked: that is the link's)
                planned = None
                if self._trim_request:  # the plate's buffer drifted from its depth: move the lead
                    with self._trim_lock:
                        request, self._trim_request = self._trim_request, 0.0
                    trim = int(min(max(trim + request, trim_range[0]), trim_range[1]))
                    self.counters.depth_corrections += 1
                connected = self._connected.is_set()
                streaming = connected and self._output_on and not self._cut
                ahead = lead + trim if streaming else 0
                due = int((now - started) * rate) + ahead - position
                if due < batch:
                    planned = min(started + (position + batch - ahead) / rate, now + heartbeat_s)
                    if streaming and now - self._sent_at > heartbeat_s:  # a long wait (the lead moved back): keep
                        self._heartbeat()  # the plate's watchdog fed
                    time.sleep(max(0.0, planned - now))
                    continue
                skip = 0
                if streaming and due > ahead + lead + 2 * batch:  # the plate ran dry (the host stalled): skip
                    skip, due = due - ahead, lead  # ahead rather than send a backlog; the plate starts again when
                    trim = 0  # the lead arrives, its playback aligned with the host's clock anew
                    self._stream_epoch += 1
                    self.counters.setpoints_skipped += skip
                elif not streaming and due > 4 * batch:
                    skip, due = due - batch, batch
                if skip:
                    position += skip
                    self._index += skip
                    skipped(source, skip)
                    self.counters.late_batches += 1
                # when the first of them plays: on the host's clock, less the plate's lag behind it that the
                # lead was moved for (its buffer back at its depth, value k plays at started + (k - trim) / rate)
                values = source.pull(due, started + (position - (trim if streaming else 0)) / rate)
                resting = connected and not self._output_on and not self._cut
                if resting and float(values.max()) > ZERO_FRACTION * self.full_scale_um_pp:  # the drive leaves zero:
                    wake[:due] = values  # the lead goes at once, so the plate plays on arrival with its buffer full
                    wake[due:due + lead] = source.pull(lead, started + (position + due) / rate)
                    values, due = wake[:due + lead], due + lead
                    trim = 0  # a new stream: the plate's playback starts with this frame
                    self._stream_epoch += 1
                position += due
                if connected and time.monotonic() - self._last_heard > self.silence_s:
                    self.counters.silences += 1
                    self._disconnect()
                    self.counters.disconnects += 1
                    self._outage(f"no telemetry for {self.silence_s:g} s")
                    connected = False
                if not connected:
                    last_sent = None
                    self.counters.setpoints_discarded += due
                    self._index += due
                    if time.monotonic() >= retry_at:
                        self._disconnect()
                        try:
                            self._connect()
                            back = True
                        except DeviceError as error:
                            retry_at = time.monotonic() + BACKOFF_S[min(attempt, len(BACKOFF_S) - 1)]
                            attempt += 1
                            self._retry_failed(str(error))
                            back = False
                        behind = int((time.perf_counter() - started) * rate) - position  # the handshake's time
                        if behind > 0:  # the renderer's clock jumps with the next pull
                            position += behind
                            self._index += behind
                            skipped(source, behind)
                            self.counters.setpoints_discarded += behind
                        if back:
                            self.counters.reconnects += 1
                            self._back()
                            attempt = 0
                            trim = 0
                            self._stream_epoch += 1
                    continue
                fractions = np.divide(values, self.full_scale_um_pp, out=self._fractions[:due])
                np.minimum(fractions, self._top_fraction, out=fractions)  # no code rounds above the drive ceiling
                if float(fractions.max()) > ZERO_FRACTION:
                    quiet_since = None
                elif quiet_since is None:
                    quiet_since = now
                idle = quiet_since is not None and now - quiet_since >= IDLE_AFTER_S
                stream = not self._cut and (self._output_on or not idle)
                if self.tracker is not None and stream:
                    played = float(np.clip(fractions, 0.0, 1.0, out=self._clipped[:due]).sum()) * self.full_scale_um_pp
                    with self._drive_lock:
                        self._drive_sum_um_pp += played
                        self._drive_count += len(fractions)
                try:
                    if self.tracker is not None:
                        self._follow_tracker()
                    self._clear_faults(now)
                    if not stream:  # idle or cut: nothing sent, the index runs on (the next ENABLE starts a new stream)
                        self._index += due
                        last_sent = None
                    else:
                        if not self._output_on:  # the drive left zero: enable, unacknowledged,
                            self._send(p.ENABLE, p.enable_payload(True))  # and stream at once (frames keep order)
                            self._output_on, self._enabled_at = True, time.perf_counter()
                            self.counters.idle_wakes += 1
                        elif self._reenable:  # the plate is off while this side streams (an ENABLE lost): again
                            self._send(p.ENABLE, p.enable_payload(True))
                            self._enabled_at = time.perf_counter()
                            self.counters.reenables += 1
                            if self.counters.reenables == 1:
                                self._reenabled_first_s = self._now_s()
                        self._reenable = False
                        self._send_setpoints(fractions)
                        sent_at = time.perf_counter()
                        if last_sent is not None and sent_at - last_sent > dry_s:  # the plate may have run dry
                            self._late_frame(sent_at - last_sent)
                        last_sent = sent_at
                        if idle and self._output_on:  # zeros long enough, the last of them sent: rest the output
                            self._send(p.ENABLE, p.enable_payload(False))
                            self._output_on = False
                            self.counters.idle_rests += 1
                            last_sent = None
                except (serial.SerialException, OSError) as error:
                    self._lost(port_failure(error))
                    retry_at = time.monotonic() + BACKOFF_S[0]
                    last_sent = None
                if source.finished:
                    break
        except Exception as error:  # the source failed: rest the plate, then report
            self.counters.errors.append(f"{type(error).__name__}: {error}")
            with self._account_lock:
                self._writer_failure = (self._now_s(), f"{type(error).__name__}: {error}")
        finally:
            self._rest()

    def _clear_faults(self, now: float) -> None:
        """Clear the latched bits seen in telemetry (already counted): one CLEAR_FAULTS at a time, sent again only
        if it went unanswered (lost on the link), never again once refused."""
        if self._clear_outstanding and now - self._clear_sent_at > CLEAR_RETRY_S:
            self._clear_outstanding = False
            self._clear_pending |= self._clear_mask
        if self._clear_pending and not self._clear_outstanding and not self._clear_refused:
            self._clear_mask, self._clear_pending = self._clear_pending, 0
            self._clear_outstanding, self._clear_sent_at = True, now
            self._send(p.CLEAR_FAULTS, p.clear_faults_payload(self._clear_mask))

    def _host_stalled(self, stalled_s: float, now: float) -> None:
        """The writer woke ``stalled_s`` late: the host did not run. Its silence check starts again (what the
        device sent meanwhile is still unread), and the stall is kept for the report."""
        self._last_heard = max(self._last_heard, time.monotonic())
        self.counters.host_stalls += 1
        with self._account_lock:
            if stalled_s > self._stall_longest[0]:
                self._stall_longest = (stalled_s, now - self._started)

    def _heartbeat(self) -> None:
        try:
            self._send(p.HEARTBEAT)
        except (serial.SerialException, OSError) as error:
            self._lost(port_failure(error))

    def _watchdog_s(self) -> float:
        return (self.device.watchdog_ms if self.device is not None else p.WATCHDOG_MS) / 1000.0

    def _buffer_ms(self) -> float:
        return float(self.device.buffer_ms if self.device is not None else p.BUFFER_MS)

    def _late_frame(self, gap_s: float) -> None:
        """A frame went out ``gap_s`` after the one before, longer than the plate's buffer lasts."""
        self.counters.late_frames += 1
        if gap_s > self.device.watchdog_ms / 1000.0:
            self.counters.send_stalls += 1
        with self._account_lock:
            self._late_longest = max(self._late_longest, (gap_s, self._now_s()))

    def _retry_failed(self, error: str) -> None:
        if len(self.counters.errors) < 20:
            self.counters.errors.append(error)
        with self._account_lock:
            if self._outages and self._outages[-1].back_s is None:
                self._outages[-1].last_error = error.split("; ")[0]  # without the advice

    def _force_reference(self) -> p.ForceReference | None:
        """What SETPOINTS_FORCE carries for the values just pulled: the force the source's friction loop computed
        them at and its model's exponent there, with the host's limit; None (plain SETPOINTS) while the loop does
        not follow, or for a device without the force correction."""
        device = self.device
        if device is None or not device.has_force_correction:
            return None
        reference = getattr(self._source, "force_reference", None)
        if reference is None:
            return None
        limit = math.floor(self.limit_um_pp / self.full_scale_um_pp * p.SETPOINT_SCALE) / p.SETPOINT_SCALE
        return p.ForceReference(reference[0], reference[1], limit)

    def _send_setpoints(self, fractions: np.ndarray) -> None:
        """Send values (fractions of full scale) in frames of at most 240, continuing the stream's index."""
        force = self._force_reference()
        for start in range(0, len(fractions), p.MAX_SETPOINTS_PER_FRAME):  # at most 480 bytes of values a frame
            chunk = fractions[start:start + p.MAX_SETPOINTS_PER_FRAME]
            self._send(p.SETPOINTS, setpoints=chunk, force=force)
            self._index += len(chunk)
            self.counters.setpoints_sent += len(chunk)
