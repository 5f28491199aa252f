"""The figure of a plate sweep: measured amplitudes (markers) and the fitted resonance curve (a line),
laid out for one IEEE column (3.5 in) or two (7.16 in)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.devices.characterisation.resonance import ResonanceFit
from ultraglide.devices.characterisation.sweep import SweepPoint

PLOT_DPI = 300


def plot_sweep(path: Path, points: list[SweepPoint], fit: ResonanceFit, level_fraction: float,
               width=None) -> None:
    """The measured amplitudes and the fitted curve, at the sweep's drive, print quality; the format is
    the file's suffix (PNG at 300 dpi, PDF, SVG)."""
    from ultraglide.apps.figures.style import PAGE_IN, figure, legend_below, save, width_of

    width_in = width_of(width)
    carriers = np.array([point.carrier_hz for point in points])
    measured = np.array([point.full_scale_um_pp for point in points]) * level_fraction
    span = np.linspace(carriers.min(), carriers.max(), 2000)
    near_peak = 3 * fit.bandwidth_hz
    span = np.union1d(span, np.linspace(fit.resonance_hz - near_peak, fit.resonance_hz + near_peak, 600))
    span = span[(span >= carriers.min()) & (span <= carriers.max())]
    page = width_in >= PAGE_IN
    rows, columns = (1, 2) if page else (2, 1)
    fig, (whole, near) = figure(rows, columns, figsize=(width_in, 3.0 if page else 5.2))
    for axes in (whole, near):
        axes.plot(carriers / 1000, measured, "o", markersize=3, label="measured")
        axes.plot(span / 1000, fit.amplitude_um_pp(span) * level_fraction, "-", linewidth=1,
                  label=f"fit: f0 = {fit.resonance_hz:.1f} ± {fit.resonance_sigma_hz:.1f} Hz, "
                        f"Q = {fit.q:.1f} ± {fit.q_sigma:.1f}")
        axes.set_xlabel("carrier frequency (kHz)")
        axes.set_ylabel("amplitude (µm p-p)")
    near.set_xlim((fit.resonance_hz - 3 * fit.bandwidth_hz) / 1000, (fit.resonance_hz + 3 * fit.bandwidth_hz) / 1000)
    whole.set_title("whole sweep")
    near.set_title("around the resonance")
    legend_below(near, ncol=1)
    save(fig, Path(path), vector=None)
