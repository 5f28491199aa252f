"""The best tracking a plate allows: how close any controller can bring a finger's friction to a grating's target
when the plate's envelope is a first-order lag (tau = Q / (pi f0)) and the drive is bounded.

For a 1 mm sine grating (ratio 0.4-1.0) swept at a speed, the finger's law known exactly (the bench's default finger
at a steady 0.5 N, not drifting), the amplitude each instant needs is the law's inverse of the target. The plate's
amplitude is y' = (u - y) / tau with the drive u within bounds: 0 to the drive ceiling (a drive that only pushes:
the firmware's now), or from minus the limit (the carrier in antiphase, braking) to the ceiling. Over whole periods
of the steady sweep, the drive that brings the finger's ratio closest to the target in the least-squares sense
(linearised: each instant's amplitude error weighted by the law's local slope, then the ratio computed exactly) is
found by bounded linear least squares with the plate's response as the matrix, knowing the whole future (no
controller does better). Errors are counted where the limit allows the target, as the bench counts them.

    best = plate_bound(speed_mm_s=200.0, brake=False)   # {'rms': ..., 'reachable': ...}
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import lsq_linear

RATE_HZ = 12000.0  # the control rate: the amplitude is followed sample by sample at it
PERIODS = 6  # steady sweep: the middle periods are scored (the first settle, the last has no future)


def _finger_inverse(law, ratio: np.ndarray, force_n: float, limit_um_pp: float) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes giving each ratio with the finger's law (the limit where it cannot: a monotone law, inverted on a
    grid 1.5 nm apart), and which it reaches."""
    grid = np.linspace(0.0, limit_um_pp, 4001)
    curve = law(grid, np.full(len(grid), force_n))  # falling with amplitude
    floor = float(curve[-1])
    amplitude = np.interp(-np.asarray(ratio), -curve, grid)  # np.interp needs rising abscissae
    return np.where(ratio <= floor, limit_um_pp, amplitude), ratio >= floor


def plate_bound(speed_mm_s: float, brake: bool, tau_s: float = 0.0025464790894703256, limit_um_pp: float = 6.0,
                ceiling_um_pp: float = 8.0, wavelength_mm: float = 1.0, ratio_range=(0.4, 1.0),
                force_n: float = 0.5) -> dict:
    """The least RMS ratio error any controller reaches on this plate (see the module docstring)."""
    from ultraglide.render.engine.finger_setup import FingerConfig, finger_law

    law = finger_law(FingerConfig())
    period_s = wavelength_mm / speed_mm_s
    n = int(round(PERIODS * period_s * RATE_HZ))
    t = np.arange(n) / RATE_HZ
    low, high = ratio_range
    target = low + (high - low) * 0.5 * (1.0 + np.cos(2.0 * math.pi * t / period_s))
    wanted, reachable = _finger_inverse(law, target, force_n, limit_um_pp)
    # the law's local slope |d ratio / d amplitude| at each wanted amplitude: the weight of its amplitude error
    step = 1e-3
    slope = np.abs(law(wanted + step, np.full(n, force_n)) - law(np.maximum(wanted - step, 0.0), np.full(n, force_n)))
    slope /= (wanted + step) - np.maximum(wanted - step, 0.0)
    weight = np.where(reachable, slope, 0.0) + 1e-3
    a = math.exp(-1.0 / (RATE_HZ * tau_s))
    # y_k = sum_j<=k a^(k-j) (1 - a) u_j, from rest: a lower-triangular Toeplitz matrix
    powers = a ** np.arange(n)
    index = np.subtract.outer(np.arange(n), np.arange(n))
    response = np.where(index >= 0, (1.0 - a) * powers[np.clip(index, 0, n - 1)], 0.0)
    lower = -limit_um_pp if brake else 0.0
    fit = lsq_linear(response * weight[:, None], wanted * weight, bounds=(lower, ceiling_um_pp), method="bvls")
    amplitude = np.abs(response @ fit.x)  # an antiphase envelope is felt as its magnitude
    felt = law(amplitude, np.full(n, force_n))
    scored = (t >= 2 * period_s) & (t < (PERIODS - 1) * period_s) & reachable
    return {"rms": float(np.sqrt(np.mean((felt[scored] - target[scored]) ** 2))),
            "reachable": float(np.mean(reachable[(t >= 2 * period_s) & (t < (PERIODS - 1) * period_s)])),
            "peak_um_pp": float(amplitude.max()), "lowest_drive_um_pp": float(fit.x.min())}


if __name__ == "__main__":
    for speed in (50.0, 100.0, 200.0):
        print(speed, {brake: plate_bound(speed, brake) for brake in (False, True)})
