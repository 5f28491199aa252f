"""The simulated finger on the simulated plate: what it presses with, how fast it slides, the friction it gets.

A :class:`SimulatedFinger` is the plate's truth about a finger, with a friction law of its own that is not
the host's model: ``law(amplitude_um_pp, force_n) -> ratio`` (numpy arrays; the layer that builds the finger
hands it over, e.g. a host model's ``relative_friction``). Over time:

* the **normal force** follows a :class:`ForceScript` (a constant, a random walk within a range, or points
  read from a CSV), 0 N meaning lifted;
* the **sliding speed** (mm/s) comes from the same script; a finger at rest (speed below 1 mm/s) sticks:
  its lateral force is not friction, and the sensors see none;
* the law's amplitude scale **drifts** slowly, ``k(t) = 1 + drift sin(2 pi t / period)``, so the ratio is
  ``law(a / k(t), F)`` (±30 % over a minute by default), and the friction at rest **rises with dwell** as
  moisture accumulates: ``mu0(t) = mu0 (1 + moisture w(t))``, ``w`` a first-order approach to 1 while
  touching (time constant ``moisture_tau_s``), back to 0 when lifted.

The lateral force of a sliding finger is ``mu0(t) law(a / k(t), F) F`` at the plate's *actual* amplitude
(the resonator's, not the setpoint). With :class:`FingerDynamics` the ratio does not follow the law at once: it
lags it, quickly where friction falls (the vibration starts) and slowly where it recovers, the more slowly the
slower the finger slides (the published figures and the assumed speed law are in ``render/physics/dynamics.py``;
this is the plate's own implementation of them, independent of the host's). What the plate's firmware
receives is what its force sensors make of the two forces (:mod:`devices.force_sensors`: bandwidth, delay,
noise). The finger's true state can be logged (:mod:`devices.finger_log`).

:meth:`SimulatedFinger.forces` is the simulated plate's ``ForceSource``: called block by block with the
plate's amplitude at ``sample_rate_hz`` from ``t_s`` (s since the simulator started), it returns the normal
and lateral force the sensors measure over those samples. The physics runs in chunks of about a millisecond
(the sensors' delay lets it run behind the blocks), so a plate rendering 0.25 ms blocks pays for it once a
millisecond.

Examples
--------
>>> import numpy as np
>>> finger = SimulatedFinger(lambda a, f: np.exp(-(a / 3.0) ** 2), ForceScript.constant(0.5, 100.0),
...                          FingerParams(drift=0.0, moisture=0.0), ForceSensorParams(noise_n=0.0))
>>> normal, lateral = finger.forces(0.0, np.full(480, 3.0))
>>> round(float(normal[-1]), 3), round(float(lateral[-1]), 3)   # mu0 1, ratio exp(-1): 0.5 N x 0.368
(0.5, 0.184)
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.sim import kernels
from ultraglide.devices.sim.force_sensors import ForceSensorParams, ForceSensors, low_pass

from ultraglide.inputs import decode_text, read_input, shown

FrictionLaw = Callable[[np.ndarray, np.ndarray], np.ndarray]  # ratio = law(amplitude_um_pp, force_n)

LIFTED_N = 0.01  # a normal force below this: the finger is off the plate
SLIDING_MM_S = 1.0  # slower than this, the finger sticks
MAX_SCRIPT_FORCE_N = 20.0
MAX_SPEED_MM_S = 2000.0
WALK_STEP_S = 0.01  # the random walk's knots, linearly interpolated between
WALK_DIFFUSION_N = 0.3  # its spread: N per sqrt(s)
CHUNK_S = 0.001  # the physics runs in chunks of at least this (the sensors' delay allows it)
MAX_BLOCK = 1 << 20  # samples a single forces() call may ask for


@dataclass(frozen=True)
class FingerParams:
    """The finger's own physiology: ``mu0`` its friction coefficient at rest (dimensionless); ``drift`` the
    law's amplitude scale swinging ±drift (a fraction) over ``drift_period_s``; ``moisture`` the rise of mu0
    after a long dwell (a fraction), approached with time constant ``moisture_tau_s`` while touching."""

    mu0: float = 1.0
    drift: float = 0.3
    drift_period_s: float = 60.0
    moisture: float = 0.25
    moisture_tau_s: float = 20.0

    def __post_init__(self) -> None:
        checks = (("mu0", self.mu0, 0.05, 5.0), ("drift", self.drift, 0.0, 0.9),
                  ("drift_period_s", self.drift_period_s, 0.1, 3600.0), ("moisture", self.moisture, 0.0, 2.0),
                  ("moisture_tau_s", self.moisture_tau_s, 0.01, 3600.0))
        for name, value, low, high in checks:
            if not (math.isfinite(value) and low <= value <= high):
                raise DeviceError(f"the finger's {name} must lie in {low:g}..{high:g}, got {value}")

    def scale_at(self, t_s: np.ndarray) -> np.ndarray:
        """k(t): the law's amplitude axis is stretched by this factor at time ``t_s`` (s)."""
        return 1.0 + self.drift * np.sin((2.0 * math.pi / self.drift_period_s) * t_s)


@dataclass(frozen=True)
class FingerDynamics:
    """How the finger's friction lags the law: time constants (s) ``onset_s`` where friction falls,
    ``recovery_s`` where it rises at ``reference_speed_mm_s``, scaled by (reference / speed)^``speed_exponent``.
    The defaults are the published figures (5 ms down, 70 ms back at 22 mm/s) with the exponent 0.5 assumed."""

    onset_s: float = 0.005
    recovery_s: float = 0.070
    reference_speed_mm_s: float = 22.0
    speed_exponent: float = 0.5

    def __post_init__(self) -> None:
        checks = (("onset_s", self.onset_s, 0.0005, 0.05), ("recovery_s", self.recovery_s, 0.002, 0.5),
                  ("reference_speed_mm_s", self.reference_speed_mm_s, 1.0, 1000.0),
                  ("speed_exponent", self.speed_exponent, 0.0, 1.5))
        for name, value, low, high in checks:
            if not (math.isfinite(value) and low <= value <= high):
                raise DeviceError(f"the finger's {name} must lie in {low:g}..{high:g}, got {value}")

    def words(self) -> str:
        return (f"friction lags: {1000 * self.onset_s:.3g} ms down, {1000 * self.recovery_s:.3g} ms back at "
                f"{self.reference_speed_mm_s:g} mm/s (x (v_ref/v)^{self.speed_exponent:g})")


SLOWEST_RECOVERY_MM_S = 2.0  # the recovery of a finger sliding slower is held at this speed's
FASTEST_LAW_MM_S = 2000.0  # the speed law holds a faster finger at this speed (and a slower one at 2 mm/s)


@dataclass(frozen=True)
class FingerSpeedLaw:
    """How the finger's settled friction reduction weakens with its sliding speed: the law is evaluated at the
    effective amplitude a (``reference_speed_mm_s`` / v)^``exponent``, v held within 2-2000 mm/s. The plate's own
    implementation of the assumed law of docs/physics.md ("Sliding speed"), independent of the host's: exponent 0
    (no dependence) to 1, reference 1-1000 mm/s.

    Examples
    --------
    >>> import numpy as np
    >>> FingerSpeedLaw(0.5).efficacy(np.array([22.0, 88.0, 1.0])).round(6).tolist()   # 1 mm/s as 2 mm/s
    [1.0, 0.5, 3.316625]
    """

    exponent: float = 0.0
    reference_speed_mm_s: float = 22.0

    def __post_init__(self) -> None:
        checks = (("speed law's exponent", self.exponent, 0.0, 1.0),
                  ("speed law's reference speed", self.reference_speed_mm_s, 1.0, 1000.0))
        for name, value, low, high in checks:
            if not (math.isfinite(value) and low <= value <= high):
                raise DeviceError(f"the finger's {name} must lie in {low:g}..{high:g}, got {value}")

    def efficacy(self, speed_mm_s: np.ndarray) -> np.ndarray:
        """(v_ref / v)^s at each speed (mm/s): what the vibration's amplitude is worth at that speed."""
        speed = np.minimum(np.maximum(speed_mm_s, SLOWEST_RECOVERY_MM_S), FASTEST_LAW_MM_S)
        return (self.reference_speed_mm_s / speed) ** self.exponent

    def words(self) -> str:
        return f"reduction x ({self.reference_speed_mm_s:g} mm/s / v)^{self.exponent:g} in amplitude"


@dataclass(frozen=True)
class ForceScript:
    """How hard the finger presses (N) and how fast it slides (mm/s) over time (s since the plate started).

    ``kind``: ``constant`` (``force_n``, ``speed_mm_s``), ``walk`` (a random walk reflected into
    ``low_n..high_n``, from their middle, seeded, at ``speed_mm_s``) or ``points`` (``times_s`` with a force and a
    speed each, linearly interpolated, held after the last). Build with :meth:`constant`, :meth:`walk`,
    :meth:`points` or :meth:`parse`."""

    kind: str
    force_n: float = 0.5
    speed_mm_s: float = 100.0
    low_n: float = 0.2
    high_n: float = 1.0
    seed: int = 0
    times_s: tuple[float, ...] = ()
    forces_n: tuple[float, ...] = ()
    speeds_mm_s: tuple[float, ...] = ()

    @classmethod
    def constant(cls, force_n: float, speed_mm_s: float = 100.0) -> ForceScript:
        _check_force(force_n, "the finger's force")
        _check_speed(speed_mm_s)
        return cls("constant", force_n=float(force_n), speed_mm_s=float(speed_mm_s))

    @classmethod
    def walk(cls, low_n: float = 0.2, high_n: float = 1.0, speed_mm_s: float = 100.0, seed: int = 0) -> ForceScript:
        _check_force(low_n, "the walk's lowest force")
        _check_force(high_n, "the walk's highest force")
        if not low_n < high_n:
            raise DeviceError(f"a force walk needs its low end below its high end, got {low_n:g}-{high_n:g} N")
        _check_speed(speed_mm_s)
        return cls("walk", low_n=float(low_n), high_n=float(high_n), speed_mm_s=float(speed_mm_s), seed=int(seed))

    @classmethod
    def points(cls, times_s, forces_n, speeds_mm_s) -> ForceScript:
        times = np.asarray(times_s, dtype=float)
        if len(times) == 0 or np.any(np.diff(times) <= 0) or not np.all(np.isfinite(times)) or times[0] < 0:
            raise DeviceError("a force script's times must be finite, from 0 s, and strictly increasing")
        for value in forces_n:
            _check_force(value, "a scripted force", allow_zero=True)
        for value in speeds_mm_s:
            _check_speed(value)
        return cls("points", times_s=tuple(map(float, times)), forces_n=tuple(map(float, forces_n)),
                   speeds_mm_s=tuple(map(float, speeds_mm_s)))

    @classmethod
    def parse(cls, spec: str, speed_mm_s: float = 100.0, seed: int = 0) -> ForceScript:
        """``0.5`` (N, constant), ``walk`` (0.2-1 N), ``walk:LOW-HIGH`` or a CSV file with columns
        ``t_s,force_n[,speed_mm_s]`` (the speed column, where present, overrides ``speed_mm_s``)."""
        spec = spec.strip()
        if spec == "walk" or spec.startswith("walk:"):
            if spec == "walk":
                return cls.walk(speed_mm_s=speed_mm_s, seed=seed)
            low, dash, high = spec[5:].partition("-")
            try:
                return cls.walk(float(low), float(high), speed_mm_s, seed)
            except ValueError:
                raise DeviceError(f"a force walk is walk:LOW-HIGH in N (e.g. walk:0.2-1), got {spec!r}") from None
        try:
            return cls.constant(float(spec), speed_mm_s)
        except ValueError:
            pass
        if not Path(spec).is_file():
            raise DeviceError(f"the finger's force is a number (N), walk, walk:LOW-HIGH or a CSV file "
                              f"(t_s,force_n[,speed_mm_s]); {spec!r} is none of these")
        return cls.read_csv(spec, speed_mm_s)

    @classmethod
    def read_csv(cls, path: str, speed_mm_s: float = 100.0) -> ForceScript:
        """A script from a CSV with a header ``t_s,force_n[,speed_mm_s]``; a bad row is named by its line."""
        times, forces, speeds = [], [], []
        text = decode_text(read_input(path, "force script", DeviceError), str(path), "force script (CSV)", DeviceError)
        try:
            reader = csv.reader(row for row in text.splitlines() if not row.startswith("#"))
            header = [name.strip() for name in next(reader, [])]
            if header[:2] != ["t_s", "force_n"] or header[2:] not in ([], ["speed_mm_s"]):
                raise DeviceError(f"{path}: the header must be t_s,force_n[,speed_mm_s], "
                                  f"got {shown(','.join(header)[:80])}")
            for line, row in enumerate(reader, start=2):
                if len(row) != len(header):
                    raise DeviceError(f"{path}, line {line}: {len(header)} columns expected, got {len(row)}")
                try:
                    values = [float(cell) for cell in row]
                except ValueError:
                    raise DeviceError(f"{path}, line {line}: not numbers: {shown(','.join(row)[:80])}") from None
                times.append(values[0])
                forces.append(values[1])
                speeds.append(values[2] if len(values) > 2 else speed_mm_s)
        except csv.Error as error:  # a cell longer than the csv module takes, a stray quote
            raise DeviceError(f"{path}: not a CSV file the finger reads ({error})") from None
        if not times:
            raise DeviceError(f"{path}: no rows after the header")
        return cls.points(times, forces, speeds)

    def words(self) -> str:
        if self.kind == "constant":
            return f"{self.force_n:g} N at {self.speed_mm_s:g} mm/s"
        if self.kind == "walk":
            return f"a random walk in {self.low_n:g}-{self.high_n:g} N at {self.speed_mm_s:g} mm/s"
        return f"a script of {len(self.times_s)} points over {self.times_s[-1]:g} s"


def adjusted_law(law: FrictionLaw, scale: float = 1.0, floor: float = 0.0) -> FrictionLaw:
    """``law`` with its amplitude axis stretched by ``scale`` (more than 1: the finger needs more vibration) and a
    constant floor ``floor``: ``d + (1 - d) law(a / scale, F)``. The form is Huloux et al. (2018)'s; whether their
    d is a floor or a bounded disturbance varying in time was not checked (docs/physics.md): here d is a constant."""
    if not (math.isfinite(scale) and 0.1 <= scale <= 10.0):
        raise DeviceError(f"the finger's law scale must lie in 0.1..10, got {scale}")
    if not (math.isfinite(floor) and 0.0 <= floor < 1.0):
        raise DeviceError(f"the finger's floor must lie in 0 to below 1, got {floor}")
    if scale == 1.0 and floor == 0.0:
        return law

    def adjusted(amplitude_um_pp, force_n):
        ratio = law(np.asarray(amplitude_um_pp, dtype=float) / scale, force_n)
        return floor + (1.0 - floor) * np.asarray(ratio, dtype=float) if floor else ratio

    adjusted.__qualname__ = f"{getattr(law, '__qualname__', 'law')} x{scale:g}" + (f" floor {floor:g}" if floor else "")
    return adjusted


def _check_force(value: float, what: str, allow_zero: bool = False) -> None:
    low_ok = value >= 0.0 if allow_zero else value > 0.0
    if not (math.isfinite(value) and low_ok and value <= MAX_SCRIPT_FORCE_N):
        bound = "0" if allow_zero else "above 0"
        raise DeviceError(f"{what} must be {bound} and up to {MAX_SCRIPT_FORCE_N:g} N, got {value}")


def _check_speed(value: float) -> None:
    if not (math.isfinite(value) and 0.0 <= value <= MAX_SPEED_MM_S):
        raise DeviceError(f"the finger's speed must be 0 to {MAX_SPEED_MM_S:g} mm/s, got {value}")


class _Track:
    """A :class:`ForceScript` played forward: force (N) and speed (mm/s) at increasing times."""

    def __init__(self, script: ForceScript):
        self.script = script
        self._rng = np.random.default_rng(script.seed)
        self._knot_t = np.zeros(0)
        self._knot_f = np.zeros(0)
        if script.kind == "walk":
            self._knot_t = np.array([0.0])
            self._knot_f = np.array([(script.low_n + script.high_n) / 2.0])
        self._free = (script.high_n - script.low_n) / 2.0  # the walk before its reflection, from the low end

    def _extend(self, from_s: float, until_s: float) -> None:
        """Walk knots up to ``until_s``; those before ``from_s`` (but the one just before it) are dropped."""
        script = self.script
        if self._knot_t[-1] >= until_s:
            return
        steps = int(math.ceil((until_s - self._knot_t[-1]) / WALK_STEP_S)) + 1
        span = script.high_n - script.low_n
        moves = self._rng.normal(0.0, WALK_DIFFUSION_N * math.sqrt(WALK_STEP_S), steps)
        walked = np.cumsum(moves) + self._free
        self._free = float(walked[-1])
        folded = np.mod(walked, 2.0 * span)  # reflected at both ends: a triangle wave of the free walk
        values = script.low_n + np.where(folded > span, 2.0 * span - folded, folded)
        times = self._knot_t[-1] + WALK_STEP_S * np.arange(1, steps + 1)
        keep = max(int(np.searchsorted(self._knot_t, from_s, side="right")) - 1, 0)
        self._knot_t = np.concatenate((self._knot_t[keep:], times))
        self._knot_f = np.concatenate((self._knot_f[keep:], values))

    def at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        script = self.script
        if script.kind == "constant":
            return np.full(t_s.shape, script.force_n), np.full(t_s.shape, script.speed_mm_s)
        if script.kind == "walk":
            self._extend(float(t_s[0]), float(t_s[-1]))
            return np.interp(t_s, self._knot_t, self._knot_f), np.full(t_s.shape, script.speed_mm_s)
        return (np.interp(t_s, script.times_s, script.forces_n), np.interp(t_s, script.times_s, script.speeds_mm_s))


SENSOR_FAULTS = ("nan", "range", "zero")


@dataclass(frozen=True)
class SensorFault:
    """The force sensors misread from ``start_s`` to ``end_s`` (s since the plate started): ``nan`` (a broken
    converter), ``range`` (50 N: a shorted bridge) or ``zero`` (a cut cable: both forces 0)."""

    kind: str
    start_s: float
    end_s: float

    def __post_init__(self) -> None:
        if self.kind not in SENSOR_FAULTS:
            raise DeviceError(f"a sensor fault is {', '.join(SENSOR_FAULTS)}, not {self.kind!r}")
        if not (math.isfinite(self.start_s) and math.isfinite(self.end_s) and 0 <= self.start_s < self.end_s):
            raise DeviceError(f"a sensor fault lasts from START to END s, START < END, got {self.start_s}-{self.end_s}")

    @classmethod
    def parse(cls, spec: str) -> SensorFault:
        """``KIND:START-END`` (seconds since the plate started), e.g. ``nan:12-12.5``."""
        kind, _, span = spec.partition(":")
        start, _, end = span.partition("-")
        try:
            return cls(kind, float(start), float(end))
        except ValueError:
            raise DeviceError(f"a sensor fault is KIND:START-END in s (KIND {', '.join(SENSOR_FAULTS)}), "
                              f"got {spec!r}") from None

    def apply(self, t_s: np.ndarray, normal: np.ndarray, lateral: np.ndarray) -> None:
        inside = (t_s >= self.start_s) & (t_s < self.end_s)
        if not inside.any():
            return
        value = {"nan": math.nan, "range": 50.0, "zero": 0.0}[self.kind]
        normal[inside] = value
        lateral[inside] = value


@dataclass
class FingerTruth:
    """The finger's true state over the samples of one chunk (arrays), times on the simulator's clock (s)."""

    t_s: np.ndarray
    amplitude_um_pp: np.ndarray
    normal_force_n: np.ndarray
    relative_friction: np.ndarray
    sliding: np.ndarray
    lateral_force_n: np.ndarray
    mu0: np.ndarray  # the friction coefficient at rest


class SimulatedFinger:
    """See the module docstring. ``log``: something with ``write(truth: FingerTruth)`` (a
    :class:`~ultraglide.devices.sim.finger_log.FingerLog`), called with each chunk of true state; ``sample_rate_hz``
    the plate's sample rate (the one its ``forces`` blocks come at)."""

    def __init__(self, law: FrictionLaw, script: ForceScript | None = None, params: FingerParams | None = None,
                 sensors: ForceSensorParams | None = None, log=None, sample_rate_hz: int = 48000, name: str = "",
                 faults: tuple[SensorFault, ...] = (), dynamics: FingerDynamics | None = None,
                 speed_law: FingerSpeedLaw | None = None):
        self.law = law
        self.dynamics = dynamics
        self.speed_law = speed_law if speed_law is not None and speed_law.exponent > 0.0 else None
        self._felt = 1.0  # the lagging friction ratio carried between chunks
        if dynamics is not None:  # compile (or load) the lag before the plate's first chunk needs it
            kernels.friction_lag(np.ones(2), np.ones(2), np.ones(2), LIFTED_N, 48000.0, 0.005, 0.07, 22.0, 0.5, 2.0,
                                 1.0, np.empty(2))
        self.script = script or ForceScript.constant(0.5)
        self.params = params or FingerParams()
        self.sensors = ForceSensors(sensors or ForceSensorParams(), sample_rate_hz)
        self.sample_rate_hz = int(sample_rate_hz)
        self.log = log
        self.faults = tuple(faults)
        self.name = name or getattr(law, "__qualname__", "law")
        self._track = _Track(self.script)
        self._steady = self._always_sliding(self.script)
        self._wet_alpha = math.exp(-1.0 / (self.sample_rate_hz * self.params.moisture_tau_s))
        self._wet = np.zeros(1)  # moisture, 0 (dry) to 1 (a long dwell)
        self._next_sample: int | None = None  # the first sample not yet given (blocks must be contiguous)
        self._pending: list[np.ndarray] = []  # amplitudes given, not yet through the physics (copies, in order)
        self._done = 0  # samples through the physics (the sensors hold their output)
        self._chunk = max(1, int(round(CHUNK_S * self.sample_rate_hz)))
        self.last: FingerTruth | None = None  # the newest chunk of truth

    @staticmethod
    def _always_sliding(script: ForceScript) -> bool:
        """Whether the script's every sample touches and slides (truth's shortcut): its lowest force and speed
        at least twice the thresholds, a margin no interpolation's rounding crosses."""
        if script.kind == "points":
            force, speed = min(script.forces_n), min(script.speeds_mm_s)
        else:
            force, speed = (script.low_n if script.kind == "walk" else script.force_n), script.speed_mm_s
        return force >= 2.0 * LIFTED_N and speed >= 2.0 * SLIDING_MM_S

    def __repr__(self) -> str:
        p = self.params
        lag = f", {self.dynamics.words()}" if self.dynamics is not None else ""
        lag += f", {self.speed_law.words()}" if self.speed_law is not None else ""
        return (f"SimulatedFinger({self.name}, {self.script.words()}, mu0 {p.mu0:g}, drift ±{100 * p.drift:g} % "
                f"over {p.drift_period_s:g} s, moisture +{100 * p.moisture:g} % ({p.moisture_tau_s:g} s){lag}, "
                f"{self.sensors.params.words()})")

    def set_clock_origin(self, origin_s: float) -> None:
        """The perf_counter time of the plate's sample 0 (the simulated plate tells it): the log's times follow."""
        if self.log is not None:
            self.log.clock_origin_s = origin_s

    def truth(self, t_s: np.ndarray, amplitude_um_pp: np.ndarray) -> FingerTruth:
        """The finger's true state at the samples ``t_s`` (s, increasing, contiguous with the last call: the
        moisture carries over) for the plate's amplitude there (µm p-p)."""
        force, speed = self._track.at(t_s)
        steady = self._steady  # touching and sliding throughout: the masks' selections are the values themselves
        if steady:
            sliding = np.empty(force.shape, dtype=bool)
            sliding.fill(True)
            wet = np.empty((1, force.size))
            wet.fill(1.0)
        else:
            touching = force >= LIFTED_N
            sliding = touching & (speed >= SLIDING_MM_S)
            wet = touching.astype(float).reshape(1, -1)
        low_pass(wet, self._wet_alpha, self._wet)  # dw/dt = (touching - w) / tau, sample by sample
        mu0 = self.params.mu0 * (1.0 + self.params.moisture * wet[0])
        scale = self.params.scale_at(t_s)
        amplitude = np.maximum(np.asarray(amplitude_um_pp, dtype=float), 0.0)
        effective = amplitude / scale
        if self.speed_law is not None:  # the reduction weakens with speed: the law at a (v_ref / v)^s
            effective *= self.speed_law.efficacy(speed)
        ratio = np.asarray(self.law(effective, force if steady else np.maximum(force, LIFTED_N)), dtype=float)
        if ratio.shape != amplitude.shape:
            ratio = np.broadcast_to(ratio, amplitude.shape)
        ratio = np.minimum(np.maximum(ratio, 0.0), 1.0)  # np.clip's values, without its wrapper
        lag = self.dynamics
        if lag is not None:
            settled = np.ascontiguousarray(ratio, dtype=float)
            ratio = np.empty(settled.shape)
            self._felt = kernels.friction_lag(settled, np.ascontiguousarray(speed, dtype=float),
                                              np.ascontiguousarray(force, dtype=float), LIFTED_N,
                                              float(self.sample_rate_hz), lag.onset_s, lag.recovery_s,
                                              lag.reference_speed_mm_s, lag.speed_exponent, SLOWEST_RECOVERY_MM_S,
                                              self._felt, ratio)
        if steady:
            return FingerTruth(t_s, amplitude, force, ratio, sliding, mu0 * ratio * force, mu0)
        lateral = np.where(sliding, mu0 * ratio * force, 0.0)
        return FingerTruth(t_s, amplitude, np.where(touching, force, 0.0), ratio, sliding, lateral, mu0)

    def forces(self, t_s: float, amplitude_um_pp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The normal and lateral force (N) the sensors measure over the block of samples that starts at
        ``t_s`` (s since the plate started), given the plate's amplitude over it (µm p-p)."""
        n = len(amplitude_um_pp)
        if n > MAX_BLOCK:
            raise ValueError(f"a block of at most {MAX_BLOCK} samples, not {n}")
        start = int(round(t_s * self.sample_rate_hz))
        if self._next_sample is None:
            self._next_sample = self._done = start
        elif abs(start - self._next_sample) <= 2:  # a clock's rounding: the blocks join
            start = self._next_sample
        elif start != self._next_sample:  # a gap or a repeat: the physics restarts there (the sensors keep state)
            self._pending = []
            self._next_sample = self._done = start
        self._next_sample = start + n
        self._pending.append(np.array(amplitude_um_pp, dtype=float))  # joined once a chunk, in _run
        delay = self.sensors.delay_samples
        needed = start + n - delay  # the sensors' output up to the block's end needs the physics up to here
        available = start + n
        if needed > self._done:
            end = min(max(needed, self._done + self._chunk), available)
            self._run(end)
        normal, lateral = self.sensors.output(start, n)
        if self.faults:
            times = (start + np.arange(n)) / self.sample_rate_hz
            for fault in self.faults:
                fault.apply(times, normal, lateral)
        return normal, lateral

    def _run(self, end: int) -> None:
        """Through the physics from sample ``_done`` to ``end``: truth, sensors, log."""
        count = end - self._done
        pending = self._pending[0] if len(self._pending) == 1 else np.concatenate(self._pending)
        amplitude, rest = pending[:count], pending[count:]
        self._pending = [rest] if len(rest) else []
        times = (self._done + np.arange(count)) / self.sample_rate_hz
        truth = self.truth(times, amplitude)
        self.sensors.measure(self._done, truth.normal_force_n, truth.lateral_force_n)
        self._done = end
        self.last = truth
        if self.log is not None:
            self.log.write(truth)

    def close(self) -> None:
        """Finish the log (if any): its file appears whole."""
        if self.log is not None:
            self.log.close()
