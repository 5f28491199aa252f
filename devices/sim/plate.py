"""The simulated plate: the firmware core (C, software in the loop) driving a resonator simulated here,
served on a real pseudo-terminal.

The device is the reference firmware itself: :class:`~ultraglide.devices.firmware.sil.FirmwareCore`, the C
core of ``devices/firmware`` built as a shared library, speaks protocol v3 (and v2) exactly as
docs/protocol.md states it: the handshake, the jitter buffer, the watchdog, the device's own limiter,
faults and counters, telemetry and SENSORS, the amplitude loop. What stays in Python is the plate's
physics (:class:`PlateTruth`) and the transport (:class:`PtyPlate`): the core renders its drive at 48 kHz,
the plate's envelope follows it through a first-order low-pass (its real resonance f0, drifting D Hz/s,
and Q give a steady gain 1/sqrt(1 + (2Q(fc - f0)/f0)²) at carrier fc and a time constant Q/(pi f0)),
computed block by block with scipy (no per-sample Python loop), and the amplitude it reaches goes back
to the core as the sensing piezo's measurement, with optional noise. The drive is signed: a negative one
is the carrier in antiphase (the firmware's brake). What the low-pass follows is the resonator's phasor
along the drive's phase, and the plate's amplitude is its magnitude: a phasor pulled through zero builds
vibration in the opposite phase, a larger amplitude, not a smaller one. (Off resonance a real resonator's
phasor also turns; the model keeps only its magnitude's steady gain and time constant.) A trip cuts the
drive at the sample where the core saw it (a comparator on the measurement): the rest of the block is
recomputed at zero drive.

Its physical truth may differ from the profile the firmware believes: another resonance, Q or full scale.
Force sensors come from a finger (``finger``, a :class:`ForceSource`), absent by default.

For tests it injects faults: dropped or corrupted incoming bytes, a hang (the frame handler stops: no
reading, no telemetry; the core's watchdog, ticked by the output thread, still rests the plate), a
disconnect (the port disappears, then comes back at the same path), and an overheat. ``breaks`` makes
the core break protocol rules on purpose (docs/protocol.md, Conformance), for testing ``plate check``.

The port is a pty; because a pty's name changes when it is re-created, :class:`PtyPlate` serves it
behind a stable symlink, which is the path to give the driver.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware import sil
from ultraglide.devices.output.kernels import first_order_filter
from ultraglide.devices.profiles import PlateProfile

TICK_S = 0.002  # the output stage's clock while it has work: enabled, or the plate still moving
LISTEN_S = 0.02  # the frame handler's longest wait for bytes (it wakes on them at once)
REST_UM_PP = 1e-6  # below this a disabled plate is at rest: the output stage wakes only for telemetry
TELEMETRY_S = 1.0 / p.TELEMETRY_HZ
STALL_S = 0.02  # the output thread woke this late: the whole simulator was descheduled (a loaded machine)
SAMPLE_RATE_HZ = 48000  # the firmware's drive samples a second (its DAC rate over its oversampling)
BLOCK = 96  # drive samples computed at once in open loop (2 ms): the physics' block
LOOP_BLOCK = 12  # ... with the amplitude loop on (0.25 ms): the loop's measurement comes a block late
DRAIN_SAMPLES = 480  # the core's bytes are taken every 10 ms of a long render
MAX_EVENTS = 10000  # events kept for a reader (plate-sim prints them); beyond that they are counted, not kept
# what the simulator states in HELLO_REPLY that its link carries (bytes/s): the 921 600 baud UART it stands in for
# (8N1: ten bits a byte), on which the host's default stream, 12 000 setpoints/s in 1 ms frames, takes 47 %
LINK_BYTES_PER_S = 92160


@dataclass(frozen=True)
class PlateTruth:
    """The simulated plate's real resonance (Hz, drifting by ``drift_hz_per_s``) and quality factor; its real
    full-scale amplitude (µm p-p at full drive on resonance; None: the profile's), the sensing piezo's
    noise (µm p-p rms, added to what the firmware measures) and how fast its crystal runs against the host's
    clock (parts per million; positive: it plays its setpoints faster than the host sends them)."""

    resonance_hz: float
    q: float
    drift_hz_per_s: float = 0.0
    full_scale_um_pp: float | None = None
    noise_um_pp: float = 0.0
    clock_ppm: float = 0.0

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


def resonator_phasor(drive: np.ndarray, start_um_pp: float, decay: float, gain_um_pp: float) -> np.ndarray:
    """The plate's phasor along the drive's phase (µm p-p, signed) after each drive sample (signed fractions of
    full scale, each held for one sample), from ``start_um_pp``: a first-order envelope decaying by ``decay`` a
    sample towards ``gain_um_pp`` times the drive (the slowly varying envelope of a resonator driven at its
    carrier, exact for a zero-order hold). The amplitude is its magnitude."""
    phasor, _ = first_order_filter([(1.0 - decay) * gain_um_pp], [1.0, -decay], drive, zi=[decay * start_um_pp])
    return phasor


class ForceSource(Protocol):
    """What presses on the plate (a simulated finger): normal and lateral force (N) for a block of samples
    at ``sample_rate_hz`` from ``t_s`` (s since the simulator started), given the plate's amplitude there."""

    def forces(self, t_s: float, amplitude_um_pp: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class SimCounters:
    """The device's counters (from the core) and the faults injected into it (here)."""

    frames_ok: int = 0
    crc_errors: int = 0
    framing_errors: int = 0
    underruns: int = 0
    overruns: int = 0
    setpoints: int = 0
    lost_setpoints: int = 0  # gaps in the setpoint index: frames that never arrived
    late_setpoints: int = 0  # behind the stream: already played or repeated
    discarded_setpoints: int = 0  # arrived while disabled
    overrun_setpoints: int = 0  # did not fit the buffer
    watchdog_trips: int = 0
    naks: int = 0
    handler_errors: int = 0  # exceptions in the simulator's own threads (the core has none)
    fault_counts: list = field(default_factory=lambda: [0] * p.FAULT_BITS)
    faults_injected: dict = field(default_factory=dict)


def _bit(name: str) -> int:
    return next(bit for bit, known in p.FAULT_NAMES.items() if known == name).bit_length() - 1


def split_frames(data: bytes) -> list[bytes]:
    """Bytes the core sent, split into frames (each with its 0x00)."""
    if not data:
        return []
    return [part + b"\x00" for part in data.split(b"\x00")[:-1] if part]


class PlateSimulator:
    """The firmware core and the plate's physics, independent of the transport: bytes in, bytes out.

    ``receive`` (the frame handler) and ``advance`` (the output stage: the core's drive through the plate,
    its ticks, its telemetry) may run on different threads; a lock held for each call keeps them apart.
    Events (``hello``, ``enabled``, ``fault`` …, each a dict with ``t_s`` and ``event``) go to the bounded
    queue ``events``. Time is the caller's: ``advance(now)`` renders the drive up to ``now``
    (perf_counter s); frames are handled at the time last advanced to, so frames that waited on the link
    while this process was descheduled are heard before the time that passed (as a UART's interrupt
    comes before real firmware's output loop). With ``real_time`` set (a pty), a valid frame feeds the
    watchdog at the real time it was read, however far the output stage lags.
    """

    def __init__(self, profile: PlateProfile, name: str = "ultraglide plate simulator",
                 truth: PlateTruth | None = None, breaks: tuple[str, ...] = (), max_version: int = 3,
                 finger: ForceSource | None = None, braking: bool = True, link_bytes_per_s: int = LINK_BYTES_PER_S):
        self.profile = profile
        self.truth = truth or PlateTruth.of(profile)
        self.name = name
        self.finger = finger
        sensors = p.SENSOR_AMPLITUDE | ((p.SENSOR_NORMAL_FORCE | p.SENSOR_LATERAL_FORCE) if finger else 0)
        features = p.FEATURE_AMPLITUDE_LOOP | (p.FEATURE_BRAKING if braking else 0) | \
            (p.FEATURE_FORCE_CORRECTION if finger else 0)
        self.core = sil.FirmwareCore(sil.CoreSettings.of(profile, name=name, breaks=tuple(breaks),
                                                         max_version=max_version, sensors=sensors,
                                                         sample_rate_hz=SAMPLE_RATE_HZ, features=features,
                                                         link_bytes_per_s=link_bytes_per_s))
        self.sample_rate_hz = SAMPLE_RATE_HZ
        self.events: queue.Queue = queue.Queue(MAX_EVENTS)  # bounded: nobody need drain it
        self.events_dropped = 0
        self.fault_requests: list[tuple[int, float]] = []
        self._injected: dict[str, int] = {}
        self._lock = threading.Lock()
        resonator_phasor(np.zeros(1), 0.0, 0.5, 1.0)  # its compiled filter loaded now (~0.3 s), not on the first drive
        self._started = time.perf_counter()
        if finger is not None and hasattr(finger, "set_clock_origin"):
            finger.set_clock_origin(self._started)  # its log's times on the host's clock: sample 0 is now
        self._clock = self._started
        self._clock_rate = 1.0 + self.truth.clock_ppm * 1e-6  # the core's samples a host's second
        self._owed = 0.0  # fractional drive samples not yet rendered
        self._plate_state = 0.0  # the plate's phasor along the drive's phase, µm p-p (its amplitude: the magnitude)
        self._rng = np.random.default_rng(0)
        self._noise = np.zeros(BLOCK)
        self.amplitude_um_pp = 0.0
        self.peak_um_pp = 0.0
        self.drive_range_um_pp = (0.0, 0.0)  # the lowest (braking) and highest drive the plate received
        self.real_time = False  # PtyPlate: frames arrive in real time, ahead of the clock last advanced to
        self.trace: list[np.ndarray] | None = None  # a list here collects the plate's amplitude, every sample
        self._sent: list[bytes] = []  # what the core sent during the present advance

    def __repr__(self) -> str:
        return (f"PlateSimulator({self.profile.name}: truth {self.truth.resonance_hz:g} Hz, Q {self.truth.q:g}; "
                f"{self.core!r})")

    # ---- events and faults -----------------------------------------------------------------------
    def elapsed_s(self) -> float:
        """Seconds since the simulator started: the time base of its events."""
        return time.perf_counter() - self._started

    def _event(self, event: str, now: float | None = None, **fields) -> None:
        """An event of the simulator's own (the transport's), at perf_counter time ``now``."""
        now = time.perf_counter() if now is None else now
        self._put({"t_s": round(now - self._started, 4), "event": event, **fields})

    def _put(self, event: dict) -> None:
        try:
            self.events.put_nowait(event)
        except queue.Full:
            self.events_dropped += 1

    def _take_events(self) -> None:
        """The core's events, in words (its sample clock is this simulator's time since it started)."""
        for e in self.core.events():
            fields: dict = {"t_s": round(e.sample / self.sample_rate_hz, 4)}
            if e.kind == sil.EV_HELLO:
                fields.update(event="hello", host_version=e.a)
            elif e.kind == sil.EV_CARRIER:
                fields.update(event="carrier", carrier_hz=round(e.value, 3))
            elif e.kind == sil.EV_ENABLED:
                fields.update(event="enabled")
            elif e.kind == sil.EV_DISABLED:
                fields.update(event="disabled", reason=sil.DISABLED_WHY.get(e.a, str(e.a)))
            elif e.kind == sil.EV_STREAM_STARTED:
                fields.update(event="stream_started", rate_hz=int(e.value))
            elif e.kind == sil.EV_STREAM_STOPPED:
                fields.update(event="stream_stopped")
            elif e.kind == sil.EV_FAULT:
                name = p.FAULT_NAMES.get(1 << e.a, f"bit {e.a}")
                fields.update(event="watchdog" if name == "watchdog" else "fault", fault=name)
                if name in ("over-limit", "trip"):
                    fields["measured_um_pp"] = round(e.value, 4)
                elif name == "bad-command":
                    fields.update(command=e.b >> 8, reason=p.NAK_REASONS.get(e.b & 0xFF, str(e.b & 0xFF)))
            elif e.kind == sil.EV_LOOP:
                fields.update(event="loop", mode="amplitude" if e.a else "open")
            elif e.kind == sil.EV_SIM_FAULT:
                if e.a == p.SIM_OVERHEAT:
                    self._count_injected("overheat")
                continue
            else:
                continue
            self._put(fields)
        for kind, duration_ms in self.core.fault_requests():  # the transport (PtyPlate) acts on these
            self.fault_requests.append((kind, duration_ms / 1000.0))

    def _count_injected(self, name: str) -> None:
        self._injected[name] = self._injected.get(name, 0) + 1

    def lag_s(self) -> float:
        """Seconds from the time last advanced to until now: what the next ``advance()`` renders."""
        with self._lock:
            return time.perf_counter() - self._clock

    def excuse(self, stalled_s: float) -> None:
        """The simulator itself did not run for ``stalled_s`` (this machine was busy): that time is not the
        host's silence, and the telemetry due meanwhile becomes one frame once the clock has caught up. A
        ``stalled`` event says so, to read the faults around it by."""
        with self._lock:
            self.core.excuse(int(stalled_s * 1000.0))
        self._event("stalled", for_s=round(stalled_s, 4))

    def overheat(self) -> None:
        """Inject an overheat now (as SIM_FAULT kind 5 with no duration: raised, output cut and disabled)."""
        with self._lock:
            self.core.set_stage_hot(True)
            self.core.set_stage_hot(False)
            self._count_injected("overheat")
            self._take_events()

    # ---- what the device reports ------------------------------------------------------------------
    def status(self) -> sil.Status:
        with self._lock:
            return self.core.status()

    @property
    def enabled(self) -> bool:
        return bool(self.status().enabled)

    @property
    def carrier_hz(self) -> float:
        return float(self.status().carrier_hz)

    @property
    def rate_hz(self) -> int:
        """The stream's setpoint rate (0: no stream)."""
        return int(self.status().stream_rate_hz)

    @property
    def drive_um_pp(self) -> float:
        """The firmware's drive now, after its limiter (µm p-p of steady amplitude at resonance)."""
        return float(self.status().drive) * self.profile.full_scale_um_pp

    @property
    def counters(self) -> SimCounters:
        s = self.status()
        counts = list(s.fault_counts)
        return SimCounters(s.frames_ok, s.crc_errors, s.framing_errors, counts[_bit("underrun")],
                           counts[_bit("overrun")], s.setpoints, s.lost_setpoints, s.late_setpoints,
                           s.discarded_setpoints, s.overrun_setpoints, counts[_bit("watchdog")], s.naks, 0, counts,
                           dict(self._injected))

    def fault_counts(self) -> dict[str, int]:
        counts = self.status().fault_counts
        return {name: counts[bit.bit_length() - 1] for bit, name in p.FAULT_NAMES.items()}

    def telemetry(self) -> p.Telemetry:
        s = self.status()
        return p.Telemetry(s.measured_um_pp, s.carrier_hz, s.faults, bool(s.enabled), s.frames_ok, s.crc_errors,
                           s.framing_errors, s.setpoints, s.lost_setpoints, s.late_setpoints, s.discarded_setpoints,
                           tuple(s.fault_counts), s.overrun_setpoints, s.expected_index, s.stream_rate_hz,
                           s.buffered, min(65535, max(0, round(s.drive * p.SETPOINT_SCALE))), s.playback, s.loop,
                           s.session_version)

    # ---- bytes in ------------------------------------------------------------------------------
    def receive(self, data: bytes) -> list[bytes]:
        """Feed received bytes (handled at the time last advanced to); returns the frames to send back."""
        with self._lock:
            now = time.perf_counter()
            lag_ms = (now - self._clock) * 1000.0 if self.real_time else 0.0
            # the drive samples due by now that are not rendered yet (never more: a CLOCK_REPLY is never ahead)
            since = int(self._owed + (now - self._clock) * self.sample_rate_hz * self._clock_rate) \
                if self.real_time else 0
            self.core.receive(data, int(lag_ms), since)
            replies = split_frames(self.core.transmit())
            self._take_events()
        return replies

    # ---- time passes ---------------------------------------------------------------------------
    def advance(self, now: float | None = None, telemetry: bool = True) -> list[bytes]:
        """Render the drive due by ``now`` through the plate (ticking the core: watchdog, telemetry); returns
        the frames the core sent meanwhile (none when ``telemetry`` is false: a hung device says nothing)."""
        with self._lock:
            now = time.perf_counter() if now is None else now
            self._owed += (now - self._clock) * self.sample_rate_hz * self._clock_rate
            self._clock = now
            n = int(self._owed)
            self._owed -= n
            self._sent = []
            if n <= 0:
                self.core.poll()
            else:
                self._run(n, now)
            self._sent.append(self.core.transmit())
            frames = split_frames(b"".join(self._sent))
            self._take_events()
            return frames if telemetry else []

    def _run(self, n: int, now: float) -> None:
        status = self.core.status()
        elapsed = now - self._started
        truth = self.truth
        alpha = math.exp(-1.0 / (self.sample_rate_hz * truth.time_constant_s(elapsed)))
        full_scale = truth.full_scale_um_pp or self.profile.full_scale_um_pp
        gain = truth.gain(status.carrier_hz, elapsed) * full_scale
        # disabled, the drive is zero whatever is measured: one block; enabled, the core hears the plate a
        # block late (its limiter and trip do not need it sooner; its amplitude loop does)
        block = (LOOP_BLOCK if status.loop else BLOCK) if status.enabled else sil.MAX_RENDER
        t0 = status.samples / self.sample_rate_hz  # the core's sample clock: a finger's blocks join exactly
        # the reductions by their ufuncs, without ndarray.min/max's wrappers
        render, sense, finger, rate = self.core.render, self.core.sense, self.finger, self.sample_rate_hz
        declared = self.profile.full_scale_um_pp  # the drive in the firmware's units, as its limit
        smallest, largest = np.minimum.reduce, np.maximum.reduce
        done = 0
        while done < n:
            k = min(block, n - done)
            drive = render(k)
            if abs(self._plate_state) <= REST_UM_PP and not drive.any():
                phasor = np.zeros(k)
            else:
                phasor = resonator_phasor(drive, self._plate_state, alpha, gain)
                low, high = self.drive_range_um_pp
                self.drive_range_um_pp = (min(low, float(smallest(drive)) * declared),
                                          max(high, float(largest(drive)) * declared))
            amplitude = np.abs(phasor)
            measured = amplitude
            if truth.noise_um_pp > 0:
                measured = amplitude + self._rng.normal(0.0, truth.noise_um_pp, k)
            normal = lateral = None
            if finger is not None:
                normal, lateral = finger.forces(t0 + done / rate, amplitude)
            cut = sense(measured, normal, lateral)
            if cut < k:  # tripped at sample `cut`: the drive stopped there
                before = phasor[cut - 1] if cut > 0 else self._plate_state
                phasor = phasor.copy()
                phasor[cut:] = before * alpha ** np.arange(1, k - cut + 1)
                amplitude = np.abs(phasor)
            self._plate_state = float(phasor[-1])
            self.peak_um_pp = max(self.peak_um_pp, float(largest(amplitude)))
            if self.trace is not None:
                self.trace.append(np.array(amplitude, dtype=float))
            done += k
            if done % DRAIN_SAMPLES < k:  # a long catch-up's frames leave as they are made, as a UART's would:
                self._sent.append(self.core.transmit())  # its 4 KB ring would otherwise overflow
        self.amplitude_um_pp = abs(self._plate_state)

    def next_wake_s(self, now: float) -> float:
        """How long the output stage may sleep from ``now`` (s): one tick while enabled or while the plate
        still moves; otherwise until the core's next telemetry frame (the plate at rest, disabled, has nothing
        else to do; ENABLE wakes it early, see :class:`PtyPlate`)."""
        status = self.status()
        if status.enabled or abs(self._plate_state) > REST_UM_PP:
            return TICK_S
        due = self._started + status.next_telemetry_ms / 1000.0 / self._clock_rate
        return min(max(due - now, 0.0), TELEMETRY_S)
