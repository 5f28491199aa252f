"""The figure written beside a calibration file: data and fitted curves per force, residuals, and
the cross-validated errors (of every model, with ``--compare``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.apps.figures.style import figure, save
from ultraglide.render.physics.calibration import Fit

CV_LABELS = {"k_fold": "k-fold", "leave_one_force_out": "leave one force out",
             "leave_one_participant_out": "leave one participant out"}


def _forces(fit: Fit) -> np.ndarray:
    data = fit.data
    return data.force_n if data.force_n is not None else np.full(len(data), 0.5)


def write_calibration_figure(fits: list[Fit], path: Path) -> list[Path]:
    """Draw ``fits[0]`` (the chosen or best model) against its data, and the CV errors of all ``fits``."""
    fit = fits[0]
    data = fit.data
    forces = _forces(fit)
    fig, (curves, residuals, errors) = figure(1, 3, figsize=(11.5, 3.6))
    top = max(float(data.amplitude_um_pp.max()) * 1.05, 1.0)
    amplitude = np.linspace(0.0, min(top, fit.model.max_amplitude_um_pp), 300)
    palette = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:gray")
    colours = dict(zip(np.unique(forces), palette, strict=False))
    for force in np.unique(forces):
        pick = forces == force
        colour = colours.get(force, "k")
        curves.plot(data.amplitude_um_pp[pick], data.relative_friction[pick], "o", color=colour, mfc="none",
                    label=f"data, {force:g} N")
        curves.plot(amplitude, fit.model.relative_friction(amplitude, float(force)), "-", color=colour,
                    label=f"{fit.kind} fit, {force:g} N")
        residuals.plot(data.amplitude_um_pp[pick], fit.residuals[pick], "o", color=colour, label=f"{force:g} N")
    curves.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction µ/µ0", ylim=(0, 1.08),
               title=f"(a) {fit.kind} fitted to {Path(data.source).name}")
    curves.legend(ncol=1 if len(colours) < 4 else 2)
    residuals.axhline(0.0, color="0.4", lw=0.8)
    residuals.set(xlabel="vibration amplitude (µm p-p)", ylabel="residual, measured − model",
                  title=f"(b) residuals (rms {fit.rms_residual:.3f})")
    schemes = [name for name in CV_LABELS if any(name in f.cross_validation for f in fits)]
    width = 0.8 / max(len(schemes), 1)
    position = np.arange(len(fits))
    for i, scheme in enumerate(schemes):
        values = [f.cross_validation.get(scheme, np.nan) for f in fits]
        bars = errors.bar(position + (i - (len(schemes) - 1) / 2) * width, values, width, label=CV_LABELS[scheme])
        errors.bar_label(bars, fmt="%.3f", fontsize=6.5, padding=1)
    errors.set_xticks(position, [f.kind for f in fits], rotation=20 if len(fits) > 2 else 0)
    errors.set(ylabel="cross-validated rms error (relative friction)", title="(c) prediction of unseen points")
    if schemes:
        errors.legend()
    return save(fig, path)
