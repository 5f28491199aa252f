"""The serial plate driver: streams amplitude setpoints to plate-driver firmware (protocol v2, docs/protocol.md).

A writer thread pulls the envelope from its source at the control rate and sends it in batches
(every ``batch_s``); pyserial's ReaderThread decodes telemetry and acknowledgements. When the port
vanishes or the device stops answering, the driver counts it, keeps pulling from the source (the
renderer keeps its clock), and reconnects with exponential backoff when the port is back. On every
way out it sends zero amplitude and disable. It counts every fault the device reports over the whole
run (from the device's fault counters, across reconnections) and clears the device's latched bits.

The carrier can change while it runs: :meth:`set_carrier` (acknowledged; the plate sweep uses it),
or a :class:`~ultraglide.devices.resonance.ResonanceTracker` given as ``tracker``, which is fed every
telemetry frame (carrier, measured amplitude, mean commanded amplitude since the previous frame) and
whose carrier the writer thread sends when it changes (unacknowledged: telemetry confirms it).

Example::

    plate = SerialPlate("/dev/ttyACM0", profile)
    plate.start(source)      # a devices.source.BlockSource of µm setpoints
    ...
    plate.stop()             # ramps down, then zero and disable
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass, field

import numpy as np
import serial
import serial.threaded
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output_stage import output_stage
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.resonance import ResonanceTracker
from ultraglide.devices.source import BlockSource, ramp_down

SILENCE_S = p.HOST_SILENCE_MS / 1000.0  # no telemetry for this long while connected: the device has hung
BACKOFF_S = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6)
# faults after which the plate played far from what was commanded (ramped or cut to zero): the tracker
# discards what it was measuring. An underrun holds the last value and an overrun drops a few: both leave
# the mean drive nearly as commanded, and on a loaded host they come often, so they do not count.
TRACKING_DISTURBANCES = (p.FAULT_WATCHDOG, p.FAULT_TRIP, p.FAULT_OVERHEAT)
# setpoints that all round to code 0 for this long: the host stops the stream and disables the output (the
# plate rests either way); the first non-zero setpoint enables it again. Well inside nothing: no watchdog
# runs while disabled, and telemetry (which the host's silence check needs) goes on.
IDLE_AFTER_S = 0.05
ZERO_FRACTION = 0.5 / p.SETPOINT_SCALE  # at most this fraction of full scale is sent as code 0
# when the drive leaves zero, the writer pulls a whole prefill (10 ms) at once, so the plate, which plays once it
# holds that much, starts as soon as it arrives; while idle it still pulls every batch, so a touch waits no longer
WAKE_PULL_S = p.PREFILL_MS / 1000.0
CUT_FAULTS = (p.FAULT_TRIP, p.FAULT_OVERHEAT)  # the device disabled itself: the host never re-enables it


@dataclass
class SerialCounters:
    frames_sent: int = 0
    setpoints_sent: int = 0
    setpoints_discarded: int = 0  # pulled while disconnected
    disconnects: int = 0
    reconnects: int = 0
    silences: int = 0  # device stopped answering
    bad_frames: int = 0  # received frames that did not decode
    late_batches: int = 0
    naks: int = 0  # frames the device refused
    carrier_changes: int = 0  # SET_CARRIER sent while streaming (sweep or tracking)
    send_stalls: int = 0  # the writer sent nothing for longer than the device's watchdog timeout
    idle_rests: int = 0  # the stream stopped and the output disabled while the drive was zero
    idle_wakes: int = 0  # ... and enabled again by a non-zero drive
    errors: list[str] = field(default_factory=list)


class _FrameReader(serial.threaded.Protocol):
    """Feeds received bytes to a FrameDecoder (which bounds its buffer) and hands frames on."""

    def __init__(self, driver: SerialPlate):
        self.driver = driver
        self.decoder = p.FrameDecoder()

    def data_received(self, data: bytes) -> None:
        for frame in self.decoder.feed(data):
            self.driver._frame(frame)
        self.driver.counters.bad_frames = self.decoder.crc_errors + self.decoder.framing_errors

    def connection_lost(self, exc) -> None:
        self.driver._lost(exc)


class SerialPlate:
    """A plate driver on a serial port (any pyserial URL: a device path, ``loop://``, …)."""

    signal = "control"

    def __init__(self, port: str, profile: PlateProfile, control_rate_hz: int = 12000, carrier_hz: float | None = None,
                 baudrate: int = 921600, batch_s: float | None = None, ack_timeout_s: float = p.HOST_ACK_TIMEOUT_S,
                 tracker: ResonanceTracker | None = None):
        self.port = port
        self.profile = profile
        self.rate_hz = int(control_rate_hz)
        self.tracker = tracker
        self.carrier_hz = tracker.carrier_hz if tracker is not None else (carrier_hz or profile.resonance_hz)
        self.baudrate = baudrate
        self.batch_s = batch_s or p.batch_s_for(baudrate, self.rate_hz)  # s between SETPOINTS frames
        self.ack_timeout_s = ack_timeout_s
        self.counters = SerialCounters()
        self.telemetry: p.Telemetry | None = None
        self.device: p.HelloReply | None = None
        self._serial: serial.Serial | None = None
        self._reader: serial.threaded.ReaderThread | None = None
        self._write_lock = threading.Lock()
        self._reply = threading.Condition()
        self._awaiting: set[int] = set()
        self._answers: dict[int, int | None] = {}  # seq → None (ACK) or a NAK reason
        self._hello: bytes | None = None
        self._session = False  # this connection's HELLO_REPLY has arrived: its telemetry counts
        self._fault_last: tuple[int, ...] | None = None  # the device's counters at the last telemetry
        self._frames_ok_last = 0
        self._fault_run = [0] * p.FAULT_BITS  # faults over the run
        self._clear_pending = 0
        self._seq = 0
        self._index = 0
        self._framer = p.SetpointFramer(self.rate_hz)  # SETPOINTS frames built in buffers made once
        self._fractions = np.empty(self.rate_hz)  # the writer's batch as fractions of full scale (up to 1 s)
        self._clipped = np.empty(self.rate_hz)
        self._connected = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_heard = 0.0
        self._first_telemetry: threading.Event | None = None
        self._source: BlockSource | None = None
        self._drive_lock = threading.Lock()  # held only to add to or take the two sums below
        self._drive_sum_um_pp = 0.0  # commanded amplitude (clipped to full scale) sent since the last telemetry
        self._drive_count = 0
        self._telemetry_arrived = threading.Condition()
        self.telemetry_frames = 0  # TELEMETRY frames taken over the run
        self._output_on = False  # the host enabled the output and streams setpoints (False: idle, or not yet)
        self._cut = False  # the device disabled itself over this run (trip, overheat): never re-enabled by idling

    # ---- frames from the device ----------------------------------------------------------------
    def _frame(self, frame: p.Frame) -> None:
        self._last_heard = time.monotonic()
        try:
            if frame.kind == p.TELEMETRY and self._session:
                self._take_telemetry(p.parse_telemetry(frame.payload))
            elif frame.kind == p.HELLO_REPLY:
                with self._reply:
                    self._hello = frame.payload
                    self._reply.notify_all()
            elif frame.kind == p.ACK:
                self._answer(p.parse_ack(frame.payload), None)
            elif frame.kind == p.NAK:
                seq, reason = p.parse_nak(frame.payload)
                self.counters.naks += 1
                self._answer(seq, reason)
        except p.ProtocolError:
            self.counters.bad_frames += 1

    def _answer(self, seq: int, reason: int | None) -> None:
        with self._reply:
            if seq in self._awaiting:
                self._answers[seq] = reason
                self._reply.notify_all()

    def _take_telemetry(self, telemetry: p.Telemetry) -> None:
        """Add the faults since the previous telemetry to the run's counts (counters wrap at 2**32)."""
        counts = telemetry.fault_counts
        previous = self._fault_last
        if self._fault_last is not None:
            if telemetry.frames_ok < self._frames_ok_last:  # the device restarted: its counters began again
                new = counts
            else:
                new = [(now - before) & 0xFFFFFFFF for now, before in zip(counts, self._fault_last, strict=True)]
            self._fault_run = [run + n for run, n in zip(self._fault_run, new, strict=True)]
            if any(self._fault_run[bit.bit_length() - 1] for bit in CUT_FAULTS):
                self._cut = True
        self._fault_last = counts
        self._frames_ok_last = telemetry.frames_ok
        self._clear_pending |= telemetry.faults
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

    def next_telemetry(self, timeout_s: float | None = None) -> p.Telemetry:
        """Wait for the next TELEMETRY frame and return it; DeviceError if none comes within ``timeout_s``
        (default: the ACK timeout)."""
        timeout_s = self.ack_timeout_s if timeout_s is None else timeout_s
        with self._telemetry_arrived:
            seen = self.telemetry_frames
            if not self._telemetry_arrived.wait_for(lambda: self.telemetry_frames > seen, timeout_s):
                raise DeviceError(f"{self.port}: no telemetry from the plate driver for {timeout_s:g} s")
            return self.telemetry

    def fault_counts(self) -> dict[str, int]:
        """Each fault the device can report, by name, with how often it happened over this run."""
        return {name: self._fault_run[bit.bit_length() - 1] for bit, name in p.FAULT_NAMES.items()}

    def _lost(self, exc) -> None:
        if self._connected.is_set():
            self._connected.clear()
            self.counters.disconnects += 1

    # ---- sending ---------------------------------------------------------------------------------
    def _send(self, kind: int, payload: bytes = b"", awaited: bool = False, setpoints: np.ndarray | None = None) -> int:
        """Write one frame; returns its seq. ``awaited``: its ACK or NAK will be waited for. ``setpoints``
        (fractions of full scale, at the stream's index): a SETPOINTS frame built by the framer instead."""
        with self._write_lock:
            port = self._serial
            if port is None:
                raise serial.SerialException("not connected")
            self._seq = seq = (self._seq + 1) & 0xFFFF
            if awaited:
                with self._reply:
                    self._awaiting.add(seq)
            if setpoints is None:
                port.write(p.encode_frame(kind, seq, payload))
            else:
                port.write(self._framer.frame(seq, self._index, setpoints))
        self.counters.frames_sent += 1
        return seq

    def _command(self, kind: int, payload: bytes) -> None:
        """Send a command and wait for its ACK; DeviceError on a NAK or no answer within ``ack_timeout_s``."""
        seq = self._send(kind, payload, awaited=True)
        try:
            with self._reply:
                if not self._reply.wait_for(lambda: seq in self._answers, self.ack_timeout_s):
                    raise DeviceError(f"{self.port}: no acknowledgement from the plate driver within "
                                      f"{self.ack_timeout_s:g} s")
                reason = self._answers.pop(seq)
        finally:
            with self._reply:
                self._awaiting.discard(seq)
                self._answers.pop(seq, None)
        if reason is not None:
            raise DeviceError(f"{self.port}: the plate driver refused command {kind:#04x}: "
                              f"{p.NAK_REASONS.get(reason, f'reason {reason}')}")

    def set_carrier(self, carrier_hz: float) -> None:
        """Change the carrier now (Hz) and wait for the device's ACK; DeviceError if it refuses or is gone."""
        self.profile.check_carrier(carrier_hz)
        if self.device is not None and not self.device.carrier_min_hz <= carrier_hz <= self.device.carrier_max_hz:
            raise DeviceError(f"{self.port}: carrier {carrier_hz:g} Hz is outside what the plate driver accepts, "
                              f"{self.device.carrier_min_hz:g}-{self.device.carrier_max_hz:g} Hz")
        self.carrier_hz = float(carrier_hz)
        try:
            self._command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
        except (serial.SerialException, OSError) as error:
            raise DeviceError(f"{self.port}: lost while setting the carrier ({error})") from None
        self.counters.carrier_changes += 1

    def _follow_tracker(self) -> None:
        """Send the tracker's carrier if it moved (writer thread; the ACK is not waited for)."""
        wanted = self.tracker.carrier_hz
        if wanted != self.carrier_hz:
            self.carrier_hz = wanted
            self._send(p.SET_CARRIER, p.carrier_payload(wanted))
            self.counters.carrier_changes += 1

    # ---- connection ------------------------------------------------------------------------------
    def _connect(self) -> None:
        try:
            port = serial.serial_for_url(self.port, baudrate=self.baudrate, timeout=0.05, write_timeout=0.5)
        except (serial.SerialException, OSError, ValueError) as error:
            raise DeviceError(f"cannot open serial port {self.port}: {error}; check the path and "
                              "permissions (the dialout group), or list ports with `ultraglide devices`") from None
        with contextlib.suppress(serial.SerialException, OSError):
            port.reset_input_buffer()  # what a previous session left unread is not ours
        self._serial = port
        self.telemetry = None  # only what this connection reports counts
        self._session = False
        self._reader = serial.threaded.ReaderThread(port, lambda: _FrameReader(self))
        self._reader.daemon = True
        self._reader.start()
        try:
            with self._reply:
                self._hello = None
            self._send(p.HELLO, p.hello_payload())
            with self._reply:
                if not self._reply.wait_for(lambda: self._hello is not None, self.ack_timeout_s):
                    raise DeviceError(f"{self.port}: no answer to the handshake; is a plate driver there, "
                                      f"speaking ultraglide protocol v{p.PROTOCOL_VERSION}?")
                raw = self._hello
            hello = self._check_device(raw)
            self.device = hello
            first = self._fault_last is None
            self._first_telemetry = threading.Event() if first else None
            self._session = True
            if first and not self._first_telemetry.wait(self.ack_timeout_s):  # the run's fault baseline
                raise DeviceError(f"{self.port}: the plate driver sends no telemetry")
            self._command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
            self._command(p.ENABLE, p.enable_payload(True))
            self._output_on = True
            self._last_heard = time.monotonic()
            self._connected.set()
        except (serial.SerialException, OSError) as error:
            self._disconnect()
            raise DeviceError(f"{self.port}: lost during the handshake ({error})") from None
        except DeviceError:
            self._disconnect()
            raise

    def _check_device(self, raw: bytes) -> p.HelloReply:
        """The device's HELLO_REPLY, if it speaks our version and can play what we will send."""
        try:
            version = p.hello_reply_version(raw)
            if version not in p.SUPPORTED_VERSIONS:
                raise DeviceError(f"{self.port}: the plate driver speaks protocol v{version}; this ultraglide "
                                  f"speaks {' and '.join(f'v{v}' for v in p.SUPPORTED_VERSIONS)}: update the firmware "
                                  "(see docs/protocol.md)")
            hello = p.parse_hello_reply(raw)
        except p.ProtocolError as error:
            raise DeviceError(f"{self.port}: the plate driver's handshake reply is malformed ({error})") from None
        if not hello.carrier_min_hz <= self.carrier_hz <= hello.carrier_max_hz:
            raise DeviceError(f"{self.port}: carrier {self.carrier_hz:g} Hz is outside what the plate driver "
                              f"accepts, {hello.carrier_min_hz:g}-{hello.carrier_max_hz:g} Hz")
        if not hello.min_setpoint_rate_hz <= self.rate_hz <= hello.max_setpoint_rate_hz:
            raise DeviceError(f"{self.port}: the plate driver plays {hello.min_setpoint_rate_hz}-"
                              f"{hello.max_setpoint_rate_hz} setpoints/s, not {self.rate_hz}")
        return hello

    def _disconnect(self) -> None:
        self._connected.clear()
        reader, self._reader = self._reader, None
        port, self._serial = self._serial, None
        if reader is not None:
            with contextlib.suppress(Exception):
                reader.stop()
        if port is not None:
            with contextlib.suppress(Exception):
                port.close()

    def _rest(self) -> None:
        """Zero amplitude and disable: sent on every way out while the link still works."""
        if self._serial is None:
            return
        with contextlib.suppress(serial.SerialException, OSError, DeviceError):
            self._send(p.SETPOINTS, p.setpoints_payload(self._index, self.rate_hz, np.zeros(16)))
            self._command(p.ENABLE, p.enable_payload(False))

    # ---- the writer thread -----------------------------------------------------------------------
    def start(self, source: BlockSource) -> None:
        """Connect (handshake, carrier, enable) and start streaming; raises DeviceError if it cannot."""
        self.profile.check_carrier(self.carrier_hz)
        self._source = output_stage(source, self.profile, self.signal, self.rate_hz)
        self._connect()
        self._thread = threading.Thread(target=self._run, name="serial-plate", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        source = self._source
        started = time.perf_counter()
        sent_samples = 0
        attempt = 0
        retry_at = 0.0
        batch = max(1, int(self.batch_s * self.rate_hz))
        wake_batch = max(batch, int(WAKE_PULL_S * self.rate_hz))
        wake = np.empty(wake_batch)
        wake_level = ZERO_FRACTION * self.profile.full_scale_um_pp
        last_sent = None
        quiet_since = None  # when the run of all-zero setpoints began (perf_counter s)
        try:
            while not self._stop.is_set():
                now = time.perf_counter()
                due = int((now - started) * self.rate_hz) - sent_samples
                resting = not self._output_on and not self._cut and self._connected.is_set()
                if due < batch:
                    time.sleep((sent_samples + batch) / self.rate_hz - (now - started))
                    continue
                if due > 4 * batch:
                    self.counters.late_batches += 1
                values = source.pull(due, now)
                if resting and due < wake_batch and float(values.max()) > wake_level:  # the drive leaves zero
                    wake[:due] = values
                    wake[due:] = source.pull(wake_batch - due, now + due / self.rate_hz)
                    values, due = wake, wake_batch
                sent_samples += due
                if self._connected.is_set() and time.monotonic() - self._last_heard > SILENCE_S:
                    self.counters.silences += 1
                    self._disconnect()
                    self.counters.disconnects += 1
                if not self._connected.is_set():
                    last_sent = None
                    self.counters.setpoints_discarded += due
                    self._index += due
                    if time.monotonic() >= retry_at:
                        self._disconnect()
                        try:
                            self._connect()
                            self.counters.reconnects += 1
                            attempt = 0
                        except DeviceError as error:
                            retry_at = time.monotonic() + BACKOFF_S[min(attempt, len(BACKOFF_S) - 1)]
                            attempt += 1
                            if len(self.counters.errors) < 20:
                                self.counters.errors.append(str(error))
                    continue
                if due <= len(self._fractions):  # (a longer batch comes only after a stall: it may allocate)
                    fractions = np.divide(values, self.profile.full_scale_um_pp, out=self._fractions[:due])
                else:
                    fractions = np.asarray(values, dtype=float) / self.profile.full_scale_um_pp
                if float(fractions.max()) > ZERO_FRACTION:
                    quiet_since = None
                elif quiet_since is None:
                    quiet_since = now
                idle = quiet_since is not None and now - quiet_since >= IDLE_AFTER_S and not self._cut
                stream = self._output_on or not idle or self._cut
                if self.tracker is not None and stream:
                    clipped = self._clipped[:due] if due <= len(self._clipped) else None
                    played = float(np.clip(fractions, 0.0, 1.0, out=clipped).sum()) * self.profile.full_scale_um_pp
                    with self._drive_lock:
                        self._drive_sum_um_pp += played
                        self._drive_count += len(fractions)
                try:
                    if self.tracker is not None:
                        self._follow_tracker()
                    if self._clear_pending:  # latched faults seen in telemetry (already counted): clear them
                        mask, self._clear_pending = self._clear_pending, 0
                        self._send(p.CLEAR_FAULTS, p.clear_faults_payload(mask))
                    if not stream:  # idle: nothing sent, the index runs on (the next ENABLE starts a new stream)
                        self._index += due
                        last_sent = None
                    else:
                        if not self._output_on and not self._cut:  # the drive left zero: enable, unacknowledged,
                            self._send(p.ENABLE, p.enable_payload(True))  # and stream at once (frames keep order)
                            self._output_on = True
                            self.counters.idle_wakes += 1
                        self._send_setpoints(fractions)
                        sent_at = time.perf_counter()
                        if last_sent is not None and sent_at - last_sent > self.device.watchdog_ms / 1000.0:
                            self.counters.send_stalls += 1
                        last_sent = sent_at
                        if idle and self._output_on:  # zeros long enough, the last of them sent: rest the output
                            self._send(p.ENABLE, p.enable_payload(False))
                            self._output_on = False
                            self.counters.idle_rests += 1
                            last_sent = None
                except (serial.SerialException, OSError):
                    self._lost(None)
                    retry_at = time.monotonic() + BACKOFF_S[0]
                    last_sent = None
                if source.finished:
                    break
        except Exception as error:  # the source failed: rest the plate, then report
            self.counters.errors.append(f"{type(error).__name__}: {error}")
        finally:
            self._rest()

    def _send_setpoints(self, fractions: np.ndarray) -> None:
        """Send values (fractions of full scale) in frames of at most 240, continuing the stream's index."""
        for start in range(0, len(fractions), p.MAX_SETPOINTS_PER_FRAME):  # at most 480 bytes of values a frame
            chunk = fractions[start:start + p.MAX_SETPOINTS_PER_FRAME]
            self._send(p.SETPOINTS, setpoints=chunk)
            self._index += len(chunk)
            self.counters.setpoints_sent += len(chunk)

    def stop(self) -> None:
        """Ramp down through the source, then send zero and disable and close the port."""
        if self._source is not None and self._thread is not None and self._thread.is_alive():
            ramp_down(self._source, self._thread.is_alive)
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self._rest()
        self._disconnect()

    def status(self) -> dict:
        c = self.counters
        t = self.telemetry
        faults = self.fault_counts()
        return {
            "device": f"serial:{self.port}", "connected": self._connected.is_set(),
            "frames_sent": c.frames_sent, "setpoints_sent": c.setpoints_sent, "disconnects": c.disconnects,
            "reconnects": c.reconnects, "silences": c.silences, "bad_frames_received": c.bad_frames,
            "naks_received": c.naks, "send_stalls": c.send_stalls, "carrier_hz": round(self.carrier_hz, 2),
            "carrier_changes": c.carrier_changes,
            "output": "cut by the device" if self._cut else ("streaming" if self._output_on else "idle (disabled)"),
            "idle_rests": c.idle_rests,
            "measured_um_pp": None if t is None else t.measured_um_pp,
            "device_frames_ok": None if t is None else t.frames_ok,
            "device_crc_errors": None if t is None else t.crc_errors,
            "device_lost_setpoints": None if t is None else t.lost_setpoints,
            "device_late_setpoints": None if t is None else t.late_setpoints,
            "faults": faults,
            "device_faults": [name for name, count in faults.items() if count],
            **({"tracking": self.tracker.summary()} if self.tracker is not None else {}),
        }
