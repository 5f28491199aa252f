"""The simulated plate: the device side of protocol v2, served on a real pseudo-terminal.

It behaves as plate-driver firmware would (docs/protocol.md is normative): answers the handshake,
plays amplitude setpoints at their rate from a jitter buffer through the plate's resonant envelope
dynamics, holds the last value when the buffer runs dry, discards setpoints while disabled, trips
(cuts the drive and disables) if the measured amplitude exceeds the plate's safe maximum, ramps to
zero when nothing has been heard for 100 ms while enabled (watchdog), latches and counts faults, and
reports telemetry 50 times a second. No frame, whatever its content, stops it: each is answered
(ACK, NAK or nothing) and the handler's own failures become NAK "internal".

Its physical truth may differ from the profile the host believes (:class:`PlateTruth`): the real
resonance f0 (drifting D Hz/s) and Q give a steady gain 1/sqrt(1 + (2Q(fc - f0)/f0)²) at carrier fc
and an envelope time constant Q/(pi f0); telemetry reports the amplitude that results.

For tests it injects faults: dropped or corrupted incoming bytes, a hang (the frame handler stops:
no reading, no telemetry; the watchdog, on its own thread, still rests the plate), a disconnect
(the port disappears, then comes back at the same path), and an overheat.

The port is a pty; because a pty's name changes when it is re-created, :class:`PtyPlate` serves it
behind a stable symlink, which is the path to give the driver.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import math
import os
import queue
import select
import tempfile
import threading
import time
import tty
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile

TICK_S = 0.002  # the output stage's clock while it has work: enabled, or the plate still moving
LISTEN_S = 0.02  # the frame handler's longest wait for bytes (it wakes on them at once)
REST_UM_PP = 1e-6  # below this a disabled plate is at rest: the output stage wakes only for telemetry
TELEMETRY_S = 1.0 / p.TELEMETRY_HZ
WATCHDOG_S = p.WATCHDOG_MS / 1000.0
WATCHDOG_RAMP_S = p.WATCHDOG_RAMP_MS / 1000.0
BUFFER_LIMIT_S = p.BUFFER_MS / 1000.0
PREFILL_S = p.PREFILL_MS / 1000.0
STALL_S = 0.02  # the output thread woke this late: the whole simulator was descheduled (a loaded machine)
STREAM_GAP_S = 0.05  # no setpoints for this long: the stream has stopped (an event, not a fault)
MIN_RATE_HZ, MAX_RATE_HZ = 1000, 48000
MAX_EVENTS = 10000  # events kept for a reader (plate-sim prints them); beyond that they are counted, not kept


@dataclass(frozen=True)
class PlateTruth:
    """The simulated plate's real resonance (Hz, drifting by ``drift_hz_per_s``) and quality factor."""

    resonance_hz: float
    q: float
    drift_hz_per_s: float = 0.0

    @classmethod
    def of(cls, profile: PlateProfile) -> PlateTruth:
        return cls(profile.resonance_hz, profile.q)

    def resonance_at(self, elapsed_s: float) -> float:
        return max(self.resonance_hz + self.drift_hz_per_s * elapsed_s, 1.0)  # a long drift down stops at 1 Hz

    def gain(self, carrier_hz: float, elapsed_s: float) -> float:
        """Steady amplitude at ``carrier_hz`` relative to that at resonance."""
        f0 = self.resonance_at(elapsed_s)
        return 1.0 / math.sqrt(1.0 + (2.0 * self.q * (carrier_hz - f0) / f0) ** 2)

    def time_constant_s(self, elapsed_s: float) -> float:
        return self.q / (math.pi * self.resonance_at(elapsed_s))


@dataclass
class SimCounters:
    frames_ok: int = 0
    crc_errors: int = 0
    framing_errors: int = 0
    underruns: int = 0
    overruns: int = 0
    setpoints: int = 0
    lost_setpoints: int = 0  # gaps in the setpoint index: frames that never arrived
    late_setpoints: int = 0  # behind the stream: already played or repeated
    discarded_setpoints: int = 0  # arrived while disabled
    watchdog_trips: int = 0
    naks: int = 0
    handler_errors: int = 0  # exceptions in frame handling, answered NAK internal
    fault_counts: list = field(default_factory=lambda: [0] * p.FAULT_BITS)
    faults_injected: dict = field(default_factory=dict)


class PlateSimulator:
    """Protocol handling and plate physics, independent of the transport: bytes in, bytes out.

    ``receive`` (the frame handler) and ``advance`` (the output stage and watchdog) may run on
    different threads; a lock held for a frame's handling or one block's physics keeps them apart.
    Events (``connected``, ``enabled``, ``fault`` …, each a dict with ``t_s`` and ``event``) go to the
    bounded queue ``events``.
    """

    def __init__(self, profile: PlateProfile, name: str = "ultraglide plate simulator",
                 truth: PlateTruth | None = None):
        self.profile = profile
        self.truth = truth or PlateTruth.of(profile)
        self.name = name
        self.decoder = p.FrameDecoder()
        self.counters = SimCounters()
        self.events: queue.Queue = queue.Queue(MAX_EVENTS)  # bounded: nobody need drain it
        self.events_dropped = 0
        self.enabled = False
        self.carrier_hz = profile.resonance_hz
        self.rate_hz = 12000
        self._lock = threading.Lock()
        self._over_limit = False  # the measured amplitude is above the safe maximum (below the trip)
        self._stream_rate: int | None = None  # set by the first SETPOINTS after ENABLE 1
        self._buffer = np.zeros(0)
        self._next_index: int | None = None
        self._last_value = 0.0  # the setpoint now playing, fraction of full scale
        self._starved = True  # waiting for the jitter buffer to fill
        self._plate_state = 0.0  # the plate's amplitude, µm p-p
        self._watchdog_gain = 1.0
        self._faults = 0  # latched until CLEAR_FAULTS
        self._started = time.perf_counter()
        self._heard = self._started
        self._clock = self._started
        self._owed = 0.0  # fractional samples not yet played
        self._telemetry_due = self._clock
        self._streaming = False
        self._last_setpoints = 0.0
        self._seq = 0
        self.amplitude_um_pp = 0.0
        self.peak_um_pp = 0.0
        self.fault_requests: list[tuple[int, float]] = []

    # ---- events and faults -----------------------------------------------------------------------
    def elapsed_s(self) -> float:
        """Seconds since the simulator started: the time base of its events."""
        return time.perf_counter() - self._started

    def _event(self, event: str, now: float | None = None, **fields) -> None:
        now = time.perf_counter() if now is None else now
        try:
            self.events.put_nowait({"t_s": round(now - self._started, 4), "event": event, **fields})
        except queue.Full:
            self.events_dropped += 1

    def _fault(self, bit: int, now: float | None = None, **fields) -> None:
        self._faults |= bit
        self.counters.fault_counts[bit.bit_length() - 1] += 1
        name = p.FAULT_NAMES[bit]
        self._event("watchdog" if bit == p.FAULT_WATCHDOG else "fault", now, fault=name, **fields)

    def excuse(self, stalled_s: float) -> None:
        """The simulator itself did not run for ``stalled_s``: that time is not the host's silence."""
        with self._lock:
            self._heard = min(self._heard + stalled_s, time.perf_counter())

    def fault_counts(self) -> dict[str, int]:
        return {name: self.counters.fault_counts[bit.bit_length() - 1] for bit, name in p.FAULT_NAMES.items()}

    def _disable(self, why: str, now: float | None = None) -> None:
        was = self.enabled
        self.enabled = False
        self._buffer = np.zeros(0)
        self._last_value = 0.0
        self._starved = True
        self._stop_stream(now)
        if was:
            self._event("disabled", now, reason=why)

    def _stop_stream(self, now: float | None = None) -> None:
        if self._streaming:
            self._streaming = False
            self._event("stream_stopped", now)

    # ---- bytes in ------------------------------------------------------------------------------
    def receive(self, data: bytes) -> list[bytes]:
        """Feed received bytes; returns the frames to send back."""
        replies = []
        frames = self.decoder.feed(data)
        for frame in frames:
            with self._lock:
                self._heard = time.perf_counter()
                try:
                    reply = self._handle(frame)
                except Exception as error:  # a bug must not kill the device: answer, count, carry on
                    self.counters.handler_errors += 1
                    self._event("handler_error", error=f"{type(error).__name__}: {error}")
                    reply = self._nak(frame, p.NAK_INTERNAL)
                if reply is not None:
                    replies.append(reply)
        self.counters.frames_ok = self.decoder.frames
        self.counters.crc_errors = self.decoder.crc_errors
        self.counters.framing_errors = self.decoder.framing_errors
        return replies

    def _reply(self, kind: int, payload: bytes) -> bytes:
        self._seq = (self._seq + 1) & 0xFFFF
        return p.encode_frame(kind, self._seq, payload)

    def _ack(self, frame: p.Frame) -> bytes:
        return self._reply(p.ACK, p.ack_payload(frame.seq))

    def _nak(self, frame: p.Frame, reason: int) -> bytes:
        self.counters.naks += 1
        self._fault(p.FAULT_BAD_COMMAND, command=frame.kind, reason=p.NAK_REASONS[reason])
        return self._reply(p.NAK, p.nak_payload(frame.seq, reason))

    def _handle(self, frame: p.Frame) -> bytes | None:
        kind, payload = frame.kind, frame.payload
        if kind not in p.HOST_COMMANDS:
            return self._nak(frame, p.NAK_UNKNOWN_TYPE)
        if kind in p.PAYLOAD_LENGTHS and len(payload) != p.PAYLOAD_LENGTHS[kind]:
            return self._nak(frame, p.NAK_BAD_LENGTH)
        if kind == p.HELLO:
            return self._hello(frame)
        if kind == p.SET_CARRIER:
            carrier = p.parse_carrier(payload)
            if not (math.isfinite(carrier) and self.profile.carrier_min_hz <= carrier <= self.profile.carrier_max_hz):
                return self._nak(frame, p.NAK_BAD_VALUE)
            self.carrier_hz = float(carrier)
            self._event("carrier", carrier_hz=round(self.carrier_hz, 3))
            return self._ack(frame)
        if kind == p.ENABLE:
            if payload[0] not in (0, 1):
                return self._nak(frame, p.NAK_BAD_VALUE)
            if payload[0] == 1:
                if not self.enabled:
                    self.enabled = True
                    self._buffer = np.zeros(0)  # nothing sent while disabled is ever replayed
                    self._starved = True
                    self._next_index = None  # a new stream: its first index is not a gap
                    self._stream_rate = None
                    self._watchdog_gain = 1.0
                    self._event("enabled")
            else:
                self._disable("host")
            return self._ack(frame)
        if kind == p.SETPOINTS:
            return self._setpoints(frame)
        if kind == p.HEARTBEAT:
            return None
        if kind == p.CLEAR_FAULTS:
            self._faults &= ~p.parse_clear_faults(payload)
            return self._ack(frame)
        return self._sim_fault(frame)

    def _hello(self, frame: p.Frame) -> bytes:
        # the host's highest version; this device speaks only v2, and says so whatever was asked
        reply = p.HelloReply(2, self.profile.resonance_hz, self.profile.full_scale_um_pp,
                             self.profile.max_amplitude_um_pp, MIN_RATE_HZ, MAX_RATE_HZ, self.profile.carrier_min_hz,
                             self.profile.carrier_max_hz, p.WATCHDOG_MS, p.BUFFER_MS, self.name)
        self._event("hello", host_version=frame.payload[0])
        return self._reply(p.HELLO_REPLY, p.hello_reply_payload(reply))

    def _sim_fault(self, frame: p.Frame) -> bytes:
        kind, duration_ms = p.parse_sim_fault(frame.payload)
        if kind not in p.SIM_FAULT_KINDS or duration_ms > p.MAX_SIM_FAULT_MS:
            return self._nak(frame, p.NAK_BAD_VALUE)
        if kind == p.SIM_OVERHEAT:
            self._count_injected("overheat")
            self._fault(p.FAULT_OVERHEAT)
            self._disable("overheat")
        else:  # the transport (PtyPlate) owns the bytes: it acts on these
            self.fault_requests.append((kind, duration_ms / 1000.0))
        return self._ack(frame)

    def _count_injected(self, name: str) -> None:
        injected = self.counters.faults_injected
        injected[name] = injected.get(name, 0) + 1

    def _setpoints(self, frame: p.Frame) -> bytes | None:
        try:
            first, rate, codes = p.parse_setpoint_codes(frame.payload)
        except p.ProtocolError:
            return self._nak(frame, p.NAK_BAD_LENGTH)
        if not 1 <= len(codes) <= p.MAX_SETPOINTS_PER_FRAME or not MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
            return self._nak(frame, p.NAK_BAD_VALUE)
        if not self.enabled:
            self.counters.discarded_setpoints += len(codes)
            return None
        if self._stream_rate is None:
            self._stream_rate = self.rate_hz = rate
        elif rate != self._stream_rate:
            return self._nak(frame, p.NAK_BAD_VALUE)
        values = codes.astype(float) / p.SETPOINT_SCALE
        if self._next_index is not None and first != self._next_index:
            gap = (first - self._next_index) & 0xFFFFFFFF
            if gap < 1 << 31:
                self.counters.lost_setpoints += gap
            else:  # behind the stream: what was already taken is late
                behind = min((1 << 32) - gap, len(values))
                self.counters.late_setpoints += behind
                values = values[behind:]
                first = (first + behind) & 0xFFFFFFFF
        if not len(values):
            return None
        self._next_index = (first + len(values)) & 0xFFFFFFFF
        self.counters.setpoints += len(values)
        room = int(BUFFER_LIMIT_S * self.rate_hz) - len(self._buffer)
        if room < len(values):
            self.counters.overruns += 1
            self._fault(p.FAULT_OVERRUN)
            values = values[:max(room, 0)]
        self._buffer = np.concatenate((self._buffer, values))
        self._last_setpoints = time.perf_counter()
        if not self._streaming:
            self._streaming = True
            self._event("stream_started", rate_hz=rate)
        return None

    # ---- time passes ---------------------------------------------------------------------------
    def advance(self, now: float | None = None, telemetry: bool = True) -> list[bytes]:
        """Play the setpoints due by ``now`` through the plate and run the watchdog; returns the telemetry
        frames due (none when ``telemetry`` is false: a hung device says nothing)."""
        with self._lock:
            now = time.perf_counter() if now is None else now
            self._owed += (now - self._clock) * self.rate_hz
            self._clock = now
            n = int(self._owed)
            self._owed -= n
            if n > 0 and not self.enabled and self._plate_state <= REST_UM_PP and len(self._buffer) == 0:
                self._plate_state = self.amplitude_um_pp = 0.0  # disabled and still: nothing to play or watch
            elif n > 0:
                self._play(n, now)
            if self._streaming and now - self._last_setpoints > STREAM_GAP_S:
                self._stop_stream(now)
            if now >= self._telemetry_due:
                self._telemetry_due = now + TELEMETRY_S
                if telemetry:
                    return [self._reply(p.TELEMETRY, p.telemetry_payload(self.telemetry(), 2))]
            return []

    def _play(self, n: int, now: float) -> None:
        if self._starved and len(self._buffer) >= PREFILL_S * self.rate_hz:
            self._starved = False
        if self._starved:
            played = np.zeros(0)
        else:
            played = self._buffer[:n]
            self._buffer = self._buffer[n:]
        if len(played) < n:
            if not self._starved:
                self._starved = True
                if self.enabled:
                    self.counters.underruns += 1
                    self._fault(p.FAULT_UNDERRUN, now)
            # a held overdrive (pre-compensation above the steady limit) would carry the plate past its
            # limit: the held value is capped at the limit's share of full scale
            hold = min(self._last_value, self.profile.max_amplitude_um_pp / self.profile.full_scale_um_pp)
            played = np.concatenate((played, np.full(n - len(played), hold)))
        if len(played):
            self._last_value = float(played[-1])
        if self.enabled and now - self._heard > WATCHDOG_S:  # armed only while enabled
            if self._watchdog_gain == 1.0:
                self.counters.watchdog_trips += 1
                self._fault(p.FAULT_WATCHDOG, now)
                self._stop_stream(now)
            step = n / (WATCHDOG_RAMP_S * self.rate_hz)
            gains = np.maximum(self._watchdog_gain - step * np.arange(1, n + 1) / n, 0.0)
            self._watchdog_gain = float(gains[-1])
            self._buffer = np.zeros(0)
            self._last_value = 0.0
            self._starved = True
        else:
            gains = 1.0
            self._watchdog_gain = 1.0
        elapsed = now - self._started
        gain = self.truth.gain(self.carrier_hz, elapsed)
        drive = np.clip(played, 0.0, 1.0) * gains * self.profile.full_scale_um_pp
        if not self.enabled:
            drive = np.zeros(n)
        alpha = math.exp(-1.0 / (self.rate_hz * self.truth.time_constant_s(elapsed)))
        amplitude, _ = lfilter([(1.0 - alpha) * gain], [1.0, -alpha], drive, zi=[alpha * self._plate_state])
        above = amplitude > self.profile.max_amplitude_um_pp
        if above.any() or self._over_limit:  # each excursion above the safe maximum is one over-limit
            edges = np.flatnonzero(above[1:] & ~above[:-1]).size + int(above[0] and not self._over_limit)
            for _ in range(edges):
                self._fault(p.FAULT_OVER_LIMIT, now, measured_um_pp=round(float(amplitude.max()), 4))
        limit = self.profile.max_amplitude_um_pp * (1.0 + p.TRIP_MARGIN)
        over = np.flatnonzero(amplitude > limit)
        if len(over):  # firmware checks every sample: cut the drive there and rest the plate
            measured = float(amplitude[over[0]])
            drive[over[0]:] = 0.0
            amplitude, _ = lfilter([(1.0 - alpha) * gain], [1.0, -alpha], drive, zi=[alpha * self._plate_state])
            self._fault(p.FAULT_TRIP, now, measured_um_pp=round(measured, 4))
            self._disable("trip", now)
        self._plate_state = float(amplitude[-1])
        self._over_limit = self._plate_state > self.profile.max_amplitude_um_pp
        self.amplitude_um_pp = self._plate_state
        self.peak_um_pp = max(self.peak_um_pp, float(amplitude.max()))

    def next_wake_s(self, now: float) -> float:
        """How long the output stage may sleep from ``now`` (s): one tick while enabled or while the plate
        still moves; otherwise until the next telemetry frame (the plate at rest, disabled, has nothing
        else to do; ENABLE wakes it early, see :class:`PtyPlate`)."""
        if self.enabled or self._plate_state > REST_UM_PP:
            return TICK_S
        return min(max(self._telemetry_due - now, 0.0), TELEMETRY_S)

    def telemetry(self) -> p.Telemetry:
        c = self.counters
        return p.Telemetry(self.amplitude_um_pp, self.carrier_hz, self._faults, self.enabled, c.frames_ok,
                           c.crc_errors, c.framing_errors, c.setpoints, c.lost_setpoints, c.late_setpoints,
                           c.discarded_setpoints, tuple(c.fault_counts))


class PtyPlate:
    """A :class:`PlateSimulator` served on a pseudo-terminal behind a stable symlink.

    Two threads: the frame handler (reads the port, answers frames) and the output stage (plays
    setpoints, runs the watchdog, sends telemetry), so a hung handler still rests the plate. The
    pty's slave side is not held open here, so the master sees who is connected (EIO when nobody is).
    """

    def __init__(self, profile: PlateProfile, link_path: str | None = None, truth: PlateTruth | None = None):
        self.simulator = PlateSimulator(profile, truth=truth)
        self._own_dir = None
        if link_path is None:
            self._own_dir = tempfile.mkdtemp(prefix="ultraglide-plate-")
            link_path = os.path.join(self._own_dir, "plate")
        directory = os.path.dirname(os.path.abspath(link_path))
        if not os.path.isdir(directory):
            raise DeviceError(f"no directory {directory} for the plate's link {link_path}: create it or choose "
                              "another --link")
        self.path = link_path
        self.pty_name = ""
        self._master = -1
        self._port_lock = threading.Lock()
        self._input_lock = threading.Lock()  # bytes read and decoded in order, by whichever thread takes them
        self._client = False
        self._stop = threading.Event()
        self._wake = threading.Event()  # the output stage's sleep ends early: stop, or the output enabled
        self._sleeping_long = False  # the output stage waits for telemetry, not the next tick
        self._threads: list[threading.Thread] = []
        self._drop_until = 0.0
        self._corrupt_until = 0.0
        self._hang_until = 0.0
        self._disconnect_until = 0.0
        self._rng = np.random.default_rng(0)
        self.dropped_replies = 0  # written while the port's buffer was full (nobody reading)

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: a byte pipe like a USB serial port
        name = os.ttyname(slave)
        os.close(slave)
        fcntl.fcntl(master, fcntl.F_SETFL, fcntl.fcntl(master, fcntl.F_GETFL) | os.O_NONBLOCK)
        temporary = self.path + ".new"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        os.symlink(name, temporary)
        os.replace(temporary, self.path)
        with self._port_lock:
            self._master, self.pty_name = master, name

    def _close_pty(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
        with self._port_lock:
            master, self._master = self._master, -1
            if master >= 0:
                with contextlib.suppress(OSError):
                    os.close(master)
        self._set_client(False)

    def _set_client(self, present: bool) -> None:
        if present != self._client:
            self._client = present
            self.simulator._event("connected" if present else "disconnected", pty=self.pty_name)

    def start(self) -> PtyPlate:
        self._open_pty()
        for target, name in ((self._serve_frames, "plate-sim-frames"), (self._serve_output, "plate-sim-output")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    @property
    def alive(self) -> bool:
        """Both threads serving."""
        return bool(self._threads) and all(thread.is_alive() for thread in self._threads)

    def inject(self, kind: int, duration_s: float) -> None:
        """Inject a fault now: SIM_DROP, SIM_CORRUPT, SIM_HANG, SIM_DISCONNECT (for ``duration_s``) or SIM_OVERHEAT."""
        if kind == p.SIM_OVERHEAT:
            with self.simulator._lock:
                self.simulator._sim_fault(p.Frame(p.SIM_FAULT, 0, p.sim_fault_payload(kind)))
            return
        until = time.monotonic() + duration_s
        self.simulator._count_injected(p.SIM_FAULT_KINDS[kind])
        if kind == p.SIM_DROP:
            self._drop_until = until
        elif kind == p.SIM_CORRUPT:
            self._corrupt_until = until
        elif kind == p.SIM_HANG:
            self._hang_until = until
        elif kind == p.SIM_DISCONNECT:
            self._disconnect_until = until

    def end_injected(self) -> None:
        """End every injected transport fault now."""
        self._drop_until = self._corrupt_until = self._hang_until = self._disconnect_until = 0.0

    def _write(self, frames: list[bytes]) -> None:
        with self._port_lock:
            for frame in frames:
                if self._master < 0:
                    return
                try:
                    os.write(self._master, frame)
                except BlockingIOError:  # nobody reads and the pty's buffer is full: like a UART, drop it
                    self.dropped_replies += 1
                except OSError:
                    return

    def _serve_frames(self) -> None:
        """The frame handler's thread: read, decode, answer. Never ends before stop()."""
        while not self._stop.is_set():
            try:
                self._serve_once()
            except Exception as error:  # keep serving whatever happened; say what it was
                self.simulator._event("handler_error", error=f"{type(error).__name__}: {error}")
                time.sleep(TICK_S)

    def _serve_once(self) -> None:
        now = time.monotonic()
        if now < self._disconnect_until:
            if self._master >= 0:
                self._close_pty()
            time.sleep(TICK_S)
            return
        if self._master < 0:
            self._open_pty()
        if now < self._hang_until:
            time.sleep(TICK_S)
            return
        ready, _, _ = select.select([self._master], [], [], LISTEN_S)
        if not ready and self._client:
            return
        with self._input_lock:
            try:
                data = os.read(self._master, 65536)
            except BlockingIOError:  # someone has the port open and is quiet (or the output stage took the bytes)
                self._set_client(True)
                return
            except OSError as error:
                if error.errno != errno.EIO:
                    raise
                self._set_client(False)  # nobody has the port open
                data = None
            if data is not None:
                self._set_client(True)
                self._write(self._incoming(data))
                return
        time.sleep(TICK_S)

    def _take_waiting_frames(self) -> None:
        """Frames already waiting on the link are handled before time advances, as a UART's interrupt
        comes before real firmware's output loop: a frame handler thread that has not been scheduled yet
        (a loaded machine) is not the host's silence, and must not trip the watchdog."""
        now = time.monotonic()
        master = self._master
        if master < 0 or now < self._hang_until or now < self._disconnect_until:
            return
        with self._input_lock:
            try:
                ready, _, _ = select.select([master], [], [], 0)
                data = os.read(master, 65536) if ready else b""
            except OSError:  # nothing after all, nobody on the port, or the port just closed
                return
            if data:
                self._write(self._incoming(data))

    def _serve_output(self) -> None:
        """The output stage's thread: plays setpoints, runs the watchdog, sends telemetry.

        It ticks every ``TICK_S`` while the output is enabled or the plate still moves; a disabled plate
        at rest wakes only for telemetry (50 a second), or at once when a frame enables the output."""
        simulator = self.simulator
        wait = TICK_S
        planned = time.perf_counter() + wait
        while True:
            self._wake.wait(wait)
            if self._stop.is_set():
                return
            self._wake.clear()
            try:
                now = time.perf_counter()
                if now - planned > STALL_S - TICK_S:  # this process was not running: real firmware's clock stops too
                    simulator.excuse(now - planned)
                hung = time.monotonic() < self._hang_until
                self._take_waiting_frames()
                frames = simulator.advance(telemetry=not hung)
                if frames and self._client:
                    self._write(frames)
                wait = simulator.next_wake_s(time.perf_counter())
                self._sleeping_long = wait > TICK_S
            except Exception as error:
                simulator._event("output_error", error=f"{type(error).__name__}: {error}")
                wait = TICK_S
            planned = time.perf_counter() + wait

    def _incoming(self, data: bytes) -> list[bytes]:
        now = time.monotonic()
        if now < self._drop_until:
            return []
        if now < self._corrupt_until:
            corrupted = bytearray(data)
            flips = self._rng.integers(0, len(corrupted), max(1, len(corrupted) // 16))
            for index in flips:
                corrupted[index] ^= 1 << int(self._rng.integers(0, 8))
            data = bytes(corrupted)
        replies = self.simulator.receive(data)
        if self._sleeping_long and self.simulator.enabled:  # the output stage waits for telemetry: its clock starts now
            self._sleeping_long = False
            self._wake.set()
        while self.simulator.fault_requests:
            self.inject(*self.simulator.fault_requests.pop(0))
        return replies

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        for thread in self._threads:
            thread.join(timeout=2)
        self._close_pty()
        if self._own_dir:
            with contextlib.suppress(OSError):
                os.rmdir(self._own_dir)
