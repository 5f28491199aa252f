"""``ultraglide plate sweep``: measure a plate's resonance, Q and gain, and write its profile.

The carrier steps across a range while the plate is driven at a low constant amplitude (15 % of
its limit); at each step, once telemetry shows the amplitude settled at the new carrier, the
measured amplitude is read. A resonance curve is fitted (devices/resonance.py), a finer sweep is
made around the peak, and the final fit over all points gives f0, Q and the amplitude at full-scale
drive, with uncertainties. The plate is rested (zero, disable) on every way out, stop signals included.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import atomic_path
from ultraglide.apps.cli.signals import held
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.devices.resonance import FitError, ResonanceFit, fit_resonance
from ultraglide.devices.urls import open_device, parse_device_url

SWEEP_LEVEL = 0.15  # drive during a sweep: this fraction of the plate's limit, µm p-p at resonance
SAFE_FRACTION = 0.5  # a measured amplitude above this fraction of the limit halves the drive
SETTLE_TAUS = 5.0  # wait at least this many envelope time constants after a carrier change
SETTLE_TOLERANCE = 0.01  # two successive telemetry frames agreeing this closely (relative): settled
MAX_FRAMES_PER_STEP = 25  # a step that never settles takes its last frame and says so
FINE_STEPS = 25
PLOT_DPI = 300


@dataclass(frozen=True)
class SweepPoint:
    """One step: the carrier (Hz), the amplitude measured (µm p-p) and the drive as a fraction of full scale."""

    carrier_hz: float
    measured_um_pp: float
    drive_fraction: float
    settled: bool

    @property
    def full_scale_um_pp(self) -> float:
        """The amplitude this carrier would give at full-scale drive (the plate is linear)."""
        return self.measured_um_pp / self.drive_fraction


class SteadyDrive:
    """A BlockSource of a constant amplitude (µm p-p) that ramps to rest in 10 ms when asked."""

    def __init__(self, amplitude_um_pp: float, rate_hz: int):
        self.amplitude_um_pp = amplitude_um_pp
        self._step = amplitude_um_pp / (0.01 * rate_hz)
        self._stopping = False

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        if self._stopping:
            start = self.amplitude_um_pp
            self.amplitude_um_pp = max(0.0, start - self._step * n)
            return np.maximum(start - self._step * np.arange(1, n + 1), 0.0)
        return np.full(n, self.amplitude_um_pp)

    def request_stop(self) -> None:
        self._stopping = True

    @property
    def finished(self) -> bool:
        return self._stopping and self.amplitude_um_pp == 0.0


class TelemetrySweeper:
    """Sweeps a plate driver (sim or serial) that reports its measured amplitude in telemetry."""

    def __init__(self, device, profile: PlateProfile):
        self.device = device
        self.driver = getattr(device, "driver", device)  # SimPlate wraps a SerialPlate
        self.profile = profile
        self.level_um_pp = SWEEP_LEVEL * profile.max_amplitude_um_pp
        self.source = SteadyDrive(self.level_um_pp, device.rate_hz)
        self.unsettled = 0

    def start(self, carrier_hz: float) -> None:
        self.driver.carrier_hz = carrier_hz
        self.device.start(self.source)

    def measure(self, carrier_hz: float, time_constant_s: float) -> SweepPoint:
        self.driver.set_carrier(carrier_hz)
        changed = time.monotonic()
        previous = None
        for _ in range(MAX_FRAMES_PER_STEP):
            telemetry = self.driver.next_telemetry()
            self._check(telemetry)
            if abs(telemetry.carrier_hz - carrier_hz) > 0.01:
                continue  # from before the change
            amplitude = telemetry.measured_um_pp
            if amplitude > SAFE_FRACTION * self.profile.max_amplitude_um_pp:
                self._lower_drive()
                previous = None
                changed = time.monotonic()
                continue
            waited = time.monotonic() - changed >= SETTLE_TAUS * time_constant_s
            floor = 0.01 * self.level_um_pp
            if waited and previous is not None and abs(amplitude - previous) <= SETTLE_TOLERANCE * max(amplitude,
                                                                                                        floor):
                return SweepPoint(carrier_hz, 0.5 * (amplitude + previous), self.drive_fraction, True)
            previous = amplitude
        self.unsettled += 1
        return SweepPoint(carrier_hz, amplitude, self.drive_fraction, False)

    @property
    def drive_fraction(self) -> float:
        return self.source.amplitude_um_pp / self.profile.full_scale_um_pp

    def _lower_drive(self) -> None:
        """The plate moves more than its profile says: halve the drive (points are kept per unit drive)."""
        self.source.amplitude_um_pp *= 0.5
        self.level_um_pp = self.source.amplitude_um_pp

    def _check(self, telemetry) -> None:
        if not telemetry.enabled:
            names = ", ".join(telemetry.fault_names()) or "no fault given"
            raise DeviceError(f"the plate driver disabled its output during the sweep ({names}); check the plate "
                              "and its profile, then sweep again")

    def stop(self) -> None:
        self.device.stop()

    def fault_counts(self) -> dict[str, int]:
        return self.driver.fault_counts()


AUDIO_DWELL_S = 0.1  # each carrier of an audio sweep plays this long
AUDIO_SETTLE_FRACTION = 0.4  # the first 40 % of each dwell (settling, the interface's latency) is not analysed
AUDIO_RAMP_S = 0.01


def sweep_signal(carriers_hz: np.ndarray, level: float, rate_hz: int) -> np.ndarray:
    """The carrier stepping through ``carriers_hz``, AUDIO_DWELL_S each, phase-continuous, at ``level`` of full
    scale, ramped in and out over 10 ms (float32, for the audio output)."""
    dwell = int(round(AUDIO_DWELL_S * rate_hz))
    frequency = np.repeat(np.asarray(carriers_hz, dtype=float), dwell)
    phase = 2.0 * np.pi * np.cumsum(frequency) / rate_hz
    signal_ = level * np.sin(phase)
    ramp = int(AUDIO_RAMP_S * rate_hz)
    envelope = np.ones_like(signal_)
    envelope[:ramp] = np.linspace(0.0, 1.0, ramp)
    tail = level * np.sin(phase[-1] + 2.0 * np.pi * frequency[-1] * np.arange(1, ramp + 1) / rate_hz)
    return np.concatenate((signal_ * envelope, tail * np.linspace(1.0, 0.0, ramp))).astype(np.float32)


def lock_in_amplitude(recorded: np.ndarray, carrier_hz: float, rate_hz: int) -> float:
    """The amplitude (peak, in the recording's units) of the component at ``carrier_hz``: a single-bin DFT
    with a Hann window, normalised so that a pure sine of amplitude A gives A."""
    n = np.arange(len(recorded))
    window = np.hanning(len(recorded))
    component = np.sum(recorded * window * np.exp(-2j * np.pi * carrier_hz * n / rate_hz))
    return float(2.0 * np.abs(component) / window.sum())


def audio_sweep(output, sensor, carriers_hz: np.ndarray, level: float, rate_hz: int) -> np.ndarray:
    """Play the stepped carrier on ``output`` while recording ``sensor``; the sensor's amplitude at each carrier."""
    from ultraglide.devices.audio import import_sounddevice

    sd = import_sounddevice()
    played = sweep_signal(carriers_hz, level, rate_hz)
    try:
        recorded = sd.playrec(played, samplerate=rate_hz, channels=1, dtype="float32", device=(sensor, output),
                              blocking=True)[:, 0]
    except sd.PortAudioError as error:
        raise DeviceError(f"audio sweep: {error}; list devices with `ultraglide devices`") from None
    finally:
        with held():
            sd.stop()
    dwell = int(round(AUDIO_DWELL_S * rate_hz))
    skip = int(AUDIO_SETTLE_FRACTION * dwell)
    return np.array([lock_in_amplitude(recorded[i * dwell + skip:(i + 1) * dwell], f, rate_hz)
                     for i, f in enumerate(carriers_hz)])


def _audio_device(target: str):
    """sounddevice's name for an audio URL's target: an index, a name, or None for the default."""
    return int(target) if target.isdigit() else (target or None)


def run_audio_sweep(args, profile: PlateProfile, low: float, high: float, output: Path) -> int:
    """One pass over a fixed grid (no refinement: the audio path has no telemetry to settle on); the sensor
    gives f0 and Q, and the full scale too when ``--sensor-um-per-unit`` calibrates it."""
    device = parse_device_url(args.device)
    sensor = parse_device_url(args.sensor)
    if sensor.kind != "audio" or not sensor.target:
        raise UsageError(f"--sensor {args.sensor}: give the input as audio:NAME_OR_INDEX")
    rate = int(device.options.get("rate", 96000))
    if rate < high / 0.4:
        raise UsageError(f"{rate} Hz cannot carry {high:g} Hz; use ?rate=96000 or 192000")
    level = SWEEP_LEVEL * profile.max_amplitude_um_pp / profile.full_scale_um_pp
    carriers = _grid(low, high, args.steps)
    amplitudes = audio_sweep(_audio_device(device.target), _audio_device(sensor.target), carriers, level, rate)
    fit = _fit([SweepPoint(float(f), float(a), 1.0, True) for f, a in zip(carriers, amplitudes, strict=True)],
               low, high)
    if args.sensor_um_per_unit:
        full_scale = fit.peak_um_pp * args.sensor_um_per_unit / level
        fit = ResonanceFit(fit.resonance_hz, fit.q, full_scale, fit.resonance_sigma_hz, fit.q_sigma,
                           fit.peak_sigma_um_pp * args.sensor_um_per_unit / level, fit.rms_residual_um_pp)
    else:
        fit = ResonanceFit(fit.resonance_hz, fit.q, profile.full_scale_um_pp, fit.resonance_sigma_hz, fit.q_sigma,
                           0.0, fit.rms_residual_um_pp)
    found = measured_profile(profile, fit, output.stem)
    write_profile(output, found, fit)
    summary = {"resonance_hz": round(fit.resonance_hz, 3), "resonance_sigma_hz": float(f"{fit.resonance_sigma_hz:.4g}"),
               "q": round(fit.q, 3), "q_sigma": float(f"{fit.q_sigma:.4g}"), "bandwidth_hz": round(fit.bandwidth_hz, 3),
               "full_scale_um_pp": found.full_scale_um_pp, "full_scale_measured": bool(args.sensor_um_per_unit),
               "max_amplitude_um_pp": found.max_amplitude_um_pp, "points": len(carriers), "from_hz": low,
               "to_hz": high, "drive_fraction": round(level, 5), "profile": str(output)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"resonance {fit.resonance_hz:.1f} ± {fit.resonance_sigma_hz:.1f} Hz, Q {fit.q:.1f} ± {fit.q_sigma:.1f} "
              f"from the sensor, {len(carriers)} carriers at {level:.1%} of full-scale drive")
        if not args.sensor_um_per_unit:
            print("full scale kept from the profile: give --sensor-um-per-unit to measure it")
        print(f"profile written to {output}")
    return 0


def _grid(low_hz: float, high_hz: float, steps: int) -> np.ndarray:
    return np.linspace(low_hz, high_hz, steps)


def sweep(sweeper: TelemetrySweeper, low_hz: float, high_hz: float, steps: int, say) -> tuple[list, ResonanceFit]:
    """Coarse sweep, then finer sweeps around the peak until the points span the resonance densely."""
    tau = sweeper.profile.time_constant_s
    points = [sweeper.measure(float(f), tau) for f in _grid(low_hz, high_hz, steps)]
    spacing = (high_hz - low_hz) / max(steps - 1, 1)
    best = max(points, key=lambda point: point.full_scale_um_pp).carrier_hz
    window = (max(low_hz, best - 2 * spacing), min(high_hz, best + 2 * spacing))
    say(f"coarse sweep: peak near {best:.0f} Hz; refining {window[0]:.0f}-{window[1]:.0f} Hz")
    for _ in range(3):
        points += [sweeper.measure(float(f), tau) for f in _grid(*window, FINE_STEPS)]
        fit = _fit(points, low_hz, high_hz)
        tau = fit.q / (math.pi * fit.resonance_hz)
        fine = (window[1] - window[0]) / (FINE_STEPS - 1)
        if fine <= fit.bandwidth_hz / 5:  # at least 5 points across the half-power width: enough
            break
        half = 2 * fit.bandwidth_hz
        window = (max(low_hz, fit.resonance_hz - half), min(high_hz, fit.resonance_hz + half))
        say(f"fit so far: {fit.resonance_hz:.1f} Hz, Q {fit.q:.1f}; refining {window[0]:.0f}-{window[1]:.0f} Hz")
    return points, fit


def _fit(points: list[SweepPoint], low_hz: float, high_hz: float) -> ResonanceFit:
    carriers = np.array([point.carrier_hz for point in points])
    gains = np.array([point.full_scale_um_pp for point in points])
    if gains.max() <= 0:
        raise DeviceError("the plate did not move at any carrier: check that it is connected and powered")
    try:
        fit = fit_resonance(carriers, gains)
    except FitError as error:
        raise DeviceError(f"no resonance found between {low_hz:g} and {high_hz:g} Hz ({error})") from None
    if not low_hz <= fit.resonance_hz <= high_hz:
        raise DeviceError(f"the amplitude peaks at the edge of {low_hz:g}-{high_hz:g} Hz: the resonance lies outside; "
                          "widen the sweep with --from-hz/--to-hz")
    return fit


def measured_profile(old: PlateProfile, fit: ResonanceFit, name: str) -> PlateProfile:
    """The profile the sweep found: its resonance, Q and full scale; the old limit kept (lowered only to the
    full scale if the plate cannot reach it), the carrier range kept."""
    full_scale = fit.peak_um_pp
    return PlateProfile(name, round(fit.resonance_hz, 2), round(fit.q, 2), round(full_scale, 4),
                        min(old.max_amplitude_um_pp, round(full_scale, 4)), old.carrier_min_hz, old.carrier_max_hz,
                        f"measured by ultraglide plate sweep from {old.name}, "
                        f"{time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC")


def write_profile(path: Path, profile: PlateProfile, fit: ResonanceFit) -> None:
    document = {key: getattr(profile, key) for key in PlateProfile.__dataclass_fields__}
    header = (f"# Plate profile measured by `ultraglide plate sweep` (load with --profile {path.name}).\n"
              f"# resonance {fit.resonance_hz:.2f} ± {fit.resonance_sigma_hz:.2f} Hz, "
              f"Q {fit.q:.2f} ± {fit.q_sigma:.2f}, "
              f"full scale {fit.peak_um_pp:.4f} ± {fit.peak_sigma_um_pp:.4f} µm p-p (one sigma)\n")
    with atomic_path(path) as temporary:
        temporary.write_text(header + tomli_w.dumps(document), encoding="utf-8")


def plot_sweep(path: Path, points: list[SweepPoint], fit: ResonanceFit, level_fraction: float) -> None:
    """The measured amplitudes and the fitted curve, at the sweep's drive, print quality."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    carriers = np.array([point.carrier_hz for point in points])
    measured = np.array([point.full_scale_um_pp for point in points]) * level_fraction
    span = np.linspace(carriers.min(), carriers.max(), 2000)
    near_peak = 3 * fit.bandwidth_hz
    span = np.union1d(span, np.linspace(fit.resonance_hz - near_peak, fit.resonance_hz + near_peak, 600))
    span = span[(span >= carriers.min()) & (span <= carriers.max())]
    figure, (whole, near) = plt.subplots(1, 2, figsize=(9, 3.6))
    for axes in (whole, near):
        axes.plot(carriers / 1000, measured, "o", markersize=3, label="measured")
        axes.plot(span / 1000, fit.amplitude_um_pp(span) * level_fraction, "-", linewidth=1,
                  label=f"fit: f0 = {fit.resonance_hz:.1f} ± {fit.resonance_sigma_hz:.1f} Hz, "
                        f"Q = {fit.q:.1f} ± {fit.q_sigma:.1f}")
        axes.set_xlabel("carrier frequency (kHz)")
        axes.set_ylabel("amplitude (µm p-p)")
        axes.grid(alpha=0.3)
    near.set_xlim((fit.resonance_hz - 3 * fit.bandwidth_hz) / 1000, (fit.resonance_hz + 3 * fit.bandwidth_hz) / 1000)
    whole.set_title("whole sweep")
    near.set_title("around the resonance")
    near.legend(fontsize=7, loc="lower center")
    figure.tight_layout()
    suffix = path.suffix.lower().lstrip(".")
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format=suffix, dpi=PLOT_DPI)
    plt.close(figure)


def run_sweep(args) -> int:
    profile = load_profile(args.profile)
    low = args.from_hz if args.from_hz is not None else profile.carrier_min_hz
    high = args.to_hz if args.to_hz is not None else profile.carrier_max_hz
    if not low < high:
        raise UsageError(f"--from-hz {low:g} must be below --to-hz {high:g}")
    profile.check_carrier(low)
    profile.check_carrier(high)
    if args.steps < 5:
        raise UsageError("--steps must be at least 5")
    output = Path(args.output)
    if output.suffix.lower() != ".toml":
        raise UsageError(f"{output}: the profile is written as TOML; name it PROFILE.toml")
    if args.plot and Path(args.plot).suffix.lower() not in (".png", ".pdf", ".svg"):
        raise UsageError(f"{args.plot}: the plot is drawn as PNG, PDF or SVG; name it so")
    for path in filter(None, (output, args.plot and Path(args.plot))):
        if not path.resolve().parent.is_dir():
            raise UsageError(f"{path}: its folder does not exist")
    kind = parse_device_url(args.device).kind
    if kind == "audio":
        if not args.sensor:
            raise UsageError("an audio output reports no amplitude: sweeping it needs a vibration sensor on an audio "
                             "input, given as --sensor audio:NAME")
        return run_audio_sweep(args, profile, low, high, output)  # a stop signal ends the stream, writes nothing
    if kind not in ("sim", "serial"):
        raise UsageError(f"{kind} measures nothing: sweep a plate driver (sim or serial:PORT), or audio with --sensor")
    say = (lambda message: None) if args.json else print

    device = open_device(args.device, profile, carrier_hz=low)
    sweeper = TelemetrySweeper(device, profile)
    try:  # a stop signal (Ctrl-C, SIGTERM, SIGHUP: apps/cli/signals.py) leaves through the finally
        sweeper.start(low)
        say(f"sweeping {low:g}-{high:g} Hz in {args.steps} steps at {sweeper.level_um_pp:.2f} µm p-p "
            f"({SWEEP_LEVEL:.0%} of the {profile.max_amplitude_um_pp:g} µm p-p limit)")
        points, fit = sweep(sweeper, low, high, args.steps, say)
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            sweeper.stop()  # ramp to rest, zero, disable
    found = measured_profile(profile, fit, output.stem)
    level_fraction = points[0].drive_fraction
    if args.plot:
        plot_sweep(Path(args.plot), points, fit, level_fraction)
    write_profile(output, found, fit)
    faults = {name: count for name, count in sweeper.fault_counts().items() if count}
    summary = {
        "resonance_hz": round(fit.resonance_hz, 3), "resonance_sigma_hz": float(f"{fit.resonance_sigma_hz:.4g}"),
        "q": round(fit.q, 3), "q_sigma": float(f"{fit.q_sigma:.4g}"), "bandwidth_hz": round(fit.bandwidth_hz, 3),
        "full_scale_um_pp": round(fit.peak_um_pp, 5), "full_scale_sigma_um_pp": float(f"{fit.peak_sigma_um_pp:.4g}"),
        "max_amplitude_um_pp": found.max_amplitude_um_pp, "rms_residual_um_pp": round(fit.rms_residual_um_pp, 5),
        "points": len(points), "unsettled_points": sweeper.unsettled, "from_hz": low, "to_hz": high,
        "drive_um_pp": round(level_fraction * profile.full_scale_um_pp, 4), "profile": str(output),
        "plot": args.plot, "faults": faults,
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"resonance {fit.resonance_hz:.1f} ± {fit.resonance_sigma_hz:.1f} Hz, Q {fit.q:.1f} ± {fit.q_sigma:.1f} "
          f"(half-power width {fit.bandwidth_hz:.1f} Hz), {fit.peak_um_pp:.3f} ± {fit.peak_sigma_um_pp:.3f} µm p-p "
          f"at full-scale drive; {len(points)} points")
    if found.max_amplitude_um_pp < profile.max_amplitude_um_pp:
        print(f"limit lowered from {profile.max_amplitude_um_pp:g} to {found.max_amplitude_um_pp:g} µm p-p: the plate "
              "cannot reach more at full-scale drive")
    else:
        print(f"limit kept at {found.max_amplitude_um_pp:g} µm p-p (a sweep never raises it)")
    if sweeper.unsettled:
        print(f"warning: {sweeper.unsettled} points did not settle within {MAX_FRAMES_PER_STEP} telemetry frames")
    if faults:
        print("device faults during the sweep: " + ", ".join(f"{count} {name}" for name, count in faults.items()))
    print(f"profile written to {output}" + (f"; response drawn in {args.plot}" if args.plot else ""))
    return 0
