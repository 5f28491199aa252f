"""The plate driver's streamer: the real-time writer thread that sends setpoints at the plate's clock.

Sample k of the stream plays at ``started + k / rate``; the writer keeps ``lead`` values sent ahead of its clock
(moved by the depth tracker's corrections), skips ahead after a stall of the host rather than sending a backlog,
sends a wake's whole lead at once, rests the output (ENABLE 0) after a run of zeros and enables it again when
the drive leaves zero, keeps the plate's watchdog fed while it waits, and reconnects when the link is lost.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
import serial
from ultraglide.devices import protocol as p
from ultraglide.devices.serial.link import (
    CLOCK_EVERY_S,
    CLOCK_GIVE_UP_S,
    IDLE_AFTER_S,
    STALL_S,
    ZERO_FRACTION,
    Pacing,
    SerialCounters,
    port_failure,
)
from ultraglide.devices.serial.report import RunAccount
from ultraglide.devices.serial.session import Session
from ultraglide.devices.serial.telemetry import Intake
from ultraglide.devices.serial.transport import Transport


def skipped(source, n: int) -> None:
    """Tell a source that counts the stream's values (``OutputStage.skip``) that ``n`` indices went by unpulled,
    so what it numbers (a record's rows, the friction loop's targets) stays the wire's index."""
    skip = getattr(source, "skip", None)
    if skip is not None:
        skip(n)


class Streamer:
    """The writer thread (:meth:`run`) and the state only it touches: where the stream is, and its lead."""

    def __init__(self, session: Session, transport: Transport, intake: Intake, account: RunAccount,
                 counters: SerialCounters, pacing: Pacing, silence_s: float, lost: Callable[[str], None],
                 tracker=None):
        self.session, self.transport, self.intake, self.account = session, transport, intake, account
        self.counters, self.pacing, self.silence_s, self.tracker = counters, pacing, silence_s, tracker
        self._lost = lost
        self.stop = threading.Event()
        self.source = None
        rate, lead, batch = pacing.rate_hz, pacing.lead, pacing.batch
        self._fractions = np.empty(rate)  # a batch as fractions of full scale (up to 1 s)
        self._clipped = np.empty(rate)
        self._wake = np.empty(lead + 4 * batch)
        self._dry_s = pacing.buffer_lasts_s
        self._started = 0.0
        self._position = 0  # values taken from the source; value k plays at started + k / rate
        self._planned: float | None = None  # when the writer meant to wake from its last sleep
        self._ran_at = 0.0  # the writer's last look at the clock (perf_counter s), to see the host's stalls
        self._waited_s = 0.0  # the transport's waits for room on the port at that look (the link's time), s
        self._trim = 0  # values the lead moved by: how far the plate's playback lags the host's clock (v3 telemetry)
        self._last_sent: float | None = None
        self._quiet_since: float | None = None  # when the run of all-zero setpoints began (perf_counter s)
        self._clock_asked_s = 0.0  # when the last CLOCK request was sent (perf_counter s: the transport's sent_at)
        self._expect_clock = self._asking_clock  # bound once: none made a request

    def run(self, source, rest: Callable[[], None]) -> None:
        """Stream ``source`` until stopped or finished; ``rest`` the plate on the way out, whatever happened."""
        self.source = source
        self._started = self._ran_at = time.perf_counter()
        self._waited_s = self.transport.waited_s
        state = self.session.state  # its silence check starts with it: a stall between the handshake and this
        state.last_heard = max(state.last_heard, time.monotonic())  # thread's start is none of the device's
        try:
            while not self.stop.is_set() and not self._turn():
                pass
        except Exception as error:  # the source failed: rest the plate, then report
            self.counters.errors.append(f"{type(error).__name__}: {error}")
            self.account.writer_failed(f"{type(error).__name__}: {error}")
        finally:
            rest()

    # ---- one turn of the loop -------------------------------------------------------------------
    def _turn(self) -> bool:
        """Send what is due (or wait for it); True once the source has finished."""
        pacing, state, source = self.pacing, self.session.state, self.source
        now = time.perf_counter()
        if self._planned is not None:  # it slept: it woke this late
            self._ran(now, self._planned)
        else:  # it went on from its last look (before the last turn's writes)
            self._ran(now, self._ran_at)
        self._planned = None
        request = self.intake.depth.take()
        if request:  # the plate's buffer drifted from its depth: move the lead
            low, high = -int(self.session.buffer_ms * pacing.rate_hz / 1000), int(0.1 * pacing.rate_hz)
            self._trim = int(min(max(self._trim + request, low), high))
            self.counters.depth_corrections += 1
        connected = state.connected.is_set()
        streaming = connected and state.output_on and not state.cut
        ahead = pacing.lead + self._trim if streaming else 0
        due = int((now - self._started) * pacing.rate_hz) + ahead - self._position
        if due < pacing.batch:
            self._wait(now, ahead, streaming)
            return False
        due = self._skip_behind(due, ahead, streaming)
        # when the first of them plays: on the host's clock, less the plate's lag behind it that the lead was
        # moved for (its buffer back at its depth, value k plays at started + (k - trim) / rate)
        values = source.pull(due, self._started + (self._position - (self._trim if streaming else 0)) / pacing.rate_hz)
        resting = connected and not state.output_on and not state.cut
        if resting and float(values.max()) > ZERO_FRACTION * self.session.limits.full_scale_um_pp:
            values, due = self._wake_values(values, due)  # the drive leaves zero
        self._position += due
        self._ran(time.perf_counter(), now)  # (the pull's time: the host's)
        if connected and time.monotonic() - state.last_heard > self.silence_s:
            self.counters.silences += 1
            self.session.disconnect()
            self.counters.disconnects += 1
            self.account.outage(f"no telemetry for {self.silence_s:g} s", self.counters.setpoints_discarded)
            connected = False
        elif connected and state.restarted:  # its counters began again: connect anew, to hear why in its handshake
            self.session.disconnect()
            self.counters.disconnects += 1
            self.account.outage("the plate driver restarted (its counters began again)",
                                self.counters.setpoints_discarded)
            state.why_restarted, connected = True, False
        state.restarted = False
        if not connected:
            self._offline(due)
            self._ran_at, self._waited_s = time.perf_counter(), self.transport.waited_s  # (a handshake's waits:
            return False  # the link's, not looked at)
        self._send_batch(values, due, now)
        return source.finished

    def _wait(self, now: float, ahead: int, streaming: bool) -> None:
        pacing = self.pacing
        heartbeat_s = self.session.watchdog_s / 4.0
        self._planned = min(self._started + (self._position + pacing.batch - ahead) / pacing.rate_hz, now + heartbeat_s)
        if streaming and now - self.transport.sent_at > heartbeat_s:  # a long wait (the lead moved back): keep
            self._heartbeat()  # the plate's watchdog fed
        time.sleep(max(0.0, self._planned - now))

    def _skip_behind(self, due: int, ahead: int, streaming: bool) -> int:
        """After the plate ran dry (the host stalled), skip ahead rather than send a backlog; the plate starts again
        when the lead arrives, its playback aligned with the host's clock anew. Returns what is due now."""
        lead, batch = self.pacing.lead, self.pacing.batch
        skip = 0
        if streaming and due > ahead + lead + 2 * batch:
            skip, due = due - ahead, lead
            self._trim = 0
            self.intake.depth.new_stream()
            self.counters.setpoints_skipped += skip
        elif not streaming and due > 4 * batch:
            skip, due = due - batch, batch
        if skip:
            self._position += skip
            self.transport.skip(skip)
            skipped(self.source, skip)
            self.counters.late_batches += 1
        return due

    def _wake_values(self, values: np.ndarray, due: int) -> tuple[np.ndarray, int]:
        """The lead goes at once with the values due, so the plate plays on arrival with its buffer full."""
        lead, wake = self.pacing.lead, self._wake
        wake[:due] = values
        wake[due:due + lead] = self.source.pull(lead, self._started + (self._position + due) / self.pacing.rate_hz)
        self._trim = 0  # a new stream: the plate's playback starts with this frame
        self.intake.depth.new_stream()
        return wake[:due + lead], due + lead

    def _offline(self, due: int) -> None:
        """The link is down: the values due are discarded (the renderer keeps its clock); the session reconnects
        when its backoff allows, and the stream takes up the host's clock after the handshake's time."""
        self._last_sent = None
        self.counters.setpoints_discarded += due
        self.transport.skip(due)
        back = self.session.reconnect()
        if back is None:  # not yet: backing off
            return
        behind = int((time.perf_counter() - self._started) * self.pacing.rate_hz) - self._position  # the handshake
        if behind > 0:  # the renderer's clock jumps with the next pull
            self._position += behind
            self.transport.skip(behind)
            skipped(self.source, behind)
            self.counters.setpoints_discarded += behind
        if back:
            self.counters.reconnects += 1
            self.account.back(self.counters.setpoints_discarded)
            self._trim = 0
            self.intake.depth.new_stream()

    def _send_batch(self, values: np.ndarray, due: int, now: float) -> None:
        state, limits = self.session.state, self.session.limits
        fractions = np.divide(values, limits.full_scale_um_pp, out=self._fractions[:due])
        np.minimum(fractions, limits.top_fraction, out=fractions)  # no code rounds above the drive ceiling
        if float(fractions.max()) > ZERO_FRACTION:
            self._quiet_since = None
        elif self._quiet_since is None:
            self._quiet_since = now
        idle = self._quiet_since is not None and now - self._quiet_since >= IDLE_AFTER_S
        stream = not state.cut and (state.output_on or not idle)
        if stream:  # what was sent, for the resonance tracker and the check that the plate follows (serial/follow.py)
            clipped = np.clip(fractions, 0.0, 1.0, out=self._clipped[:due])
            self.intake.drive.add(float(clipped.sum()) * limits.full_scale_um_pp, len(fractions))
            self.intake.sent.put(self.transport.index, np.multiply(clipped, limits.full_scale_um_pp, out=clipped))
        try:
            self._ran(time.perf_counter(), self._ran_at)  # (the batch made ready: the host's; the writes follow)
            if self.tracker is not None:
                self._follow_tracker()
            self._clear_faults(now)
            if not stream:  # idle or cut: nothing sent, the index runs on (the next ENABLE starts a new stream)
                self.transport.skip(due)
                self._last_sent = None
                return
            self._enable_if_off()
            self._ask_clock(now)  # before the frame: on a paced link its bytes would wait behind the frame's
            self._send_setpoints(fractions)
            sent_at = time.perf_counter()
            if self._last_sent is not None and sent_at - self._last_sent > self._dry_s:  # it may have run dry
                self._late_frame(sent_at - self._last_sent)
            self._last_sent = sent_at
            if idle and state.output_on:  # zeros long enough, the last of them sent: rest the output
                self.transport.send(p.ENABLE, p.enable_payload(False))
                state.output_on = False
                self.counters.idle_rests += 1
                self._last_sent = None
        except (serial.SerialException, OSError) as error:
            self._port_failed(error)
            self.session.retry_soon()
            self._last_sent = None

    def _enable_if_off(self) -> None:
        """ENABLE 1, unacknowledged, before the frame (frames keep order): the drive left zero after a rest, or
        telemetry says the plate is off while this side streams (an ENABLE lost on the link)."""
        state = self.session.state
        if not state.output_on:
            self.transport.send(p.ENABLE, p.enable_payload(True))
            state.output_on, state.enabled_at = True, time.perf_counter()
            self.counters.idle_wakes += 1
        elif state.reenable:
            self.transport.send(p.ENABLE, p.enable_payload(True))
            state.enabled_at = time.perf_counter()
            self.counters.reenables += 1
            if self.counters.reenables == 1:
                self.account.reenabled_first_s = self.account.now_s()
        state.reenable = False

    # ---- pieces -----------------------------------------------------------------------------------
    def _follow_tracker(self) -> None:
        """Send the tracker's carrier if it moved (the ACK is not waited for)."""
        wanted = self.tracker.carrier_hz
        if wanted != self.session.carrier_hz:
            self.session.carrier_hz = wanted
            self.transport.send(p.SET_CARRIER, p.carrier_payload(wanted))
            self.counters.carrier_changes += 1

    def _clear_faults(self, now: float) -> None:
        mask = self.intake.clearing.due(now)
        if mask:
            self.transport.send(p.CLEAR_FAULTS, p.clear_faults_payload(mask))

    def _ran(self, now: float, since: float) -> None:
        """The writer looks at the clock (``now``) having run, or slept to a planned wake, since ``since``
        (perf_counter s): more than ``STALL_S`` went by beyond its writes' waits for room on the port (the
        link's), so this process did not run for a while (descheduled, stopped). Looked at in every turn, not only
        after a sleep: a stall that came while the writer computed (its pull, its frames) went unseen, and the
        plate's telemetry, unread meanwhile, was taken for its silence (the plate lost)."""
        waited = self.transport.waited_s
        stalled_s = now - since - (waited - self._waited_s)
        self._ran_at, self._waited_s = now, waited
        if stalled_s > STALL_S:
            self._host_stalled(stalled_s, now)

    def _host_stalled(self, stalled_s: float, now: float) -> None:
        """The writer woke ``stalled_s`` late: the host did not run. Its silence check is moved on by the stall
        (what the device sent meanwhile is still unread), not started again: a device silent between stalls that
        come more often than the check's time is still found silent. The stall is kept for the report."""
        state = self.session.state
        state.last_heard = min(time.monotonic(), state.last_heard + stalled_s)
        self.counters.host_stalls += 1
        self.account.host_stalled(stalled_s, now)

    def _ask_clock(self, now: float) -> None:
        """A CLOCK request every ``CLOCK_EVERY_S`` while the device states its clock and someone listens (one
        awaited at a time; one unanswered for ``CLOCK_GIVE_UP_S`` is given up)."""
        intake, device = self.intake, self.session.state.device
        since = now - self._clock_asked_s  # the time the gate and the request's record share: the send's sent_at
        if not intake.wants_clock or device is None or not device.states_clock or since < CLOCK_EVERY_S or \
                (intake.clock_seq is not None and since < CLOCK_GIVE_UP_S):  # (the reader clears it on the reply)
            return
        self.transport.send(p.CLOCK, expect=self._expect_clock)

    def _asking_clock(self, seq: int) -> None:
        """The CLOCK request ``seq`` is about to be written (inside the transport's send, its ``sent_at`` taken):
        kept here for the gate and handed to the reader's intake, which awaits the reply; no float made."""
        self._clock_asked_s = sent_at = self.transport.sent_at
        self.intake.asking_clock(seq, sent_at)

    def _heartbeat(self) -> None:
        try:
            self.transport.send(p.HEARTBEAT)
        except (serial.SerialException, OSError) as error:
            self._port_failed(error)

    def _port_failed(self, error: BaseException) -> None:
        """A write failed: the link is lost, and a write that waited out its timeout is counted as such."""
        if isinstance(error, serial.SerialTimeoutException):
            self.counters.write_timeouts += 1
        self._lost(port_failure(error))

    def _late_frame(self, gap_s: float) -> None:
        """A frame went out ``gap_s`` after the one before, longer than the plate's buffer lasts."""
        self.counters.late_frames += 1
        if gap_s > self.session.watchdog_s:
            self.counters.send_stalls += 1
        self.account.late_frame(gap_s)

    def _send_setpoints(self, fractions: np.ndarray) -> None:
        """Send values (fractions of full scale) in frames of at most 240, continuing the stream's index."""
        force = self.session.force_reference(self.source)
        for start in range(0, len(fractions), p.MAX_SETPOINTS_PER_FRAME):  # at most 480 bytes of values a frame
            chunk = fractions[start:start + p.MAX_SETPOINTS_PER_FRAME]
            self.transport.send(p.SETPOINTS, setpoints=chunk, force=force)
            self.counters.setpoints_sent += len(chunk)
