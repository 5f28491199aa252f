"""The serial plate driver: streams amplitude setpoints to plate-driver firmware (docs/protocol.md).

A writer thread pulls the envelope from its source at the control rate and sends it in batches
(every ``batch_s``); pyserial's ReaderThread decodes telemetry and acknowledgements. When the port
vanishes or the device stops answering, the driver counts it, keeps pulling from the source (the
renderer keeps its clock), and reconnects with exponential backoff when the port is back. On every
way out, error paths included, it sends zero amplitude and disable while the link works. It counts
every fault the device reports over the whole run (from the device's fault counters, across
reconnections), clears the device's latched bits, and keeps what happened and when: :meth:`report`
says it in words and gives the exit status it earns (:mod:`ultraglide.devices.run_report`).

**The device's limits bind.** At each handshake the host takes the smaller of the profile's and the
device's amplitude limit (and drive ceiling), binds the output stage's limiter to them, and scales
setpoint codes by the device's own full scale; :attr:`notes` says so when they differ from the profile.

**Timing.** While streaming, the writer keeps the plate's jitter buffer at its target depth: it sends
``lead`` values (the device's prefill, 10 ms, plus one frame) ahead of its clock, so sample k of the
stream plays at ``start + k / rate``. A stream that (re)starts sends the whole lead in its first frame,
which the device plays on arrival. After a stall of the host long enough for the plate to run dry, the
writer skips ahead (the device counts the skipped values as lost) instead of sending its backlog, so the
latency once streaming resumes is the lead again, not the stall. A v3 device reports its buffer's depth
in telemetry: averaged over 0.2 s, a depth more than 5 ms off its target (the plate's clock drifting
from the host's, a stall of the plate's own, a backlog it read late) moves the lead by the difference.

The carrier can change while it runs: :meth:`set_carrier` (acknowledged; the plate sweep uses it),
or a :class:`~ultraglide.devices.resonance.ResonanceTracker` given as ``tracker``, which is fed every
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
import errno
import math
import os
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
from ultraglide.devices.run_report import Incident, RunReport, seconds, times
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
CUT_FAULTS = (p.FAULT_TRIP, p.FAULT_OVERHEAT)  # the device disabled itself: the host never re-enables it
CUT_WORDS = {"trip": "over-amplitude trip: its measured amplitude went more than 1 % over its limit",
             "overheat": "overheat: its driver stage was too hot"}
STALL_S = 0.05  # the writer woke this much later than it meant to: the host did not run (not the plate's silence)
CLEAR_RETRY_S = 0.5  # a CLEAR_FAULTS unanswered this long was lost on the link: sent again
DEPTH_WINDOW = 10  # v3 telemetry frames (0.2 s) over which the plate's buffer depth is averaged
DEPTH_DEADBAND_S = 0.005  # the plate's buffer this far from its target on average: the host moves its lead
REST_ACK_S = 0.25  # after a failed handshake, how long the rest's ENABLE 0 waits for its ACK (best effort)
MAX_OUTAGES = 20  # disconnections kept with their times; more are counted
# the baud rates a UART is usually opened at, to name the one a stream needs
STANDARD_BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
                  1500000, 2000000, 2500000, 3000000, 3500000, 4000000)
# device counters whose run totals the report words (summed across reconnections like the fault counters)
LINK_COUNTERS = ("crc_errors", "framing_errors", "lost_setpoints", "late_setpoints", "overrun_setpoints")
COMMAND_NAMES = {p.HELLO: "HELLO", p.SET_CARRIER: "SET_CARRIER", p.ENABLE: "ENABLE", p.SETPOINTS: "SETPOINTS",
                 p.HEARTBEAT: "HEARTBEAT", p.CLEAR_FAULTS: "CLEAR_FAULTS", p.SIM_FAULT: "SIM_FAULT"}
if hasattr(p, "SET_LOOP"):
    COMMAND_NAMES[p.SET_LOOP] = "SET_LOOP"


def port_failure(error: BaseException | None) -> str:
    """Why the port failed, in a few words (pyserial's messages are long and about its internals)."""
    if error is None:
        return "the port closed"
    text = str(error)
    if "returned no data" in text or "Input/output error" in text or getattr(error, "errno", None) == errno.EIO:
        return "the port went away (the device closed it or was unplugged)"
    if "timeout" in text.lower():
        return "the port stopped taking data (a write timed out)"
    return f"the port failed ({text.splitlines()[0] if text else type(error).__name__})"


def open_port(port: str, baudrate: int, write_timeout_s: float = 0.5) -> serial.Serial:
    """A serial port (any pyserial URL) opened exclusively: a ``flock`` (pyserial's ``exclusive``; it holds on
    pseudo-terminals too) and ``TIOCEXCL``, which keeps out programs that take no lock (unless root).
    DeviceError in one line if it is missing or in use."""
    try:
        opened = serial.serial_for_url(port, baudrate=baudrate, timeout=0.05, write_timeout=write_timeout_s,
                                       exclusive=True)
    except (serial.SerialException, OSError, ValueError) as error:
        code = getattr(error, "errno", None)
        if code in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY) or "exclusively lock" in str(error):
            raise DeviceError(f"serial port {port} is in use by another program; stop it (or the other "
                              "ultraglide) first") from None
        reason = os.strerror(code).lower() if isinstance(code, int) else str(error)
        raise DeviceError(f"cannot open serial port {port}: {reason}; check the path and permissions (the "
                          "dialout group), or list ports with `ultraglide devices`") from None
    fd = getattr(opened, "fd", None)
    if fd is not None:
        import fcntl
        import termios

        with contextlib.suppress(OSError):
            fcntl.ioctl(fd, termios.TIOCEXCL)
    return opened


def stream_bytes_per_s(rate_hz: int) -> float:
    """Bytes a second a stream of ``rate_hz`` setpoints costs in 2 ms frames (docs/protocol.md, byte budget)."""
    return p.FRAME_OVERHEAD_BYTES / p.BATCH_S + 2.0 * rate_hz


def check_link_budget(port: str, baud: int, rate_hz: int) -> None:
    """DeviceError (one line, naming the baud rate needed) unless a ``baud`` UART (8N1: ten bits a byte) carries
    ``rate_hz`` setpoints a second in 2 ms frames."""
    needed = stream_bytes_per_s(rate_hz)
    if needed <= baud / 10.0:
        return
    fastest = max(0, int((baud / 10.0 - p.FRAME_OVERHEAD_BYTES / p.BATCH_S) / 2.0))
    minimum = int(math.ceil(needed * 10.0))
    standard = next((b for b in STANDARD_BAUDS if b >= minimum), None)
    advice = f"open it at {standard} baud (serial:{port}?baud={standard})" if standard else \
        "use USB CDC or a faster link, or a lower rate"
    raise DeviceError(f"serial port {port} at {baud} baud carries at most {fastest} setpoints/s (docs/protocol.md, "
                      f"byte budget), not {rate_hz}: the stream needs {minimum} baud; {advice}")


@dataclass
class SerialCounters:
    frames_sent: int = 0
    setpoints_sent: int = 0
    setpoints_discarded: int = 0  # pulled while disconnected
    setpoints_skipped: int = 0  # skipped after a host stall (re-anchoring): the device counts them lost
    disconnects: int = 0
    reconnects: int = 0
    silences: int = 0  # device stopped answering
    bad_frames: int = 0  # received frames that did not decode
    late_batches: int = 0
    naks: int = 0  # frames the device refused
    carrier_changes: int = 0  # SET_CARRIER sent while streaming (sweep or tracking)
    send_stalls: int = 0  # the writer sent nothing for longer than the device's watchdog timeout
    host_stalls: int = 0  # the writer woke more than STALL_S late (the host process did not run)
    late_frames: int = 0  # frames sent longer after the one before than the plate's buffer lasts (it may run dry)
    depth_corrections: int = 0  # the plate's buffer (v3 telemetry) drifted from its depth: the lead moved
    idle_rests: int = 0  # the stream stopped and the output disabled while the drive was zero
    idle_wakes: int = 0  # ... and enabled again by a non-zero drive
    errors: list[str] = field(default_factory=list)


@dataclass
class _Outage:
    """One loss of the plate: when (s into the run), why, when it came back, setpoints not sent meanwhile."""

    lost_s: float
    cause: str
    discarded_before: int
    back_s: float | None = None
    not_sent: int = 0
    last_error: str = ""


class _FrameReader(serial.threaded.Protocol):
    """Feeds received bytes to a FrameDecoder (which bounds its buffer) and hands frames on."""

    def __init__(self, driver: SerialPlate):
        self.driver = driver
        self.decoder = p.FrameDecoder()
        self._bad = 0

    def data_received(self, data: bytes) -> None:
        for frame in self.decoder.feed(data):
            self.driver._frame(frame)
        bad = self.decoder.crc_errors + self.decoder.framing_errors
        if bad != self._bad:
            self.driver._bad_frames_received(bad - self._bad, self.decoder.crc_errors, self.decoder.framing_errors)
            self._bad = bad

    def connection_lost(self, exc) -> None:
        self.driver._lost(port_failure(exc))


class SerialPlate:
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
        self._stream_epoch = 0  # a new stream (wake, connection, re-anchoring): the depth average starts again
        self._depth_epoch = -1
        self._depth_sum, self._depth_n = 0.0, 0
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
        self._cut = False  # the device disabled itself over this run (trip, overheat): never re-enabled by the host
        # what happened, for the report (times in s since start); guarded by _account_lock, held for a copy
        self._account_lock = threading.Lock()
        self._started = time.perf_counter()
        self._outages: list[_Outage] = []
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
    def _batch(self) -> int:
        return max(1, int(round(self.batch_s * self.rate_hz)))

    # ---- frames from the device ----------------------------------------------------------------
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
        """v3 telemetry says how many values wait in the plate's buffer. Averaged over DEPTH_WINDOW frames while it
        plays, a depth off its target by more than the deadband (the plate's clock drifting from the host's, the
        plate stalled, a backlog it read late) asks the writer to move its lead by the difference: the buffer, and
        the latency it costs, come back to the prefill and a frame."""
        if (getattr(telemetry, "version", 2) < 3 or telemetry.playback != p.PLAYBACK_PLAYING or not self._output_on
                or self._cut or self._depth_epoch != self._stream_epoch):
            self._depth_sum, self._depth_n, self._depth_epoch = 0.0, 0, self._stream_epoch
            return
        self._depth_sum += telemetry.buffered_setpoints
        self._depth_n += 1
        if self._depth_n < DEPTH_WINDOW:
            return
        error = self._depth_sum / self._depth_n - (self.lead - self._batch / 2.0)
        self._depth_sum, self._depth_n = 0.0, 0
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
                self._outages.append(_Outage(self._now_s(), cause, self.counters.setpoints_discarded))
            else:
                self._outages_dropped += 1

    def _back(self) -> None:
        with self._account_lock:
            if self._outages and self._outages[-1].back_s is None:
                outage = self._outages[-1]
                outage.back_s = self._now_s()
                outage.not_sent = self.counters.setpoints_discarded - outage.discarded_before

    # ---- sending ---------------------------------------------------------------------------------
    def _send(self, kind: int, payload: bytes = b"", awaited: bool = False, setpoints: np.ndarray | None = None) -> int:
        """Write one frame; returns its seq. ``awaited``: its ACK or NAK will be waited for. ``setpoints``
        (fractions of full scale, at the stream's index): a SETPOINTS frame built by the framer instead."""
        with self._write_lock:
            port = self._serial
            if port is None:
                raise serial.SerialException("not connected")
            self._seq = seq = (self._seq + 1) & 0xFFFF
            self._sent_kinds[seq] = kind
            self._sent_at = time.perf_counter()
            if awaited:
                with self._reply:
                    self._awaiting.add(seq)
            if setpoints is None:
                port.write(p.encode_frame(kind, seq, payload))
            else:
                port.write(self._framer.frame(seq, self._index, setpoints))
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
        self._reader = serial.threaded.ReaderThread(port, lambda: _FrameReader(self))
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
            if self.amplitude_loop and hello.has_amplitude_loop:  # only while disabled: before ENABLE
                self._command(p.SET_LOOP, p.set_loop_payload(1))
                self.loop_on = True
            self._command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
            if not self._cut:  # a device that cut itself out over this run is never re-enabled by the host
                self._command(p.ENABLE, p.enable_payload(True))
                self._output_on = True
            self._last_heard = time.monotonic()
            self._connected.set()
        except (serial.SerialException, OSError) as error:
            self._disconnect()
            raise DeviceError(f"{self.port}: lost during the handshake ({error})") from None
        except BaseException:
            self._rest_now(REST_ACK_S)  # zero and disable while the link works: the device may have enabled
            self._disconnect()
            raise

    def _handshake(self) -> p.HelloReply:
        """HELLO, and the device's answer: its HELLO_REPLY (checked), or a NAK or silence reported in one line."""
        with self._reply:
            self._hello = None
        seq = self._send(p.HELLO, p.hello_payload(), awaited=True)
        try:
            with self._reply:
                if not self._reply.wait_for(lambda: self._hello is not None or seq in self._answers,
                                            self.ack_timeout_s):
                    raise DeviceError(f"{self.port}: no answer to the handshake; is a plate driver there, "
                                      f"speaking ultraglide protocol v{p.PROTOCOL_VERSION}?")
                raw, reason = self._hello, self._answers.get(seq)
        finally:
            with self._reply:
                self._awaiting.discard(seq)
                self._answers.pop(seq, None)
        if raw is None:
            raise DeviceError(f"{self.port}: the plate driver refused the handshake (HELLO: "
                              f"{p.NAK_REASONS.get(reason, f'reason {reason}')}); it does not speak ultraglide "
                              f"protocol v{p.PROTOCOL_VERSION} as docs/protocol.md describes")
        return self._check_device(raw)

    def _check_device(self, raw: bytes) -> p.HelloReply:
        """The device's HELLO_REPLY, if it speaks our version and can play what we will send."""
        try:
            version = p.hello_reply_version(raw)
            if version not in p.SUPPORTED_VERSIONS:
                speaks = " or ".join(f"v{v}" for v in p.SUPPORTED_VERSIONS)
                raise DeviceError(f"{self.port}: the plate driver speaks protocol v{version}; this ultraglide "
                                  f"speaks {speaks}: update the firmware (see docs/protocol.md)")
            hello = p.parse_hello_reply(raw)
        except p.ProtocolError as error:
            raise DeviceError(f"{self.port}: the plate driver's handshake reply is malformed ({error})") from None
        if not hello.carrier_min_hz <= self.carrier_hz <= hello.carrier_max_hz:
            raise DeviceError(f"{self.port}: carrier {self.carrier_hz:g} Hz is outside what the plate driver "
                              f"accepts, {hello.carrier_min_hz:g}-{hello.carrier_max_hz:g} Hz")
        if not hello.min_setpoint_rate_hz <= self.rate_hz <= hello.max_setpoint_rate_hz:
            raise DeviceError(f"{self.port}: the plate driver plays {hello.min_setpoint_rate_hz}-"
                              f"{hello.max_setpoint_rate_hz} setpoints/s, not {self.rate_hz}")
        for name in ("full_scale_um_pp", "max_amplitude_um_pp"):
            value = getattr(hello, name)
            if not (math.isfinite(value) and value > 0):
                raise DeviceError(f"{self.port}: the plate driver reports {name} = {value:g}; it must be a "
                                  "positive number of µm p-p")
        return hello

    def _bind(self, hello: p.HelloReply) -> None:
        """The device's limits bind: the smaller limit and drive ceiling, codes scaled by its full scale; the
        output stage's limiter enforces them. Narrowed at each handshake, never widened over a run."""
        profile = self.profile
        device_limit = hello.max_amplitude_um_pp
        device_drive = getattr(hello, "max_drive_um_pp", None)  # v2 declares none: no overdrive (protocol.py)
        if device_drive is None:
            device_drive = max(device_limit, profile.max_drive_um_pp)
        limit = min(self.limit_um_pp, device_limit)
        overdrive = profile.max_drive_um_pp > profile.max_amplitude_um_pp and device_drive > device_limit
        drive = min(self.max_drive_um_pp, device_drive, hello.full_scale_um_pp) if overdrive else limit
        self.limit_um_pp, self.max_drive_um_pp = limit, max(limit, drive)
        self.full_scale_um_pp = hello.full_scale_um_pp
        # the largest code whose drive is not above the ceiling: rounding to nearest could add half a code
        self._top_fraction = min(1.0, math.floor(self.max_drive_um_pp / self.full_scale_um_pp * p.SETPOINT_SCALE)
                                 / p.SETPOINT_SCALE)
        self.device = hello
        stage = self._source
        if stage is not None and hasattr(stage, "limiter"):
            stage.limiter.bind(self.limit_um_pp, self.max_drive_um_pp)
        self._note_limits(hello, device_limit, device_drive)

    def _note_limits(self, hello: p.HelloReply, device_limit: float, device_drive: float) -> None:
        profile = self.profile
        notes = []
        if device_limit < profile.max_amplitude_um_pp:
            notes.append(f"the plate driver's limit is {device_limit:g} µm p-p, below the profile's "
                         f"{profile.max_amplitude_um_pp:g}: using {self.limit_um_pp:g}")
        elif device_limit > profile.max_amplitude_um_pp:
            notes.append(f"the plate driver's limit is {device_limit:g} µm p-p, above the profile's "
                         f"{profile.max_amplitude_um_pp:g}: using the profile's {self.limit_um_pp:g}")
        if hello.full_scale_um_pp != profile.full_scale_um_pp:
            notes.append(f"the plate driver's full scale is {hello.full_scale_um_pp:g} µm p-p, not the profile's "
                         f"{profile.full_scale_um_pp:g}: setpoint codes are scaled to the driver's")
        if profile.max_drive_um_pp > profile.max_amplitude_um_pp and self.max_drive_um_pp < profile.max_drive_um_pp:
            if device_drive <= device_limit:
                why = ("speaks protocol v2, which declares no overdrive" if hello.version < 3
                       else "allows no overdrive")
                notes.append(f"the plate driver {why}: drive held at the limit, {self.max_drive_um_pp:g} µm p-p "
                             f"(the profile allows {profile.max_drive_um_pp:g})")
            else:
                notes.append(f"the plate driver allows drive up to {device_drive:g} µm p-p, below the profile's "
                             f"{profile.max_drive_um_pp:g}: using {self.max_drive_um_pp:g}")
        for note in notes:
            if note not in self.notes:
                self.notes.append(note)

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
        dry_s = (lead - batch) / rate  # the plate's buffer lasts this long after a frame arrives
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
                    self.counters.late_batches += 1
                values = source.pull(due, started + position / rate)
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
                            self._output_on = True
                            self.counters.idle_wakes += 1
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
            if self._thread.is_alive():  # stuck (a write that never returns): rest from here, once
                self._rest()
        else:
            self._rest()
        self._disconnect()

    # ---- what happened ---------------------------------------------------------------------------
    def report(self) -> RunReport:
        """The run so far in words, with the exit status it earns (see :mod:`ultraglide.devices.run_report`)."""
        with self._account_lock:
            outages = [(o.lost_s, o.cause, o.back_s, o.not_sent, o.last_error, o.discarded_before)
                       for o in self._outages]
            refusals = {key: tuple(value) for key, value in self._refusals.items()}
            first = dict(self._fault_first_s)
            cut_at, stall, bad = self._cut_at, self._stall_longest, list(self._bad_received)
            late = self._late_longest
            writer_failure, dropped = self._writer_failure, self._outages_dropped
        incidents = []
        for lost_s, cause, back_s, not_sent, last_error, before in outages:
            if back_s is None:
                not_sent = self.counters.setpoints_discarded - before
                last = f" (the last try: {last_error})" if last_error else ""
                words = (f"plate lost at {seconds(lost_s)}: {cause}; not back by the end{last}; "
                         f"{not_sent} setpoints not sent")
            else:
                words = (f"plate lost at {seconds(lost_s)}: {cause}; back at {seconds(back_s)}; "
                         f"{not_sent} setpoints not sent")
            incidents.append(Incident(lost_s, "lost", words))
        if dropped:
            incidents.append(Incident(outages[-1][0], "lost", f"and {dropped} more losses of the plate"))
        if writer_failure is not None:
            incidents.append(Incident(writer_failure[0], "lost", f"the stream to the plate stopped at "
                                      f"{seconds(writer_failure[0])}: {writer_failure[1]}"))
        if cut_at is not None:
            incidents.append(Incident(cut_at[0], "cut", f"the plate cut its output at {seconds(cut_at[0])} "
                                      f"({CUT_WORDS.get(cut_at[1], cut_at[1])}): streaming stopped there; the host "
                                      "does not enable it again, so it stays off until the next run"))
        faults = self.fault_counts()
        severity = {"watchdog": "faulted", "over-limit": "faulted", "bad-command": "faulted", "trip": "cut",
                    "overheat": "cut"}
        for name, count in faults.items():
            if not count or cut_at is not None and name == cut_at[1] and count == 1:
                continue  # (the cut says it)
            kind = severity.get(name, "note")
            at = first.get(name, 0.0)
            incidents.append(Incident(at, kind, f"the plate raised {name} {times(count)} (first at {seconds(at)}): "
                                                f"{p.FAULT_WORDS.get(name, name)}"))
        for (command, reason), (count, at) in refusals.items():
            incidents.append(Incident(at, "faulted", f"the plate refused {times(count, 'frame')} of {command} "
                                                     f"({reason}), first at {seconds(at)}"
                                      + ("; its latched faults were not cleared again" if command == "CLEAR_FAULTS"
                                         else "")))
        if bad[0] or bad[1]:
            incidents.append(Incident(bad[2] or 0.0, "note", f"{times(bad[0] + bad[1], 'frame')} from the plate "
                                      f"arrived damaged ({bad[0]} with a bad CRC, {bad[1]} truncated or malformed), "
                                      f"first at {seconds(bad[2] or 0.0)}"))
        if stall[0]:
            skipped = self.counters.setpoints_skipped
            incidents.append(Incident(stall[1], "note", f"the host stalled {times(self.counters.host_stalls)} "
                                      f"(longest {stall[0]:.2f} s at {seconds(stall[1])})"
                                      + (f"; {skipped} setpoints skipped so the latency stays at the plate's "
                                         f"{1000 * self.lead / self.rate_hz:.0f} ms buffer" if skipped else "")))
        if late[0]:
            lasts_ms = 1000 * (self.lead - self._batch) / self.rate_hz
            incidents.append(Incident(late[1], "note", f"the host sent {times(self.counters.late_frames, 'frame')} "
                                      f"later than the plate's {lasts_ms:.0f} ms buffer lasts (the longest gap "
                                      f"{1000 * late[0]:.0f} ms, at {seconds(late[1])}): the plate may have run dry"))
        summary = self._link_summary()
        if self.counters.depth_corrections:
            worst_ms = 1000 * self._depth_worst / self.rate_hz
            summary.append(f"the plate's buffer drifted from its depth {times(self.counters.depth_corrections)} (by "
                           f"up to {worst_ms:.0f} ms: its clock against the host's, or a stall of its own); the host "
                           "moved its lead to bring it back")
        if self._rest_failure and self._rested:
            summary.append(f"the plate could not be rested at the end ({self._rest_failure}): its watchdog rests "
                           "it if it is still powered and was enabled")
        return RunReport.of(incidents, summary)

    def _link_summary(self) -> list[str]:
        run = self._link_run
        lines = []
        damaged = run["crc_errors"] + run["framing_errors"]
        if damaged:
            lines.append(f"the plate received {times(damaged, 'damaged frame')} ({run['crc_errors']} with a bad CRC, "
                         f"{run['framing_errors']} malformed)")
        lost, late, overrun = run["lost_setpoints"], run["late_setpoints"], run["overrun_setpoints"]
        if lost or late or overrun:
            parts = [f"{lost} lost" + (f" ({self.counters.setpoints_skipped} of them skipped by the host)"
                                       if self.counters.setpoints_skipped else "")]
            parts += [f"{late} late"] if late else []
            parts += [f"{overrun} dropped by overruns"] if overrun else []
            lines.append("the plate counted setpoints " + ", ".join(parts))
        return lines

    def status(self) -> dict:
        c = self.counters
        t = self.telemetry
        faults = self.fault_counts()
        report = self.report()
        return {
            "device": f"serial:{self.port}", "connected": self._connected.is_set(),
            "frames_sent": c.frames_sent, "setpoints_sent": c.setpoints_sent, "disconnects": c.disconnects,
            "reconnects": c.reconnects, "silences": c.silences, "bad_frames_received": c.bad_frames,
            "naks_received": c.naks, "send_stalls": c.send_stalls, "host_stalls": c.host_stalls,
            "late_frames": c.late_frames, "depth_corrections": c.depth_corrections,
            "setpoints_not_sent": c.setpoints_discarded, "setpoints_skipped": c.setpoints_skipped,
            "carrier_hz": round(self.carrier_hz, 2), "carrier_changes": c.carrier_changes,
            "output": "cut by the device" if self._cut else ("streaming" if self._output_on else "idle (disabled)"),
            "idle_rests": c.idle_rests,
            "protocol_version": None if self.device is None else self.device.version,
            "device_name": None if self.device is None else self.device.name,
            "limit_um_pp": self.limit_um_pp, "max_drive_um_pp": self.max_drive_um_pp,
            "device_full_scale_um_pp": self.full_scale_um_pp, "notes": list(self.notes),
            "measured_um_pp": None if t is None else t.measured_um_pp,
            "device_frames_ok": None if t is None else t.frames_ok,
            "device_crc_errors": None if t is None else t.crc_errors,
            "device_lost_setpoints": None if t is None else t.lost_setpoints,
            "device_late_setpoints": None if t is None else t.late_setpoints,
            "faults": faults,
            "device_faults": [name for name, count in faults.items() if count],
            "report": report.as_dict(),
            **({"tracking": self.tracker.summary()} if self.tracker is not None else {}),
        }
