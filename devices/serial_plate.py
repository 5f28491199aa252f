"""The serial plate driver: streams amplitude setpoints to plate-driver firmware (docs/protocol.md).

A writer thread pulls the envelope from its source at the control rate and sends it in batches
(every ``batch_s``); pyserial's ReaderThread decodes telemetry and acknowledgements. When the port
vanishes or the device stops answering, the driver counts it, keeps pulling from the source (the
renderer keeps its clock), and reconnects with exponential backoff when the port is back. On every
way out it sends zero amplitude and disable.

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
from ultraglide.devices.source import BlockSource, ramp_down

HANDSHAKE_TIMEOUT_S = 1.0
SILENCE_S = 0.5  # no telemetry for this long while connected: the device has hung
BACKOFF_S = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6)


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
                 baudrate: int = 921600, batch_s: float = 0.002):
        self.port = port
        self.profile = profile
        self.rate_hz = int(control_rate_hz)
        self.carrier_hz = carrier_hz or profile.resonance_hz
        self.baudrate = baudrate
        self.batch_s = batch_s
        self.counters = SerialCounters()
        self.telemetry: p.Telemetry | None = None
        self.device: p.HelloReply | None = None
        self._serial: serial.Serial | None = None
        self._reader: serial.threaded.ReaderThread | None = None
        self._write_lock = threading.Lock()
        self._reply = threading.Condition()
        self._acks: dict[int, int] = {}
        self._hello: p.HelloReply | None = None
        self._seq = 0
        self._index = 0
        self._connected = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_heard = 0.0
        self._source: BlockSource | None = None

    # ---- frames from the device ----------------------------------------------------------------
    def _frame(self, frame: p.Frame) -> None:
        self._last_heard = time.monotonic()
        try:
            if frame.kind == p.TELEMETRY:
                self.telemetry = p.parse_telemetry(frame.payload)
            elif frame.kind == p.HELLO_REPLY:
                with self._reply:
                    self._hello = p.parse_hello_reply(frame.payload)
                    self._reply.notify_all()
            elif frame.kind == p.ACK:
                seq, status = p.parse_ack(frame.payload)
                with self._reply:
                    self._acks[seq] = status
                    self._reply.notify_all()
        except p.ProtocolError:
            self.counters.bad_frames += 1

    def _lost(self, exc) -> None:
        if self._connected.is_set():
            self._connected.clear()
            self.counters.disconnects += 1

    # ---- sending ---------------------------------------------------------------------------------
    def _send(self, kind: int, payload: bytes = b"") -> int:
        self._seq = (self._seq + 1) & 0xFFFF
        frame = p.encode_frame(kind, self._seq, payload)
        with self._write_lock:
            port = self._serial
            if port is None:
                raise serial.SerialException("not connected")
            port.write(frame)
        self.counters.frames_sent += 1
        return self._seq

    def _command(self, kind: int, payload: bytes) -> None:
        seq = self._send(kind, payload)
        with self._reply:
            if not self._reply.wait_for(lambda: seq in self._acks, HANDSHAKE_TIMEOUT_S):
                raise DeviceError(f"{self.port}: no acknowledgement from the plate driver")
            status = self._acks.pop(seq)
        if status != p.ACK_OK:
            raise DeviceError(f"{self.port}: the plate driver refused command {kind:#04x} (status {status})")

    # ---- connection ------------------------------------------------------------------------------
    def _connect(self) -> None:
        try:
            port = serial.serial_for_url(self.port, baudrate=self.baudrate, timeout=0.05, write_timeout=0.5)
        except (serial.SerialException, OSError, ValueError) as error:
            raise DeviceError(f"cannot open serial port {self.port}: {error}; check the path and "
                              "permissions (the dialout group), or list ports with `ultraglide devices`") from None
        self._serial = port
        self.telemetry = None  # only what this connection reports counts
        self._reader = serial.threaded.ReaderThread(port, lambda: _FrameReader(self))
        self._reader.daemon = True
        self._reader.start()
        try:
            with self._reply:
                self._hello = None
            self._send(p.HELLO, p.hello_payload())
            with self._reply:
                if not self._reply.wait_for(lambda: self._hello is not None, HANDSHAKE_TIMEOUT_S):
                    raise DeviceError(f"{self.port}: no answer to the handshake; is a plate driver there, "
                                      "speaking ultraglide protocol v1?")
                hello = self._hello
            if hello.version != p.PROTOCOL_VERSION:
                raise DeviceError(f"{self.port}: the plate driver speaks protocol v{hello.version}; "
                                  f"this ultraglide speaks v{p.PROTOCOL_VERSION}")
            self.device = hello
            self._command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
            self._command(p.ENABLE, p.enable_payload(True))
            self._last_heard = time.monotonic()
            self._connected.set()
        except (serial.SerialException, OSError) as error:
            self._disconnect()
            raise DeviceError(f"{self.port}: lost during the handshake ({error})") from None
        except DeviceError:
            self._disconnect()
            raise

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
        try:
            while not self._stop.is_set():
                now = time.perf_counter()
                due = int((now - started) * self.rate_hz) - sent_samples
                if due < batch:
                    time.sleep((sent_samples + batch) / self.rate_hz - (now - started))
                    continue
                if due > 4 * self.batch_s * self.rate_hz:
                    self.counters.late_batches += 1
                values = source.pull(due, now)
                sent_samples += due
                if self._connected.is_set() and time.monotonic() - self._last_heard > SILENCE_S:
                    self.counters.silences += 1
                    self._disconnect()
                    self.counters.disconnects += 1
                if not self._connected.is_set():
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
                fractions = np.asarray(values, dtype=float) / self.profile.full_scale_um_pp
                try:
                    for start in range(0, due, 240):  # at most 240 setpoints (480 bytes) a frame
                        chunk = fractions[start:start + 240]
                        self._send(p.SETPOINTS, p.setpoints_payload(self._index, self.rate_hz, chunk))
                        self._index += len(chunk)
                        self.counters.setpoints_sent += len(chunk)
                except (serial.SerialException, OSError):
                    self._lost(None)
                    retry_at = time.monotonic() + BACKOFF_S[0]
                if source.finished:
                    break
        except Exception as error:  # the source failed: rest the plate, then report
            self.counters.errors.append(f"{type(error).__name__}: {error}")
        finally:
            self._rest()

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
        return {
            "device": f"serial:{self.port}", "connected": self._connected.is_set(),
            "frames_sent": c.frames_sent, "setpoints_sent": c.setpoints_sent, "disconnects": c.disconnects,
            "reconnects": c.reconnects, "silences": c.silences, "bad_frames_received": c.bad_frames,
            "measured_um_pp": None if t is None else t.measured_um_pp,
            "device_frames_ok": None if t is None else t.frames_ok,
            "device_crc_errors": None if t is None else t.crc_errors,
            "device_faults": [] if t is None else t.fault_names(),
        }
