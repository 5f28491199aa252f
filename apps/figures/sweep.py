"""The figure of a plate sweep: measured amplitudes and the fitted resonance curve."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.apps.cli.files import atomic_path
from ultraglide.devices.resonance import ResonanceFit
from ultraglide.devices.sweep import SweepPoint

PLOT_DPI = 300


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


