"""The figure written beside a calibration file, laid out for one IEEE column (or two): the data and the
fitted law at each force with a band, the residuals, and the cross-validated errors (of every model, with
``--compare``). Measurements are markers, fitted laws lines; synthetic data say so in their source name."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
from ultraglide.apps.figures.style import PAGE_IN, figure, legend_below, save, width_of
from ultraglide.render.physics.calibration import Fit, selection_note

CV_LABELS = {"k_fold": "k-fold", "leave_one_force_out": "leave one force out",
             "leave_one_participant_out": "leave one participant out"}
PALETTE = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:gray")


def _forces(fit: Fit) -> np.ndarray:
    data = fit.data
    return data.force_n if data.force_n is not None else np.full(len(data), 0.5)


def write_calibration_figure(fits: list[Fit], path: Path, width=None) -> list[Path]:
    """Draw ``fits[0]`` (the chosen or best model) against its data, and the CV errors of all ``fits``.
    The band about each force's curve is ±2 rms of that force's residuals: where new points of the
    same series are expected to fall."""
    width_in = width_of(width)
    fit = fits[0]
    data = fit.data
    forces = _forces(fit)
    page = width_in >= PAGE_IN
    rows, columns = (1, 3) if page else (3, 1)
    fig, (curves, residuals, errors) = figure(rows, columns, figsize=(width_in, 3.6 if page else 8.2))
    model = fit.model
    model._range_said = True  # drawn at the data's own forces
    top = max(float(data.amplitude_um_pp.max()) * 1.05, 1.0)
    amplitude = np.linspace(0.0, min(top, model.max_amplitude_um_pp), 300)
    colours = dict(zip(np.unique(forces), PALETTE, strict=False))
    for force in np.unique(forces):
        pick = forces == force
        colour = colours.get(force, "k")
        curve = model.relative_friction(amplitude, float(force))
        spread = 2.0 * float(np.sqrt(np.mean(fit.residuals[pick] ** 2)))
        curves.fill_between(amplitude, curve - spread, curve + spread, color=colour, alpha=0.18, lw=0)
        curves.plot(data.amplitude_um_pp[pick], data.relative_friction[pick], "o", color=colour, mfc="none",
                    label=f"measured, {force:g} N")
        curves.plot(amplitude, curve, "-", color=colour, label=f"fit ± 2 rms, {force:g} N")
        residuals.plot(data.amplitude_um_pp[pick], fit.residuals[pick], "o", color=colour, mfc="none",
                       label=f"{force:g} N")
    curves.set(xlabel="amplitude (µm p-p)", ylabel="friction ratio µ/µ0", ylim=(-0.05, 1.1), xlim=(0, top),
               title=f"(a) {fit.kind} fitted to {Path(data.source).name}")
    legend_below(curves, ncol=2)
    residuals.axhline(0.0, color="0.4", lw=0.8)
    residuals.set(xlabel="amplitude (µm p-p)", ylabel="measured − model", xlim=(0, top),
                  title=f"(b) residuals, rms {fit.rms_residual:.3f}")
    schemes = [name for name in CV_LABELS if any(name in f.cross_validation for f in fits)]
    height_bar = 0.8 / max(len(schemes), 1)
    position = np.arange(len(fits))[::-1]  # the best model on top
    for i, scheme in enumerate(schemes):
        values = [f.cross_validation.get(scheme, np.nan) for f in fits]
        errors.barh(position - (i - (len(schemes) - 1) / 2) * height_bar, values, height_bar, label=CV_LABELS[scheme])
    errors.set_yticks(position, [f.kind for f in fits])
    errors.set(xlabel="cross-validated rms", title="(c) unseen points")
    errors.grid(axis="y", visible=False)
    note = textwrap.fill(selection_note(data).split(";")[0], 44 if not page else 34)
    if schemes:
        legend_below(errors, ncol=1, title=note)
    return save(fig, path)
