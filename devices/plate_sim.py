"""The simulated plate: the device side of the protocol, served on a real pseudo-terminal.

It behaves as plate-driver firmware would: answers the handshake, plays amplitude setpoints at
their rate from a jitter buffer through the plate's first-order envelope dynamics (tau = Q / pi f0),
holds the last value when the buffer runs dry, clamps to full scale, faults and rests if the
amplitude ever exceeds the plate's safe maximum, ramps to zero when nothing has been heard for
100 ms (watchdog), and reports telemetry 50 times a second.

For tests it injects faults: dropped or corrupted incoming bytes, a hang (no reading, no
telemetry), and a disconnect (the port disappears, then comes back at the same path).

The port is a pty; because a pty's name changes when it is re-created, :class:`PtyPlate` serves it
behind a stable symlink, which is the path to give the driver.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import tempfile
import threading
import time
import tty
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import PlateProfile

TICK_S = 0.002
TELEMETRY_S = 0.02
WATCHDOG_S = 0.1
WATCHDOG_RAMP_S = 0.02
BUFFER_LIMIT_S = 0.25  # setpoints beyond this much playing time are dropped (overrun)
PREFILL_S = 0.004  # after running dry, play again only once this much is buffered (jitter buffer)


@dataclass
class SimCounters:
    frames_ok: int = 0
    crc_errors: int = 0
    framing_errors: int = 0
    underruns: int = 0
    overruns: int = 0
    setpoints: int = 0
    lost_setpoints: int = 0  # gaps in the setpoint index: frames that never arrived
    watchdog_trips: int = 0
    faults_injected: dict = field(default_factory=dict)


class PlateSimulator:
    """Protocol handling and plate physics, independent of the transport: bytes in, bytes out."""

    def __init__(self, profile: PlateProfile, name: str = "ultraglide plate simulator"):
        self.profile = profile
        self.name = name
        self.decoder = p.FrameDecoder()
        self.counters = SimCounters()
        self.enabled = False
        self.carrier_hz = profile.resonance_hz
        self.rate_hz = 12000
        self._buffer = np.zeros(0)
        self._next_index: int | None = None
        self._last_value = 0.0  # the setpoint now playing, fraction of full scale
        self._starved = True  # waiting for the jitter buffer to fill
        self._plate_state = 0.0  # the plate's amplitude, µm p-p
        self._watchdog_gain = 1.0
        self._faults = 0  # latched until the next telemetry
        self._heard = time.monotonic()
        self._clock = time.monotonic()
        self._owed = 0.0  # fractional samples not yet played
        self._telemetry_due = self._clock
        self._seq = 0
        self.amplitude_um_pp = 0.0
        self.peak_um_pp = 0.0
        self.fault_requests: list[tuple[int, float]] = []

    # ---- bytes in ------------------------------------------------------------------------------
    def receive(self, data: bytes) -> list[bytes]:
        """Feed received bytes; returns the frames to send back."""
        replies = []
        for frame in self.decoder.feed(data):
            self._heard = time.monotonic()
            replies += self._handle(frame)
        self.counters.frames_ok = self.decoder.frames
        self.counters.crc_errors = self.decoder.crc_errors
        self.counters.framing_errors = self.decoder.framing_errors
        return replies

    def _reply(self, kind: int, payload: bytes) -> bytes:
        self._seq += 1
        return p.encode_frame(kind, self._seq, payload)

    def _handle(self, frame: p.Frame) -> list[bytes]:
        try:
            if frame.kind == p.HELLO:
                reply = p.HelloReply(p.PROTOCOL_VERSION, self.profile.resonance_hz, self.profile.full_scale_um_pp,
                                     self.profile.max_amplitude_um_pp, 48000, self.name)
                return [self._reply(p.HELLO_REPLY, p.hello_reply_payload(reply))]
            if frame.kind == p.SET_CARRIER:
                (carrier,) = np.frombuffer(frame.payload, "<f4", count=1)
                ok = self.profile.carrier_min_hz <= carrier <= self.profile.carrier_max_hz
                if ok:
                    self.carrier_hz = float(carrier)
                return [self._reply(p.ACK, p.ack_payload(frame.seq, p.ACK_OK if ok else p.ACK_BAD_VALUE))]
            if frame.kind == p.ENABLE:
                self.enabled = bool(frame.payload[:1] == b"\x01")
                if not self.enabled:
                    self._buffer = np.zeros(0)
                    self._last_value = 0.0
                    self._starved = True
                return [self._reply(p.ACK, p.ack_payload(frame.seq, p.ACK_OK))]
            if frame.kind == p.SETPOINTS:
                self._take_setpoints(*p.parse_setpoints(frame.payload))
                return []
            if frame.kind == p.HEARTBEAT:
                return []
            if frame.kind == p.SIM_FAULT:  # the transport (PtyPlate) owns the bytes: it acts on these
                kind, duration_ms = int(frame.payload[0]), int.from_bytes(frame.payload[1:3], "little")
                self.fault_requests.append((kind, duration_ms / 1000.0))
                return [self._reply(p.ACK, p.ack_payload(frame.seq, p.ACK_OK))]
        except (p.ProtocolError, ValueError):
            pass
        self._faults |= p.FAULT_BAD_COMMAND
        return [self._reply(p.ACK, p.ack_payload(frame.seq, p.ACK_UNSUPPORTED))]

    def _take_setpoints(self, first: int, rate: int, values: np.ndarray) -> None:
        if rate != self.rate_hz and 1000 <= rate <= 48000:
            self.rate_hz = rate
        if self._next_index is not None and first != self._next_index:
            gap = (first - self._next_index) & 0xFFFFFFFF
            if gap < 1 << 31:
                self.counters.lost_setpoints += gap
        self._next_index = (first + len(values)) & 0xFFFFFFFF
        self.counters.setpoints += len(values)
        room = int(BUFFER_LIMIT_S * self.rate_hz) - len(self._buffer)
        if room < len(values):
            self.counters.overruns += 1
            self._faults |= p.FAULT_OVERRUN
            values = values[:max(room, 0)]
        self._buffer = np.concatenate((self._buffer, values))

    # ---- time passes ---------------------------------------------------------------------------
    def advance(self, now: float | None = None) -> list[bytes]:
        """Play the setpoints due by ``now`` through the plate; returns telemetry frames due."""
        now = time.monotonic() if now is None else now
        self._owed += (now - self._clock) * self.rate_hz
        self._clock = now
        n = int(self._owed)
        self._owed -= n
        if n > 0:
            self._play(n, now)
        if now >= self._telemetry_due:
            self._telemetry_due = now + TELEMETRY_S
            return [self._reply(p.TELEMETRY, p.telemetry_payload(self.telemetry()))]
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
                    self._faults |= p.FAULT_UNDERRUN
            played = np.concatenate((played, np.full(n - len(played), self._last_value)))
        if len(played):
            self._last_value = float(played[-1])
        if now - self._heard > WATCHDOG_S:
            if self._watchdog_gain == 1.0:
                self.counters.watchdog_trips += 1
            self._faults |= p.FAULT_WATCHDOG
            step = n / (WATCHDOG_RAMP_S * self.rate_hz)
            gains = np.maximum(self._watchdog_gain - step * np.arange(1, n + 1) / n, 0.0)
            self._watchdog_gain = float(gains[-1])
            self._buffer = np.zeros(0)
            self._last_value = 0.0
            self._starved = True
        else:
            gains = 1.0
            self._watchdog_gain = 1.0
        drive = np.clip(played, 0.0, 1.0) * gains * self.profile.full_scale_um_pp
        if not self.enabled:
            drive = np.zeros(n)
        alpha = math.exp(-1.0 / (self.rate_hz * self.profile.time_constant_s))
        amplitude, _ = lfilter([1.0 - alpha], [1.0, -alpha], drive, zi=[alpha * self._plate_state])
        over = np.flatnonzero(amplitude > self.profile.max_amplitude_um_pp * 1.01)
        if len(over):  # firmware checks every sample: cut the drive there and rest the plate
            drive[over[0]:] = 0.0
            amplitude, _ = lfilter([1.0 - alpha], [1.0, -alpha], drive, zi=[alpha * self._plate_state])
            self._faults |= p.FAULT_OVER_AMPLITUDE
            self.enabled = False
            self._buffer = np.zeros(0)
        self._plate_state = float(amplitude[-1])
        self.amplitude_um_pp = self._plate_state
        self.peak_um_pp = max(self.peak_um_pp, float(amplitude.max()))

    def telemetry(self) -> p.Telemetry:
        faults, self._faults = self._faults, 0
        c = self.counters
        return p.Telemetry(self.amplitude_um_pp, self.carrier_hz, faults, c.frames_ok, c.crc_errors,
                           c.framing_errors, c.underruns, c.setpoints, self.enabled)


class PtyPlate:
    """A :class:`PlateSimulator` served on a pseudo-terminal behind a stable symlink, in a thread."""

    def __init__(self, profile: PlateProfile, link_path: str | None = None):
        self.simulator = PlateSimulator(profile)
        self._own_dir = None
        if link_path is None:
            self._own_dir = tempfile.mkdtemp(prefix="ultraglide-plate-")
            link_path = os.path.join(self._own_dir, "plate")
        self.path = link_path
        self.pty_name = ""
        self._master = -1
        self._slave = -1
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._drop_until = 0.0
        self._corrupt_until = 0.0
        self._hang_until = 0.0
        self._disconnect_until = 0.0
        self._rng = np.random.default_rng(0)

    def _open_pty(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line discipline: a byte pipe like a USB serial port
        self.pty_name = os.ttyname(self._slave)
        temporary = self.path + ".new"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        os.symlink(self.pty_name, temporary)
        os.replace(temporary, self.path)

    def _close_pty(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    def start(self) -> PtyPlate:
        self._open_pty()
        self._thread = threading.Thread(target=self._serve, name="plate-sim", daemon=True)
        self._thread.start()
        return self

    def inject(self, kind: int, duration_s: float) -> None:
        """Inject a fault now: SIM_DROP, SIM_CORRUPT, SIM_HANG or SIM_DISCONNECT."""
        until = time.monotonic() + duration_s
        name = {p.SIM_DROP: "drop", p.SIM_CORRUPT: "corrupt", p.SIM_HANG: "hang", p.SIM_DISCONNECT: "disconnect"}
        injected = self.simulator.counters.faults_injected
        injected[name[kind]] = injected.get(name[kind], 0) + 1
        if kind == p.SIM_DROP:
            self._drop_until = until
        elif kind == p.SIM_CORRUPT:
            self._corrupt_until = until
        elif kind == p.SIM_HANG:
            self._hang_until = until
        elif kind == p.SIM_DISCONNECT:
            self._disconnect_until = until

    def _serve(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            if now < self._disconnect_until:
                if self._master >= 0:
                    self._close_pty()
                time.sleep(TICK_S)
                continue
            if self._master < 0:
                self._open_pty()
            if now < self._hang_until:
                time.sleep(TICK_S)
                self.simulator.advance()
                continue
            ready, _, _ = select.select([self._master], [], [], TICK_S)
            replies = []
            if ready:
                try:
                    data = os.read(self._master, 65536)
                except OSError:  # the other side closed: wait for the next opener
                    data = b""
                    time.sleep(TICK_S)
                if data:
                    replies += self._incoming(data)
            replies += self.simulator.advance()
            for reply in replies:
                if self._master < 0:
                    break
                with contextlib.suppress(OSError):
                    os.write(self._master, reply)
        self._close_pty()

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
        while self.simulator.fault_requests:
            self.inject(*self.simulator.fault_requests.pop(0))
        return replies

    def stop(self) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(timeout=2)
        self._close_pty()
        if self._own_dir:
            with contextlib.suppress(OSError):
                os.rmdir(self._own_dir)
