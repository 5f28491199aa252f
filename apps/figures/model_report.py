"""``ultraglide model --report FILE.pdf``: one page on a model at one force: its parameters, its
curve, its inverse, and the contact physics of the paper at that force."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.apps.figures.style import mosaic, save
from ultraglide.render.physics.fingerprint import FingerParams, detach_amplitude_um_pp, glide_threshold_um_pp
from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.render.physics.normal_contact import cycle_reaction_n

A4_PORTRAIT_IN = (8.27, 11.69)


def write_report(path: Path, model: FrictionModel, summary: dict, params: FingerParams) -> list[Path]:
    """Draw the report page; ``summary`` is what ``ultraglide model`` prints (see model_command)."""
    force = summary["force_n"]
    fig, axes = mosaic([["text", "text"], ["curve", "inverse"], ["reaction", "thresholds"]],
                       figsize=A4_PORTRAIT_IN, height_ratios=[0.55, 1, 1])
    text = axes["text"]
    text.axis("off")
    lines = [f"ultraglide model report at {force:g} N", "", summary["model"], ""]
    lines += [f"{key} = {value:.6g}" if isinstance(value, float) else f"{key} = {value}"
              for key, value in model.parameters().items()]
    lines += ["",
              f"contact area {summary['contact_area_mm2']:.2f} mm², eq. (3);  normal stiffness "
              f"{summary['normal_stiffness_n_per_m']:.4g} N/m, eq. (1)",
              f"detachment amplitude {summary['detach_amplitude_um_pp']:.2f} µm p-p, eq. (6);  glide threshold "
              f"{summary['glide_threshold_um_pp']:.2f} µm p-p, eq. (5)",
              f"lowest ratio within 10 µm p-p: {float(model.floor_ratio(force, 10.0)):.3f}"]
    text.text(0.0, 1.0, lines[0], va="top", ha="left", fontsize=13, weight="bold")
    text.text(0.0, 0.85, "\n".join(lines[2:]), va="top", ha="left", fontsize=9, linespacing=1.5)

    top = min(10.0, model.max_amplitude_um_pp)
    amplitude = np.linspace(0.0, top, 301)
    curve, inverse = axes["curve"], axes["inverse"]
    for scale, style in ((0.5, ":"), (1.0, "-"), (2.0, "--")):
        f = force * scale
        curve.plot(amplitude, model.relative_friction(amplitude, f), style, color="k" if scale == 1 else "0.45",
                   label=f"{f:g} N")
    curve.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction µ/µ0", ylim=(0, 1.05), xlim=(0, top),
              title="(a) forward model")
    curve.legend(title="normal force")
    floor = float(model.floor_ratio(force, top))
    ratio = np.linspace(floor, 1.0, 400)
    inverse.plot(ratio, model.amplitude_um_pp(ratio, force, top).amplitude_um_pp, color="tab:blue",
                 label=f"{force:g} N")
    inverse.axvline(floor, color="0.5", ls=":", label=f"lowest reachable ratio {floor:.3f}")
    inverse.set(xlabel="target friction ratio µ/µ0", ylabel="amplitude needed (µm p-p)", xlim=(0, 1.0),
                ylim=(0, top * 1.05), title="(b) inverse used for rendering")
    inverse.legend(loc="upper right")

    reaction, thresholds = axes["reaction"], axes["thresholds"]
    phase = np.linspace(0.0, 2.0 * np.pi, 361)
    detach = float(detach_amplitude_um_pp(force, params))
    for factor, colour in ((0.5, "tab:blue"), (1.0, "tab:green"), (2.0, "tab:orange"), (4.0, "tab:red")):
        a = factor * detach
        reaction.plot(phase / (2 * np.pi) * 50.0, cycle_reaction_n(a, force, phase, params), color=colour,
                      label=f"{a:.2f} µm ({factor:g} W_c)")
    reaction.set(xlabel="time over one 20 kHz cycle (µs)", ylabel="plate reaction force (N)", xlim=(0, 50),
                 title=f"(c) contact over a cycle, {params.contact} pressure")
    reaction.legend(title="amplitude p-p", loc="upper right")
    reaction.set_ylim(0, None)
    forces = np.linspace(0.02, max(1.0, 2 * force), 200)
    thresholds.plot(forces, detach_amplitude_um_pp(forces, params), label="detachment, eq. (6)")
    thresholds.plot(forces, glide_threshold_um_pp(forces, params), "--", label="lateral glide, eq. (5)")
    thresholds.axvline(force, color="0.5", ls=":", label=f"{force:g} N")
    thresholds.set(xlabel="normal force (N)", ylabel="amplitude (µm p-p)", xlim=(0, forces[-1]), ylim=(0, None),
                   title="(d) thresholds of the paper's ridge model")
    thresholds.legend(loc="upper left")
    return save(fig, path, vector=None)
