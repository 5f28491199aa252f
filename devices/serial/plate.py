"""The serial plate driver: streams amplitude setpoints to plate-driver firmware (docs/protocol.md).

A writer thread pulls the envelope from its source at the control rate and sends it in batches
(every ``batch_s``); pyserial's ReaderThread decodes telemetry and acknowledgements. When the port
vanishes or the device stops answering, the driver counts it, keeps pulling from the source (the
renderer keeps its clock), and reconnects with exponential backoff when the port is back. On every
way out, error paths included, it sends zero amplitude and disable while the link works. It counts
every fault the device reports over the whole run (from the device's fault counters, across
reconnections), clears the device's latched bits, and keeps what happened and when: :meth:`report`
says it in words and gives the exit status it earns (:mod:`ultraglide.devices.serial.run_report`).

**The device's limits bind.** At each handshake the host takes the smaller of the profile's and the
device's amplitude limit (and drive ceiling), binds the output stage's limiter to them, and scales
setpoint codes by the device's own full scale; :attr:`notes` says so when they differ from the profile.

**Timing.** While streaming, the writer keeps the plate's jitter buffer at its target depth: it sends
``lead`` values (the device's prefill, 10 ms, plus one frame) ahead of its clock, so sample k of the
stream plays at ``start + k / rate``. A stream that (re)starts sends the whole lead in its first frame,
which the device plays on arrival. After a stall of the host long enough for the plate to run dry, the
writer skips ahead (the device counts the skipped values as lost) instead of sending its backlog, so the
latency once streaming resumes is the lead again, not the stall. A v3 device reports its buffer's depth
in telemetry: its median over 0.2 s more than 5 ms off its target (the plate's clock drifting from the
host's, its playback restarted late) moves the lead by the difference; a few frames deep for a moment (the
plate catching up a stall of its own, reading a backlog late) do not. The source is told when its values play
on the plate (``pull``'s ``now_s``): the host's clock, moved by what the lead was moved by. A wake's ENABLE 1
goes unacknowledged; telemetry that says the plate is still off 0.1 s later has it sent again.

The carrier can change while it runs: :meth:`set_carrier` (acknowledged; the plate sweep uses it),
or a :class:`~ultraglide.devices.characterisation.resonance.ResonanceTracker` given as ``tracker``, which is fed every
telemetry frame (carrier, measured amplitude, mean commanded amplitude since the previous frame) and
whose carrier the writer thread sends when it changes (unacknowledged: telemetry confirms it).

The port is opened exclusively (a ``flock``, which pyserial's ``exclusive`` takes and which holds on
pseudo-terminals too, plus ``TIOCEXCL`` for programs that do not lock): a second driver on the same
port is refused in one line. A setpoint rate the link cannot carry at its baud rate is refused too.

Example::

    plate = SerialPlate("/dev/ttyACM0", profile)
    plate.start(source)      # a devices.source.BlockSource of µm setpoints
    ...
    plate.stop()             # ramps down, then zero and disable
    plate.report().lines     # what happened, in words; .exit_status
"""

from __future__ import annotations

import contextlib
import math
import threading
import time

import numpy as np
import serial
import serial.threaded
from ultraglide.devices import protocol as p
from ultraglide.devices.characterisation.resonance import ResonanceTracker
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.source import BlockSource, ramp_down
from ultraglide.devices.output.stage import output_stage
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.serial.handshake import Handshake
from ultraglide.devices.serial.link import (  # noqa: F401 - IDLE_AFTER_S, open_port: the driver's names
    COMMAND_NAMES,
    CUT_FAULTS,
    DEPTH_DEADBAND_S,
    DEPTH_WINDOW,
    IDLE_AFTER_S,
    LINK_COUNTERS,
    MAX_OUTAGES,
    REST_ACK_S,
    SILENCE_S,
    TRACKING_DISTURBANCES,
    FrameReader,
    Outage,
    SerialCounters,
    check_link_budget,
    open_port,
)
from ultraglide.devices.serial.report import RunReporting
from ultraglide.devices.serial.telemetry import TelemetryIntake
from ultraglide.devices.serial.writer import StreamWriter


class SerialPlate(Handshake, TelemetryIntake, StreamWriter, RunReporting):
    """A plate driver on a serial port (any pyserial URL: a device path, ``loop://``, …)."""

    signal = "control"

    def __init__(self, port: str, profile: PlateProfile, control_rate_hz: int = 12000, carrier_hz: float | None = None,
                 baudrate: int = 921600, batch_s: float | None = None, ack_timeout_s: float = p.HOST_ACK_TIMEOUT_S,
                 tracker: ResonanceTracker | None = None, check_budget: bool = True, silence_s: float = SILENCE_S,
                 amplitude_loop: bool = False):
        self.port = port
        self.profile = profile
        self.rate_hz = int(control_rate_hz)
        if check_budget and "://" not in port:  # URL transports (loop://, socket://) have no baud rate
            check_link_budget(port, baudrate, self.rate_hz)
        self.tracker = tracker
        self.carrier_hz = tracker.carrier_hz if tracker is not None else (carrier_hz or profile.resonance_hz)
        self.baudrate = baudrate
        self.batch_s = batch_s or p.batch_s_for(baudrate, self.rate_hz)  # s between SETPOINTS frames
        self.ack_timeout_s = ack_timeout_s
        self.silence_s = silence_s  # no telemetry, or no room for a frame, for this long: the device is gone
        self.counters = SerialCounters()
        self.telemetry: p.Telemetry | None = None
        self.device: p.HelloReply | None = None
        self.notes: list[str] = []  # one line each: where the device's facts bind the host (limits, version)
        # what binds the output: the profile's, narrowed by every device met over the run
        self.limit_um_pp = profile.max_amplitude_um_pp
        self.max_drive_um_pp = profile.max_drive_um_pp
        self.full_scale_um_pp = profile.full_scale_um_pp  # the device's once it has said (codes scale by it)
        self._top_fraction = 1.0
        self.amplitude_loop = amplitude_loop  # asked: SET_LOOP 1 before each ENABLE, where the device has the loop
        self.loop_on = False  # the device's amplitude loop runs (this connection)
        self._serial: serial.Serial | None = None
        self._reader: serial.threaded.ReaderThread | None = None
        self._write_lock = threading.Lock()
        self._reply = threading.Condition()
        self._awaiting: set[int] = set()
        self._answers: dict[int, int | None] = {}  # seq → None (ACK) or a NAK reason
        self._sent_kinds = bytearray(65536)  # the command each seq carried, to name what a NAK refused
        self._sent_at = 0.0  # perf_counter s of the last frame sent
        self._hello: bytes | None = None
        self._hello_seq = -1
        self._session = False  # this connection's HELLO_REPLY has arrived: its telemetry counts
        self._fault_last: tuple[int, ...] | None = None  # the device's counters at the last telemetry
        self._frames_ok_last = 0
        self._fault_run = [0] * p.FAULT_BITS  # faults over the run
        self._link_last: dict[str, int] = {}
        self._link_run = dict.fromkeys(LINK_COUNTERS, 0)
        self._clear_pending = 0
        self._clear_refused = False  # the device refused CLEAR_FAULTS: not asked again
        self._trim_lock = threading.Lock()  # held only to add to or take the request below
        self._trim_request = 0.0  # values the writer's lead should move by (the reader's depth tracking asks)
        self._stream_epoch = 0  # a new stream (wake, connection, re-anchoring): the depth window starts again
        self._depth_epoch = -1
        self._depths, self._depth_n = [0] * DEPTH_WINDOW, 0  # the present window's depths, values
        self._depth_worst = 0.0  # the largest correction asked, values
        self._clear_outstanding = False  # a CLEAR_FAULTS is on its way, not yet answered
        self._clear_mask = 0
        self._clear_sent_at = 0.0
        self._seq = 0
        self._index = 0
        self._framer = p.SetpointFramer(self.rate_hz)  # SETPOINTS frames built in buffers made once
        self._fractions = np.empty(self.rate_hz)  # the writer's batch as fractions of full scale (up to 1 s)
        self._clipped = np.empty(self.rate_hz)
        self._zeros = np.zeros(16)
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
        self.sensors: p.Sensors | None = None  # the last SENSORS frame (v3, a device with sensors)
        self.sensors_frames = 0
        self.sensor_errors = 0
        self._sensor_listeners: tuple = ()
        self.telemetry_frames = 0  # TELEMETRY frames taken over the run
        self._output_on = False  # the host enabled the output and streams setpoints (False: idle, or not yet)
        self._enabled_at = 0.0  # when the last ENABLE 1 went (perf_counter s)
        self._reenable = False  # telemetry says the plate is off while the host streams: the writer enables again
        self._reenabled_first_s = 0.0  # when it first did (s since the run started)
        self._cut = False  # the device disabled itself over this run (trip, overheat): never re-enabled by the host
        # what happened, for the report (times in s since start); guarded by _account_lock, held for a copy
        self._account_lock = threading.Lock()
        self._started = time.perf_counter()
        self._outages: list[Outage] = []
        self._outages_dropped = 0
        self._refusals: dict[tuple[str, str], list] = {}  # (command, reason) → [count, first s]
        self._fault_first_s: dict[str, float] = {}
        self._cut_at: tuple[float, str] | None = None
        self._stall_longest = (0.0, 0.0)  # (duration s, at s)
        self._late_longest = (0.0, 0.0)  # the longest gap between frames while streaming, over the buffer (s, at s)
        self._bad_received = [0, 0, None]  # crc, malformed, first s
        self._writer_failure: tuple[float, str] | None = None
        self._rest_failure: str | None = None
        self._rested = False

    # ---- the run's clock and account ----------------------------------------------------------
    def _now_s(self) -> float:
        """Seconds since the run started (:meth:`start`)."""
        return time.perf_counter() - self._started

    @property
    def lead(self) -> int:
        """Values the writer keeps sent ahead of its clock while streaming: the device's prefill plus a frame."""
        return int(math.ceil(p.PREFILL_MS * self.rate_hz / 1000.0)) + self._batch

    @property
    def buffer_lasts_s(self) -> float:
        """How long the plate's buffer lasts after a frame (s): the lead, less a frame's time between frames and
        one more for the link's latency. A frame sent later than that after the one before is late: the plate
        may have run dry. (A simulated plate on a pty beside two CPU hogs held 1.3 ms less than the lead when a
        frame arrived, and ran dry after a gap of 9.7 ms that a margin of one frame called on time.)"""
        return (self.lead - 2 * self._batch) / self.rate_hz

    @property
    def _batch(self) -> int:
        return max(1, int(round(self.batch_s * self.rate_hz)))

    # ---- frames from the device ----------------------------------------------------------------
    def next_telemetry(self, timeout_s: float | None = None) -> p.Telemetry:
        """Wait for the next TELEMETRY frame and return it; DeviceError if none comes within ``timeout_s``
        (default: the ACK timeout)."""
        timeout_s = self.ack_timeout_s if timeout_s is None else timeout_s
        with self._telemetry_arrived:
            seen = self.telemetry_frames
            if not self._telemetry_arrived.wait_for(lambda: self.telemetry_frames > seen, timeout_s):
                raise DeviceError(f"{self.port}: no telemetry from the plate driver for {timeout_s:g} s")
            return self.telemetry

    def hello(self) -> p.HelloReply | None:
        """What the device said of itself in this connection's handshake (None before one)."""
        return self.device

    def fault_counts(self) -> dict[str, int]:
        """Each fault the device can report, by name, with how often it happened over this run."""
        return {name: self._fault_run[bit.bit_length() - 1] for bit, name in p.FAULT_NAMES.items()}

    def _lost(self, cause: str) -> None:
        """The link failed (reader or writer thread): the plate is lost until a reconnection."""
        if self._connected.is_set():
            self._connected.clear()
            self.counters.disconnects += 1
            self._outage(cause)

    def _outage(self, cause: str) -> None:
        with self._account_lock:
            if len(self._outages) < MAX_OUTAGES:
                self._outages.append(Outage(self._now_s(), cause, self.counters.setpoints_discarded))
            else:
                self._outages_dropped += 1

    def _back(self) -> None:
        with self._account_lock:
            if self._outages and self._outages[-1].back_s is None:
                outage = self._outages[-1]
                outage.back_s = self._now_s()
                outage.not_sent = self.counters.setpoints_discarded - outage.discarded_before

    # ---- sending ---------------------------------------------------------------------------------
    def _send(self, kind: int, payload: bytes = b"", awaited: bool = False, setpoints: np.ndarray | None = None,
              force: p.ForceReference | None = None) -> int:
        """Write one frame; returns its seq. ``awaited``: its ACK or NAK will be waited for. ``setpoints``
        (fractions of full scale, at the stream's index): a SETPOINTS frame built by the framer instead, or with
        ``force`` a SETPOINTS_FORCE frame (the force its values were computed at)."""
        with self._write_lock:
            port = self._serial
            if port is None:
                raise serial.SerialException("not connected")
            self._seq = seq = (self._seq + 1) & 0xFFFF
            self._sent_kinds[seq] = kind if force is None else p.SETPOINTS_FORCE
            self._sent_at = time.perf_counter()
            if awaited:
                with self._reply:
                    self._awaiting.add(seq)
            if setpoints is None:
                port.write(p.encode_frame(kind, seq, payload))
            else:
                port.write(self._framer.frame(seq, self._index, setpoints, force))
        self.counters.frames_sent += 1
        return seq

    def _command(self, kind: int, payload: bytes, timeout_s: float | None = None) -> None:
        """Send a command and wait for its ACK; DeviceError on a NAK or no answer within ``ack_timeout_s``."""
        timeout_s = self.ack_timeout_s if timeout_s is None else timeout_s
        seq = self._send(kind, payload, awaited=True)
        try:
            with self._reply:
                if not self._reply.wait_for(lambda: seq in self._answers, timeout_s):
                    raise DeviceError(f"{self.port}: no acknowledgement of {COMMAND_NAMES.get(kind, hex(kind))} from "
                                      f"the plate driver within {timeout_s:g} s")
                reason = self._answers.pop(seq)
        finally:
            with self._reply:
                self._awaiting.discard(seq)
                self._answers.pop(seq, None)
        if reason is not None:
            raise DeviceError(f"{self.port}: the plate driver refused {COMMAND_NAMES.get(kind, hex(kind))}: "
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
    def _open(self) -> serial.Serial:
        return open_port(self.port, self.baudrate, write_timeout_s=self.silence_s)

    def _connect(self) -> None:
        port = self._open()
        with contextlib.suppress(serial.SerialException, OSError):
            port.reset_input_buffer()  # what a previous session left unread is not ours
        self._serial = port
        self.telemetry = None  # only what this connection reports counts
        self._session = False
        self._reader = serial.threaded.ReaderThread(port, lambda: FrameReader(self))
        self._reader.daemon = True
        self._reader.start()
        try:
            hello = self._handshake()
            self._bind(hello)
            first = self._fault_last is None
            self._first_telemetry = threading.Event() if first else None
            self._session = True
            if first and not self._first_telemetry.wait(self.ack_timeout_s):  # the run's fault baseline
                raise DeviceError(f"{self.port}: the plate driver sends no telemetry")
            self.loop_on = False
            if self.amplitude_loop and hello.has_amplitude_loop:  # only while disabled: before ENABLE, and after
                self._command(p.ENABLE, p.enable_payload(False))  # a hang the device may still be enabled (NAK 3)
                self._command(p.SET_LOOP, p.set_loop_payload(1))
                self.loop_on = True
            self._command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
            if not self._cut:  # a device that cut itself out over this run is never re-enabled by the host
                self._command(p.ENABLE, p.enable_payload(True))
                self._output_on, self._enabled_at = True, time.perf_counter()
            self._last_heard = time.monotonic()
            self._connected.set()
        except (serial.SerialException, OSError) as error:
            self._disconnect()
            raise DeviceError(f"{self.port}: lost during the handshake ({error})") from None
        except BaseException:
            self._rest_now(REST_ACK_S)  # zero and disable while the link works: the device may have enabled
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

    def _rest_now(self, ack_timeout_s: float | None = None) -> bool:
        """Zero setpoints (at the stream's next index) and ENABLE 0, acknowledged; False if the link failed."""
        if self._serial is None:
            return False
        try:
            self._send(p.SETPOINTS, setpoints=self._zeros)
            self._index += len(self._zeros)
            self._command(p.ENABLE, p.enable_payload(False), ack_timeout_s)
            self._output_on = False
            return True
        except (serial.SerialException, OSError, DeviceError) as error:
            self._rest_failure = str(error).splitlines()[0] if str(error) else type(error).__name__
            return False

    def _rest(self) -> None:
        """The end of the run: zero amplitude and disable while the link still works, exactly once."""
        with self._account_lock:
            if self._rested:
                return
            self._rested = True
        if self.device is None:  # never connected: nothing to rest (a failed handshake rested what answered)
            return
        if self._serial is None:
            self._rest_failure = "the link was down"
            return
        if self._rest_now():
            self._rest_failure = None

    # ---- the writer thread -----------------------------------------------------------------------
    def start(self, source: BlockSource) -> None:
        """Connect (handshake, carrier, enable) and start streaming; raises DeviceError if it cannot."""
        self.profile.check_carrier(self.carrier_hz)
        self._source = output_stage(source, self.profile, self.signal, self.rate_hz)
        self._started = time.perf_counter()
        self._connect()
        self._thread = threading.Thread(target=self._run, name="serial-plate", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Ramp down through the source, then send zero and disable and close the port."""
        if self._source is not None and self._thread is not None and self._thread.is_alive():
            ramp_down(self._source, self._thread.is_alive)
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            if self._thread.is_alive():  # stuck (a write that never returns): rest from here, once
                self._rest()
        else:
            self._rest()
        self._disconnect()

    # ---- what happened ---------------------------------------------------------------------------
