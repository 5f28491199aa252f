"""``ultraglide model --report FILE.pdf``: one page on a model at one force: its description, force
law and parameters, its curve at F/2, F and 2F, the inverse used for rendering and, for the models
built on the paper's ridges only, the contact over a cycle and the thresholds of eqs. (5)-(6).
Laid out for print at one or two IEEE columns (``width``)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
from ultraglide.apps.figures.style import PAGE_IN, legend_below, mosaic, save, width_of
from ultraglide.render.physics.fingerprint import FingerParams, detach_amplitude_um_pp, glide_threshold_um_pp
from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.render.physics.normal_contact import cycle_reaction_n


def _words(model: FrictionModel, summary: dict, width_in: float) -> str:
    """The report's text block, wrapped to the page (about 14 characters an inch at 8 pt)."""
    force = summary["force_n"]
    low, high = summary["valid_force_range_n"]
    lines = [model.describe().split("; force law:")[0] + ".",
             f"Force law: {summary['force_law']}; holds on {low:.3g}-{high:.3g} N."]
    parameters = ", ".join(f"{key} = {value:.4g}" if isinstance(value, float) else f"{key} = {value}"
                           for key, value in model.parameters().items())
    if parameters:
        lines.append(f"Parameters: {parameters}.")
    if "contact_area_mm2" in summary:
        lines.append(f"At {force:g} N: contact area {summary['contact_area_mm2']:.1f} mm² (eq. 3), detachment "
                     f"{summary['detach_amplitude_um_pp']:.2f} µm p-p (eq. 6), lateral glide threshold "
                     f"{summary['glide_threshold_um_pp']:.2f} µm p-p (eq. 5), ridge shear resonance "
                     f"{summary['ridge_shear_resonance_hz'] / 1e3:.1f} kHz.")
    lines.append(f"Lowest ratio within 10 µm p-p at {force:g} N: {float(model.floor_ratio(force, 10.0)):.3f}.")
    characters = int(width_in * 12.0)
    return "\n".join(textwrap.fill(line, characters) for line in lines)


def write_report(path: Path, model: FrictionModel, summary: dict, params: FingerParams | None,
                 width: str | float | None = None) -> list[Path]:
    """Draw the report page; ``summary`` is what ``ultraglide model`` prints; ``params``: the ridges of a
    model built on them, else None (no contact panels: the model has no contact)."""
    width_in = width_of(width)
    force = summary["force_n"]
    panels = ["curve", "inverse"] + (["reaction", "thresholds"] if params is not None else [])
    columns = 2 if width_in >= PAGE_IN else 1
    rows = -(-len(panels) // columns)
    text = _words(model, summary, width_in)
    text_in = 0.16 * (text.count("\n") + 2)
    panel_in = 2.3 if columns == 1 else 2.6
    layout = [["text"] * columns] + [panels[r * columns:(r + 1) * columns] for r in range(rows)]
    fig, named = mosaic(layout, figsize=(width_in, text_in + rows * panel_in),
                        height_ratios=[text_in] + [panel_in] * rows)
    header = named["text"]
    header.axis("off")
    header.text(0.0, 1.0, f"Model report at {force:g} N\n{text}", va="top", ha="left", fontsize=8,
                transform=header.transAxes, linespacing=1.3)

    top = min(10.0, model.max_amplitude_um_pp)
    amplitude = np.linspace(0.0, top, 301)
    curve = named["curve"]
    for scale, style in ((0.5, ":"), (1.0, "-"), (2.0, "--")):
        f = force * scale
        curve.plot(amplitude, model.relative_friction(amplitude, f), style, color="k" if scale == 1 else "0.45",
                   label=f"{f:g} N")
    curve.set(xlabel="amplitude (µm p-p)", ylabel="friction ratio µ/µ0", ylim=(0, 1.05), xlim=(0, top),
              title="(a) forward model")
    legend_below(curve, ncol=3, title="normal force")
    floor = float(model.floor_ratio(force, top))
    ratio = np.linspace(floor, 1.0, 400)
    inverse = named["inverse"]
    inverse.plot(ratio, model.amplitude_um_pp(ratio, force, top).amplitude_um_pp, color="tab:blue",
                 label=f"{force:g} N")
    inverse.axvline(floor, color="0.5", ls=":", label=f"lowest, {floor:.3f}")
    inverse.set(xlabel="target ratio µ/µ0", ylabel="amplitude (µm p-p)", xlim=(0, 1.0), ylim=(0, top * 1.05),
                title="(b) inverse used for rendering")
    legend_below(inverse, ncol=2)
    if params is not None:
        reaction = named["reaction"]
        phase = np.linspace(0.0, 2.0 * np.pi, 361)
        detach = float(detach_amplitude_um_pp(force, params))
        for factor, colour in ((0.5, "tab:blue"), (1.0, "tab:green"), (2.0, "tab:orange"), (4.0, "tab:red")):
            a = factor * detach
            reaction.plot(phase / (2 * np.pi) * 50.0, cycle_reaction_n(a, force, phase, params), color=colour,
                          label=f"{a:.2f} µm, {factor:g} W_c")
        reaction.set(xlabel="time in a 20 kHz cycle (µs)", ylabel="plate reaction (N)", xlim=(0, 50),
                     title=f"(c) contact over a cycle, {params.contact}")
        reaction.set_ylim(0, None)
        legend_below(reaction, ncol=2, title="amplitude p-p")
        thresholds = named["thresholds"]
        forces = np.linspace(0.02, max(1.0, 2 * force), 200)
        thresholds.plot(forces, detach_amplitude_um_pp(forces, params), label="detach, eq. 6")
        thresholds.plot(forces, glide_threshold_um_pp(forces, params), "--", label="glide, eq. 5")
        thresholds.axvline(force, color="0.5", ls=":", label=f"{force:g} N")
        thresholds.set(xlabel="normal force (N)", ylabel="amplitude (µm p-p)", xlim=(0, forces[-1]), ylim=(0, None),
                       title="(d) thresholds of the ridge model")
        legend_below(thresholds, ncol=3)
    return save(fig, path, vector=None)
