"""A plate's resonance from measured amplitudes: the curve fit of a sweep, and a tracker that follows it.

Driven at carrier f with a constant drive, a resonator's steady vibration amplitude is
A(f) = A0 / sqrt(1 + (2Q(f - f0)/f0)²): the peak A0 (µm peak-to-peak) at the resonance f0 (Hz), half
power (A0/√2) at f0 ± f0/(2Q). :func:`fit_resonance` fits A0, f0 and Q to a sweep with
scipy.optimize.curve_fit and gives their standard uncertainties.

:class:`ResonanceTracker` follows a drifting resonance while the plate plays, from amplitude alone
(protocol v2's telemetry reports the measured amplitude and the carrier, not the phase). It dithers
the carrier between fc + δ and fc − δ, measures the gain (mean measured amplitude over mean
commanded amplitude, so a texture's changing drive cancels) on each side, and steps fc along the
gradient of log gain by a Newton step on the resonance curve. The steps also estimate how fast the
resonance drifts (an integral term, as in a second-order phase-locked loop), and between steps the
centre moves on at that rate, so a steady thermal drift is followed without lag. Phase would give the sign of the
detuning without dithering, but no telemetry here reports it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ultraglide.errors import UltraglideError


def resonance_curve(carrier_hz, peak_um_pp: float, resonance_hz: float, q: float):
    """A(f) = A0 / sqrt(1 + (2Q(f − f0)/f0)²), amplitudes in µm p-p, frequencies in Hz."""
    detuning = 2.0 * q * (np.asarray(carrier_hz, dtype=float) - resonance_hz) / resonance_hz
    return peak_um_pp / np.sqrt(1.0 + detuning * detuning)


class FitError(UltraglideError, ValueError):
    """The measurements do not show a resonance that can be fitted; a ``ValueError`` too.

    Examples
    --------
    >>> import numpy as np
    >>> fit_resonance(np.array([24000.0, 25000.0, 26000.0]), np.array([1.0, 1.0, 1.0]))   # Hz, µm p-p
    Traceback (most recent call last):
    ...
    ultraglide.devices.characterisation.resonance.FitError: a resonance fit needs at least 4 measured points
    """


@dataclass(frozen=True)
class ResonanceFit:
    """A fitted resonance with standard uncertainties (one sigma, from the fit's covariance)."""

    resonance_hz: float
    q: float
    peak_um_pp: float
    resonance_sigma_hz: float
    q_sigma: float
    peak_sigma_um_pp: float
    rms_residual_um_pp: float

    @property
    def bandwidth_hz(self) -> float:
        """Full width at half power, f0 / Q."""
        return self.resonance_hz / self.q

    def amplitude_um_pp(self, carrier_hz):
        return resonance_curve(carrier_hz, self.peak_um_pp, self.resonance_hz, self.q)


def load_fitter():
    """scipy's curve_fit, imported on first use (scipy.optimize is 0.3 s of CPU that a serial session without a
    fit need not spend). A caller that fits while it streams to a plate calls this before the stream starts: an
    import holds Python's interpreter lock for up to 20 ms at a time (70 ms beside four busy processes), which
    starves the stream's writer thread towards the plate's 100 ms watchdog."""
    from scipy.optimize import curve_fit

    return curve_fit


def fit_resonance(carrier_hz, amplitude_um_pp) -> ResonanceFit:
    """Fit :func:`resonance_curve` to amplitudes measured at carriers; FitError if there is no peak to fit.

    The starting point comes from the data: the highest point, and the width where the amplitude
    crosses 1/√2 of it (or the spacing of the points when the peak is narrower than that).
    """
    f = np.asarray(carrier_hz, dtype=float)
    a = np.asarray(amplitude_um_pp, dtype=float)
    if f.shape != a.shape or f.size < 4:
        raise FitError("a resonance fit needs at least 4 measured points")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(a))):
        raise FitError("the measurements contain non-finite values")
    order = np.argsort(f)
    f, a = f[order], a[order]
    top = int(np.argmax(a))
    if a[top] <= 0:
        raise FitError("the plate did not move at any carrier (all amplitudes are zero)")
    above = f[a >= a[top] / math.sqrt(2.0)]
    spacing = float(np.min(np.diff(np.unique(f)))) if np.unique(f).size > 1 else 1.0
    width = max(float(above.max() - above.min()), spacing)
    guess = (float(a[top]), float(f[top]), float(f[top]) / width)
    curve_fit = load_fitter()
    try:
        values, covariance = curve_fit(resonance_curve, f, a, p0=guess, maxfev=20000,
                                       bounds=([0.0, f.min() - 10 * width, 0.5], [np.inf, f.max() + 10 * width, 1e6]))
    except (RuntimeError, ValueError) as error:
        raise FitError(f"the resonance curve does not fit the measurements ({error})") from None
    sigmas = np.sqrt(np.diag(covariance)) if np.all(np.isfinite(covariance)) else np.full(3, math.inf)
    residual = a - resonance_curve(f, *values)
    return ResonanceFit(float(values[1]), float(values[2]), float(values[0]), float(sigmas[1]), float(sigmas[2]),
                        float(sigmas[0]), float(np.sqrt(np.mean(residual * residual))))


@dataclass(frozen=True)
class TrackerSettings:
    """How the tracker dithers and steps.

    ``dither_fraction``: δ as a fraction of the half bandwidth f0/(2Q) (0.2 costs 2 % of amplitude);
    ``frames_per_side``: telemetry frames averaged on each side of the dither, after the first one
    at a new carrier is skipped (it may not have settled: the envelope needs several Q/(π f0));
    ``step_gain``: fraction of the Newton step taken (below 1 for a Q that may be off by a factor 2);
    ``max_step_fraction``: the largest step, as a fraction of the half bandwidth (0.25 costs at most 3 %
    of amplitude if a step goes the wrong way);
    ``min_drive_fraction``: windows whose mean commanded amplitude is below this fraction of the
    limit carry too little signal and are skipped (finger lifted);
    ``rate_gain``: each step (Hz) times this (per second) is added to the drift-rate estimate (with the
    step gain 0.7 and a 0.12 s dither cycle, 0.8 makes an over-damped second-order loop, ζ ≈ 1.3);
    ``max_rate_hz_per_s``: the drift rate believed at most.
    """

    dither_fraction: float = 0.2
    frames_per_side: int = 2
    step_gain: float = 0.7
    max_step_fraction: float = 0.25
    min_drive_fraction: float = 0.02
    rate_gain: float = 0.8
    max_rate_hz_per_s: float = 200.0


class ResonanceTracker:
    """Follows a plate's resonance from (carrier, measured amplitude, commanded amplitude) observations.

    Not thread-safe by itself; the driver calls :meth:`observe` from one thread and reads
    :attr:`carrier_hz` (a float, replaced atomically) from another.

    ``resonance_hz`` and ``q`` are the starting estimate (the profile's); ``limit_um_pp`` scales the
    minimum useful drive; the carrier stays within ``carrier_min_hz..carrier_max_hz``.
    """

    def __init__(self, resonance_hz: float, q: float, limit_um_pp: float, carrier_min_hz: float,
                 carrier_max_hz: float, settings: TrackerSettings = TrackerSettings()):
        self.settings = settings
        self.q = q
        self.start_hz = float(resonance_hz)
        self.center_hz = float(resonance_hz)
        self.limit_um_pp = limit_um_pp
        self.carrier_min_hz = carrier_min_hz
        self.carrier_max_hz = carrier_max_hz
        self.updates = 0
        self.rejected = 0  # dither pairs whose difference no resonance curve can give
        self.rate_hz_per_s = 0.0  # the drift rate the steps have shown
        self._center_s: float | None = None  # when center_hz was estimated
        self._side = 1
        self._gains: dict[int, float] = {}
        self._skip = True
        self._measured = 0.0
        self._commanded = 0.0
        self._frames = 0
        self.carrier_hz = self._clamp(self.center_hz + self._side * self.dither_hz)

    @property
    def dither_hz(self) -> float:
        return self.settings.dither_fraction * self.center_hz / (2.0 * self.q)

    def summary(self) -> dict:
        """What it tracked, as plain JSON values: where it started and where the resonance is now (Hz), the
        drift between them, the drift rate it has seen (Hz/s), its steps and the steps it discarded."""
        return {"start_hz": round(self.start_hz, 2), "resonance_hz": round(self.center_hz, 2),
                "drift_hz": round(self.center_hz - self.start_hz, 2), "rate_hz_per_s": round(self.rate_hz_per_s, 3),
                "steps": self.updates, "discarded_steps": self.rejected}

    def _clamp(self, carrier_hz: float) -> float:
        return min(max(carrier_hz, self.carrier_min_hz), self.carrier_max_hz)

    def observe(self, carrier_hz: float, measured_um_pp: float, commanded_um_pp: float,
                now_s: float | None = None) -> None:
        """One telemetry frame: the carrier it reports, the amplitude it measured, and the mean amplitude
        the host commanded (µm p-p at resonance) over the interval it covers; ``now_s`` is when
        (perf_counter seconds, the default now)."""
        now_s = time.perf_counter() if now_s is None else now_s
        if self._center_s is None:
            self._center_s = now_s
        if abs(carrier_hz - self.carrier_hz) > 0.01:  # the device has not taken the new carrier yet
            return
        if self._skip:  # the first frame at a new carrier: the envelope may still be settling
            self._skip = False
            return
        if commanded_um_pp < self.settings.min_drive_fraction * self.limit_um_pp:
            return
        self._measured += measured_um_pp
        self._commanded += commanded_um_pp
        self._frames += 1
        if self._frames < self.settings.frames_per_side:
            return
        self._gains[self._side] = self._measured / self._commanded
        self._measured = self._commanded = 0.0
        self._frames = 0
        if len(self._gains) == 2:
            self._step()
        self._side = -self._side
        self._restart_side(now_s)

    def _restart_side(self, now_s: float) -> None:
        """Move the centre on by the drift rate and set this side's carrier; its first frame will be skipped."""
        self._skip = True
        self.center_hz = self._clamp(self.center_hz + self.rate_hz_per_s * (now_s - self._center_s))
        self._center_s = now_s
        self.carrier_hz = self._clamp(self.center_hz + self._side * self.dither_hz)

    def disturbed(self, now_s: float | None = None) -> None:
        """The device did not play what was commanded (underrun, watchdog, lost setpoints): this side's
        frames so far measure that, not the resonance; start the side again (the centre still drifts on)."""
        now_s = time.perf_counter() if now_s is None else now_s
        self._measured = self._commanded = 0.0
        self._frames = 0
        if self._center_s is None:
            self._center_s = now_s
        self._restart_side(now_s)

    def _step(self) -> None:
        """Newton step on log A(f): d log A/df = −k²x/(1 + k²x²) with k = 2Q/f0, x = f − f0; near the
        peak x ≈ −(d log A/df)/k², and the two-sided difference estimates the derivative."""
        upper, lower = self._gains.pop(1), self._gains.pop(-1)
        if upper <= 0 or lower <= 0:
            return
        # |d log A/df| is at most k/2 (at the half-power points), so two carriers 2δ apart differ by at
        # most δk = dither_fraction in log A: a larger difference is not the plate's response (the drive
        # was cut or held meanwhile), and is discarded
        difference = math.log(upper) - math.log(lower)
        if abs(difference) > 1.2 * self.settings.dither_fraction:
            self.rejected += 1
            return
        delta = self.dither_hz
        slope = difference / (2.0 * delta)
        k = 2.0 * self.q / self.center_hz
        half_band = self.center_hz / (2.0 * self.q)
        limit = self.settings.max_step_fraction * half_band
        step = max(-limit, min(limit, self.settings.step_gain * slope / (k * k)))
        self.center_hz = self._clamp(self.center_hz + step)
        rate = self.rate_hz_per_s + self.settings.rate_gain * step
        self.rate_hz_per_s = max(-self.settings.max_rate_hz_per_s, min(self.settings.max_rate_hz_per_s, rate))
        self.updates += 1
