"""The paper's figures 2–9, drawn from our implementation of its model, laid out for print.

Each figure is drawn at the force the paper used for it unless a force is given (``--force``), in
which case every figure is drawn at that force, and at one IEEE column (3.5 in) or two (7.16 in),
text of 8 pt or more at that size. Each is written as a 300 dpi PNG and a PDF beside it. What is not
the paper's (the Hertzian panels of Figs. 5–6, the preloaded threshold of Fig. 3, the bundled
Monnoyer fit in Fig. 9) is labelled as what it is; fitted laws are lines, measurements markers.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from ultraglide.apps.figures import PAPER_FIGURES
from ultraglide.apps.figures.style import PAGE_IN, figure, legend_below, save, width_of
from ultraglide.render.physics.errors import QuasiStaticWarning
from ultraglide.render.physics.fingerprint import (
    FingerParams,
    detach_amplitude_um_pp,
    friction_coefficient,
    glide_threshold_um_pp,
    ridge_shear_resonance_hz,
)
from ultraglide.render.physics.lateral import (
    PSYCHOPHYSICS_FORCE_N,
    PSYCHOPHYSICS_PRELOAD_N,
    simulate_lateral,
    simulated_glide_threshold_um_pp,
    steady_glide_threshold_um_pp,
)
from ultraglide.render.physics.measurements import read_measurements
from ultraglide.render.physics.normal_contact import cycle_friction_n, cycle_reaction_n, relative_friction

FIGURE_AMPLITUDES_UM_PP = (0.1, 0.5, 1.0, 2.0, 4.0, 8.0)  # Figs. 5-6: 0.1 µm (blue) to 8 µm (red)
FORCES_N = np.linspace(0.02, 1.0, 99)
BUNDLED_FIT_NAME = "monnoyer2018-fit.csv"


def _size(width_in: float, height_ratio: float = 0.75, legend_in: float = 0.0) -> tuple[float, float]:
    """A figure's size: its width, a plot ``height_ratio`` of the width high (at most 3.2 in), plus room
    for a legend below."""
    return width_in, min(width_in * height_ratio, 3.2) + legend_in


def figure_2(path: Path, params: FingerParams, force_n: float = 0.5, width=None) -> list[Path]:
    """Lateral stick–slip over a cycle: mu_s = 1, mu_d = 0.7, 20 kHz, 5 µm p-p (the paper: 0.5 N)."""
    width_in = width_of(width)
    with warnings.catch_warnings():  # the paper's own frequency; the figure's note says how quasi-static it is
        warnings.simplefilter("ignore", QuasiStaticWarning)
        sim = simulate_lateral(5.0, force_n, 20e3, cycles=3, steps_per_cycle=2000, params=params)
    last = slice(-2001, None)
    t_us = (sim.time_s[last] - sim.time_s[last][0]) * 1e6
    fig, axis = figure(figsize=_size(width_in, 0.6, 0.9))
    position, velocity = sim.plate_position_m[last], sim.plate_velocity_m_per_s[last]
    sliding = sim.sliding[last]
    axis.fill_between(t_us, -1.1, 1.1, where=~sliding, color="0.88", lw=0, label="sticking")
    axis.fill_between(t_us, -1.1, 1.1, where=sliding, facecolor="none", edgecolor="tab:green", hatch="xx", lw=0,
                      label="sliding")
    axis.plot(t_us, position / np.abs(position).max(), label="position x / x_max")
    axis.plot(t_us, velocity / np.abs(velocity).max(), label="velocity V / V_max")
    axis.plot(t_us, sim.lateral_force_n[last] / force_n, color="k", label="lateral force F_l / F_n")
    axis.set(xlabel="time (µs)", ylabel="normalised value", ylim=(-1.1, 1.1), xlim=(0, 50),
             title=f"Fig. 2: lateral stick–slip, 20 kHz, 5 µm p-p, {force_n:g} N\n"
                   f"(quasi-static at {20e3 / ridge_shear_resonance_hz(params):.2f} of the ridges' shear "
                   "resonance)")
    legend_below(axis, ncol=2 if width_in < PAGE_IN else 5)
    return save(fig, path)


def figure_3(path: Path, params: FingerParams, force_n: float | None = None, width=None) -> list[Path]:
    """Glide threshold against normal force: closed form (5) and simulation, without and with the stated
    tangential preload, and the paper's psychophysics (2 µm not felt, 4 µm felt, at about 0.4 N)."""
    width_in = width_of(width)
    fig, axis = figure(figsize=_size(width_in, 0.7, 1.3))
    axis.plot(FORCES_N, glide_threshold_um_pp(FORCES_N, params), label="onset from rest, eq. (5)")
    axis.plot(FORCES_N, steady_glide_threshold_um_pp(FORCES_N, params), "--", label="steady slip, (µs + µd) F / k_t")
    preload = PSYCHOPHYSICS_PRELOAD_N
    reachable = FORCES_N > preload / params.static_friction
    axis.plot(FORCES_N[reachable], glide_threshold_um_pp(FORCES_N[reachable], params, preload), "-.",
              label=f"onset with a {preload:g} N tangential preload")
    forces = np.array([0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0])
    simulated = [simulated_glide_threshold_um_pp(f, params, tolerance_um=0.01) for f in forces]
    axis.plot(forces, simulated, "o", mfc="none", label="time-domain simulation of eq. (4)")
    axis.plot([PSYCHOPHYSICS_FORCE_N], [2.0], "kx", markersize=7, label="psychophysics: 2 µm not felt")
    axis.plot([PSYCHOPHYSICS_FORCE_N], [4.0], "k*", markersize=8, label="psychophysics: 4 µm felt")
    if force_n is not None:
        threshold = float(glide_threshold_um_pp(force_n, params))
        axis.plot([force_n], [threshold], "s", color="tab:red", label=f"{force_n:g} N: {threshold:.2f} µm p-p")
    axis.set(xlabel="normal force F_n (N)", ylabel="glide threshold (µm p-p)", xlim=(0, 1.0), ylim=(0, None),
             title="Fig. 3a: glide threshold of lateral vibration")
    legend_below(axis, ncol=1 if width_in < PAGE_IN else 3)
    return save(fig, path)


def figure_4(path: Path, params: FingerParams, force_n: float = 0.15, width=None) -> list[Path]:
    """Detachment amplitude against normal force (6), with the worked example (the paper: 0.15 N)."""
    width_in = width_of(width)
    fig, axis = figure(figsize=_size(width_in, 0.65, 0.55))
    axis.plot(FORCES_N, detach_amplitude_um_pp(FORCES_N, params), label="2 F_n / k_n, eq. (6) read peak-to-peak")
    example = float(detach_amplitude_um_pp(force_n, params))
    axis.plot([force_n], [example], "o", color="tab:red", label=f"{force_n:g} N needs {example:.2f} µm p-p")
    axis.set(xlabel="normal force F_n (N)", ylabel="detachment amplitude (µm p-p)", xlim=(0, 1.0), ylim=(0, None),
             title="Fig. 4: detachment of the fingerprint ridges")
    legend_below(axis, ncol=1 if width_in < PAGE_IN else 2)
    return save(fig, path)


def _cycle_figure(path: Path, params: FingerParams, friction: bool, force_n: float = 0.5, width=None) -> list[Path]:
    width_in = width_of(width)
    phase = np.linspace(0.0, 2.0 * np.pi, 721)
    time_us = phase / (2.0 * np.pi) * 50.0  # 20 kHz
    page = width_in >= PAGE_IN
    rows, columns = (1, 2) if page else (2, 1)
    panel_in = 2.2 if page else 1.9
    fig, axes = figure(rows, columns, figsize=(width_in, rows * panel_in + 1.4), sharey=True)
    titles = {"uniform": "uniform bed (the paper's)", "hertz": "Hertzian pressure, eq. (8) (ours)"}
    colours = [(t, 0.2, 1.0 - t) for t in np.linspace(0.0, 1.0, len(FIGURE_AMPLITUDES_UM_PP))]
    for axis, contact in zip(axes, ("uniform", "hertz"), strict=True):
        p = params.with_(contact=contact)
        for amplitude, colour in zip(FIGURE_AMPLITUDES_UM_PP, colours, strict=True):
            if friction:
                value = cycle_friction_n(amplitude, force_n, phase, p)
                mean = float(np.mean(value[:-1]))
                axis.plot(time_us, value, color=colour, label=f"{amplitude:g} µm, {mean:.3f} N")
            else:
                axis.plot(time_us, cycle_reaction_n(amplitude, force_n, phase, p), color=colour,
                          label=f"{amplitude:g} µm")
        if friction:
            still = float(cycle_friction_n(0.0, force_n, 0.0, p))
            axis.axhline(still, color="0.3", ls=":", lw=1, label=f"at rest, {still:.3f} N")
        axis.set(xlabel="time in a 20 kHz cycle (µs)", title=titles[contact], xlim=(0, 50))
        axis.set_ylabel("friction µ_1N F^n (N)" if friction else "plate reaction (N)")
    title = "amplitude p-p, cycle mean" if friction else "amplitude p-p"
    handles, labels = axes[-1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=(2 if friction else 3) if not page else 4,
               title=title)
    if friction:
        fig.suptitle(f"Fig. 6: friction over a cycle, {force_n:g} N, n = {params.friction_exponent:.3g}")
    else:
        fig.suptitle(f"Fig. 5: plate reaction over a 20 kHz cycle, {force_n:g} N")
    return save(fig, path)


def figure_7(path: Path, params: FingerParams, force_n: float | None = None, width=None) -> list[Path]:
    """The non-Coulombic coefficient of friction against normal force."""
    width_in = width_of(width)
    forces = np.linspace(0.05, 2.0, 200)
    fig, axis = figure(figsize=_size(width_in, 0.65, 0.7))
    axis.plot(forces, friction_coefficient(forces, params),
              label=f"µ = µ_1N F^(n−1), n = {params.friction_exponent:.3g}, "
                    f"µ_1N = {params.friction_coefficient_at_1n:g}")
    axis.plot(forces, np.full_like(forces, params.dynamic_friction), "--", color="0.5",
              label=f"Coulomb, constant µd = {params.dynamic_friction:g}")
    if force_n is not None:
        mu = float(friction_coefficient(force_n, params))
        axis.plot([force_n], [mu], "o", color="tab:red", label=f"{force_n:g} N: µ = {mu:.2f}")
    axis.set(xlabel="normal force F_n (N)", ylabel="coefficient of friction µ", xlim=(0, 2.0), ylim=(0, None),
             title="Fig. 7: non-Coulombic friction of a finger pad")
    legend_below(axis, ncol=1 if width_in < PAGE_IN else 3)
    return save(fig, path)


def figure_8(path: Path, params: FingerParams, force_n: float | None = None, width=None) -> list[Path]:
    """Relative coefficient of friction against vibration amplitude (both pressure profiles)."""
    width_in = width_of(width)
    amplitude = np.linspace(0.0, 10.0, 201)
    forces = (0.2, 0.5, 1.0) if force_n is None else (force_n,)
    fig, axis = figure(figsize=_size(width_in, 0.65, 0.75))
    for contact, style in (("hertz", "-"), ("uniform", "--")):
        for force, colour in zip(forces, ("tab:blue", "tab:orange", "tab:green"), strict=False):
            ratio = relative_friction(amplitude, force, params.with_(contact=contact))
            axis.plot(amplitude, ratio, style, color=colour, label=f"{contact}, {force:g} N")
    axis.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction F_l(a) / F_l(0)", ylim=(0.5, 1.02),
             xlim=(0, 10), title="Fig. 8: reduction from non-Coulombic friction")
    legend_below(axis, ncol=2 if width_in < PAGE_IN else 6)
    return save(fig, path)


def figure_9(path: Path, params: FingerParams, data_path: Path | None, force_n: float = 0.35,
             model=None, width=None) -> list[Path]:
    """The paper's model at its comparison force (0.35 N, three fingers of [16] at 25 kHz, which are
    not bundled); other curves are drawn as lines and labelled as what they are (the bundled Monnoyer
    fit is a fitted law, not measurements), measured points of ``--data`` as markers."""
    width_in = width_of(width)
    amplitude = np.linspace(0.0, 10.0, 201)
    fig, axis = figure(figsize=_size(width_in, 0.7, 1.1))
    for contact, style in (("hertz", "-"), ("uniform", "--")):
        axis.plot(amplitude, relative_friction(amplitude, force_n, params.with_(contact=contact)), style,
                  color="k", label=f"paper model, {contact}, {force_n:g} N")
    if model is not None and model.name not in ("paper",):
        axis.plot(amplitude, model.relative_friction(np.minimum(amplitude, model.max_amplitude_um_pp), force_n),
                  "-.", color="tab:purple", label=f"{model.name} model, {force_n:g} N")
    if data_path is not None:
        data = read_measurements(data_path)
        forces = data.force_n if data.force_n is not None else np.full(len(data), np.nan)
        if Path(data.source).name == BUNDLED_FIT_NAME:
            order = np.argsort(data.amplitude_um_pp)
            axis.plot(data.amplitude_um_pp[order], data.relative_friction[order], "-", color="tab:orange",
                      label="Monnoyer et al. 2018 fitted law (force not stated)")
        else:
            for force in np.unique(forces):
                pick = forces == force if np.isfinite(force) else np.isnan(forces)
                where = f", {force:g} N" if np.isfinite(force) else ""
                axis.plot(data.amplitude_um_pp[pick], data.relative_friction[pick], "o", mfc="none",
                          label=f"measured, {Path(data.source).name}{where}")
    axis.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction µ/µ0", ylim=(0, 1.05), xlim=(0, 10),
             title=f"Fig. 9: the paper's model at {force_n:g} N")
    legend_below(axis, ncol=1 if width_in < PAGE_IN else 2,
                 title="the paper's measured fingers [16] are not bundled")
    return save(fig, path)


def write_paper_figures(directory: Path, data_path: Path | None, params: FingerParams = FingerParams(),
                        force_n: float | None = None, model=None, width=None) -> list[Path]:
    """Write figs. 2–9 into ``directory`` as PNG (300 dpi) and PDF; returns the PNG paths.

    ``force_n``: draw every figure at this force; None draws each at the paper's own force.
    ``width``: ``"column"`` (3.5 in, the default) or ``"page"`` (7.16 in)."""
    directory.mkdir(parents=True, exist_ok=True)
    fig2, fig3, fig4, fig5, fig6, fig7, fig8, fig9 = (directory / f"{stem}.png" for stem in PAPER_FIGURES)

    def at(default: float) -> float:
        return default if force_n is None else force_n
    written = [
        figure_2(fig2, params, at(0.5), width),
        figure_3(fig3, params, force_n, width),
        figure_4(fig4, params, at(0.15), width),
        _cycle_figure(fig5, params, friction=False, force_n=at(0.5), width=width),
        _cycle_figure(fig6, params, friction=True, force_n=at(0.5), width=width),
        figure_7(fig7, params, force_n, width),
        figure_8(fig8, params, force_n, width),
        figure_9(fig9, params, data_path, at(0.35), model, width),
    ]
    return [paths[0] for paths in written]
