"""Measuring a plate: the resonance sweep, on a plate driver that reports its amplitude in telemetry or on an
audio output with a vibration sensor on an audio input.

The carrier steps across a range while the plate is driven at a low constant amplitude (15 % of its
limit); at each step, once telemetry shows the amplitude settled at the new carrier, the measured
amplitude is read (:class:`TelemetrySweeper`). An audio sweep plays the stepped carrier and reads the
sensor's amplitude at each carrier with a lock-in (:func:`lock_in_amplitude`). A resonance curve is
fitted (:mod:`ultraglide.devices.characterisation.resonance`), a finer sweep is made around the peak
(:func:`sweep`), and :func:`measured_profile` is the profile that results.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass

import numpy as np
from ultraglide.devices.characterisation.resonance import FitError, ResonanceFit, fit_resonance, load_fitter
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile

SWEEP_LEVEL = 0.15  # drive during a sweep: this fraction of the plate's limit, µm p-p at resonance
SAFE_FRACTION = 0.5  # a measured amplitude above this fraction of the limit halves the drive
SETTLE_TAUS = 5.0  # wait at least this many envelope time constants after a carrier change
SETTLE_TOLERANCE = 0.01  # two successive telemetry frames agreeing this closely (relative): settled
MAX_FRAMES_PER_STEP = 25  # a step that never settles takes its last frame and says so
FINE_STEPS = 25


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
        self.limit_um_pp = profile.max_amplitude_um_pp  # the device's own once it has said, if smaller
        self.level_um_pp = SWEEP_LEVEL * self.limit_um_pp
        self.source = SteadyDrive(self.level_um_pp, device.rate_hz)
        self.unsettled = 0
        load_fitter()  # now, not between two frames of the stream

    def start(self, carrier_hz: float) -> None:
        """Connect and drive at 15 % of the smaller of the profile's and the device's limits."""
        self.driver.carrier_hz = carrier_hz
        if hasattr(self.driver, "sweeping"):  # a serial plate judges whether it follows what it is sent
            self.driver.sweeping()
        self.device.start(self.source)
        bound = getattr(self.driver, "limit_um_pp", self.limit_um_pp)
        if bound < self.limit_um_pp:
            self.limit_um_pp = bound
            self.level_um_pp = self.source.amplitude_um_pp = SWEEP_LEVEL * bound

    def measure(self, carrier_hz: float, time_constant_s: float) -> SweepPoint:
        self.driver.set_carrier(carrier_hz)
        changed = time.monotonic()
        previous = amplitude = None
        reported = None
        for _ in range(MAX_FRAMES_PER_STEP):
            telemetry = self.driver.next_telemetry()
            self._check(telemetry)
            if abs(telemetry.carrier_hz - carrier_hz) > 0.01:
                reported = telemetry.carrier_hz
                continue  # from before the change
            amplitude = telemetry.measured_um_pp
            if not math.isfinite(amplitude) or amplitude < 0.0:
                raise DeviceError(f"the plate driver reported a measured amplitude of {amplitude} µm p-p at "
                                  f"{carrier_hz:.1f} Hz, which cannot be: check its sensor and firmware")
            if amplitude > SAFE_FRACTION * self.limit_um_pp:
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
        if amplitude is None:  # no telemetry at the carrier it was set to: it does not follow SET_CARRIER
            raise DeviceError(f"the plate driver does not follow the carrier: set to {carrier_hz:.1f} Hz, its "
                              f"telemetry said {reported:.1f} Hz for {MAX_FRAMES_PER_STEP} frames; check its "
                              "firmware (SET_CARRIER)")
        self.unsettled += 1
        return SweepPoint(carrier_hz, amplitude, self.drive_fraction, False)

    @property
    def drive_fraction(self) -> float:
        """The drive as a fraction of full scale: the device's full scale, by which its codes are scaled."""
        return self.source.amplitude_um_pp / getattr(self.driver, "full_scale_um_pp", self.profile.full_scale_um_pp)

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


def audio_sweep(output, sensor, carriers_hz: np.ndarray, level: float, rate_hz: int,
                hold=contextlib.nullcontext) -> np.ndarray:
    """Play the stepped carrier on ``output`` while recording ``sensor``; the sensor's amplitude at each carrier.
    ``hold``: a context manager the stream is stopped inside (the command's, which holds back stop signals)."""
    from ultraglide.devices.sinks.audio import import_sounddevice

    sd = import_sounddevice()
    played = sweep_signal(carriers_hz, level, rate_hz)
    try:
        recorded = sd.playrec(played, samplerate=rate_hz, channels=1, dtype="float32", device=(sensor, output),
                              blocking=True)[:, 0]
    except sd.PortAudioError as error:
        raise DeviceError(f"audio sweep: {error}; list devices with `ultraglide devices`") from None
    finally:
        with hold():  # the caller's guard against a stop signal cutting the stream's end short
            sd.stop()
    dwell = int(round(AUDIO_DWELL_S * rate_hz))
    skip = int(AUDIO_SETTLE_FRACTION * dwell)
    return np.array([lock_in_amplitude(recorded[i * dwell + skip:(i + 1) * dwell], f, rate_hz)
                     for i, f in enumerate(carriers_hz)])


def sweep_grid(low_hz: float, high_hz: float, steps: int) -> np.ndarray:
    return np.linspace(low_hz, high_hz, steps)


def sweep(sweeper: TelemetrySweeper, low_hz: float, high_hz: float, steps: int, say) -> tuple[list, ResonanceFit]:
    """Coarse sweep, then finer sweeps around the peak until the points span the resonance densely."""
    tau = sweeper.profile.time_constant_s
    points = [sweeper.measure(float(f), tau) for f in sweep_grid(low_hz, high_hz, steps)]
    spacing = (high_hz - low_hz) / max(steps - 1, 1)
    best = max(points, key=lambda point: point.full_scale_um_pp).carrier_hz
    window = (max(low_hz, best - 2 * spacing), min(high_hz, best + 2 * spacing))
    say(f"coarse sweep: peak near {best:.0f} Hz; refining {window[0]:.0f}-{window[1]:.0f} Hz")
    for _ in range(3):
        points += [sweeper.measure(float(f), tau) for f in sweep_grid(*window, FINE_STEPS)]
        fit = fit_sweep(points, low_hz, high_hz)
        tau = fit.q / (math.pi * fit.resonance_hz)
        fine = (window[1] - window[0]) / (FINE_STEPS - 1)
        if fine <= fit.bandwidth_hz / 5:  # at least 5 points across the half-power width: enough
            break
        half = 2 * fit.bandwidth_hz
        window = (max(low_hz, fit.resonance_hz - half), min(high_hz, fit.resonance_hz + half))
        say(f"fit so far: {fit.resonance_hz:.1f} Hz, Q {fit.q:.1f}; refining {window[0]:.0f}-{window[1]:.0f} Hz")
    return points, fit


def fit_sweep(points: list[SweepPoint], low_hz: float, high_hz: float) -> ResonanceFit:
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
    full scale if the plate cannot reach it), the old overdrive headroom (``max_drive_um_pp``) kept (lowered
    only to the full scale, never below the limit), the carrier range and ``allow_audible`` kept."""
    full_scale = round(fit.peak_um_pp, 4)
    limit = min(old.max_amplitude_um_pp, full_scale)
    return PlateProfile(name, round(fit.resonance_hz, 2), round(fit.q, 2), full_scale, limit, old.carrier_min_hz,
                        old.carrier_max_hz, f"measured by ultraglide plate sweep from {old.name}, "
                        f"{time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC",
                        max_drive_um_pp=max(limit, min(old.max_drive_um_pp, full_scale)),
                        allow_audible=old.allow_audible)
