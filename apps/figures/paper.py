"""The paper's figures 2–9, drawn from our implementation of its model, at print quality.

Each figure is drawn at the force the paper used for it unless a force is given (``--force``), in
which case every figure is drawn at that force. Each is written as a 300 dpi PNG and a PDF beside it.
What is not the paper's (the Hertzian panels of Figs. 5–6, the bundled Monnoyer fit in Fig. 9) is
labelled as what it is.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.apps.figures.style import figure, save
from ultraglide.render.physics.fingerprint import (
    FingerParams,
    detach_amplitude_um_pp,
    friction_coefficient,
    glide_threshold_um_pp,
)
from ultraglide.render.physics.lateral import (
    simulate_lateral,
    simulated_glide_threshold_um_pp,
    steady_glide_threshold_um_pp,
)
from ultraglide.render.physics.measurements import read_measurements
from ultraglide.render.physics.normal_contact import cycle_friction_n, cycle_reaction_n, relative_friction

FIGURE_AMPLITUDES_UM_PP = (0.1, 0.5, 1.0, 2.0, 4.0, 8.0)  # Figs. 5-6: 0.1 µm (blue) to 8 µm (red)
FORCES_N = np.linspace(0.02, 1.0, 99)
BUNDLED_FIT_NAME = "monnoyer2018-fit.csv"


def figure_2(path: Path, params: FingerParams, force_n: float = 0.5) -> list[Path]:
    """Lateral stick–slip over a cycle: mu_s = 1, mu_d = 0.7, 20 kHz, 5 µm p-p (the paper: 0.5 N)."""
    sim = simulate_lateral(5.0, force_n, 20e3, cycles=3, steps_per_cycle=2000, params=params)
    last = slice(-2001, None)
    t_us = (sim.time_s[last] - sim.time_s[last][0]) * 1e6
    fig, axis = figure(figsize=(6.5, 3.6))
    position, velocity = sim.plate_position_m[last], sim.plate_velocity_m_per_s[last]
    sliding = sim.sliding[last]
    axis.fill_between(t_us, -1.1, 1.1, where=~sliding, color="0.88", lw=0, label="sticking (no relative motion)")
    axis.fill_between(t_us, -1.1, 1.1, where=sliding, facecolor="none", edgecolor="tab:green", hatch="xx", lw=0,
                      label="sliding")
    axis.plot(t_us, position / np.abs(position).max(), label="plate position x / x_max")
    axis.plot(t_us, velocity / np.abs(velocity).max(), label="plate velocity V / V_max")
    axis.plot(t_us, sim.lateral_force_n[last] / force_n, color="k", label="lateral force F_l / F_n")
    axis.set(xlabel="time (µs)", ylabel="normalised value (dimensionless)", ylim=(-1.1, 1.1), xlim=(0, 50),
             title=f"Fig. 2: steady lateral stick–slip, 20 kHz, 5 µm p-p, {force_n:g} N, µs = "
                   f"{params.static_friction:g}, µd = {params.dynamic_friction:g}")
    axis.legend(loc="lower left", ncol=2)
    return save(fig, path)


def figure_3(path: Path, params: FingerParams, force_n: float | None = None) -> list[Path]:
    """Glide threshold against normal force, closed form (5) and simulation."""
    fig, axis = figure(figsize=(6.0, 3.8))
    axis.plot(FORCES_N, glide_threshold_um_pp(FORCES_N, params), label="onset from rest, eq. (5)")
    axis.plot(FORCES_N, steady_glide_threshold_um_pp(FORCES_N, params), "--",
              label="steady slip, (µs + µd) F_n / k_t")
    forces = np.array([0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0])
    simulated = [simulated_glide_threshold_um_pp(f, params, tolerance_um=0.01) for f in forces]
    axis.plot(forces, simulated, "o", mfc="none", label="time-domain simulation of eq. (4)")
    axis.plot([0.4], [4.0], "k*", markersize=10, label="psychophysics: slip felt at 4 µm, about 0.4 N")
    if force_n is not None:
        threshold = float(glide_threshold_um_pp(force_n, params))
        axis.plot([force_n], [threshold], "s", color="tab:red", label=f"{force_n:g} N: {threshold:.2f} µm p-p")
    axis.set(xlabel="normal force F_n (N)", ylabel="glide threshold (µm p-p)", xlim=(0, 1.0), ylim=(0, None),
             title="Fig. 3a: glide threshold of lateral vibration")
    axis.legend()
    return save(fig, path)


def figure_4(path: Path, params: FingerParams, force_n: float = 0.15) -> list[Path]:
    """Detachment amplitude against normal force (6), with the worked example (the paper: 0.15 N)."""
    fig, axis = figure(figsize=(6.0, 3.8))
    axis.plot(FORCES_N, detach_amplitude_um_pp(FORCES_N, params), label="W_c = F_n / k_n, eq. (6), peak-to-peak")
    example = float(detach_amplitude_um_pp(force_n, params))
    axis.plot([force_n], [example], "o", color="tab:red", label=f"{force_n:g} N needs {example:.2f} µm p-p")
    axis.set(xlabel="normal force F_n (N)", ylabel="detachment amplitude (µm p-p)", xlim=(0, 1.0), ylim=(0, None),
             title="Fig. 4: detach condition of the fingerprint ridges")
    axis.legend()
    return save(fig, path)


def _cycle_figure(path: Path, params: FingerParams, friction: bool, force_n: float = 0.5) -> list[Path]:
    phase = np.linspace(0.0, 2.0 * np.pi, 721)
    time_us = phase / (2.0 * np.pi) * 50.0  # 20 kHz
    fig, axes = figure(1, 2, figsize=(10, 4.6), sharey=True, layout="constrained")
    titles = {"uniform": "uniform bed of springs (the paper's Figs. 5–6)",
              "hertz": "Hertzian pressure, eq. (8), per annulus (our extension)"}
    for axis, contact in zip(axes, ("uniform", "hertz"), strict=True):
        p = params.with_(contact=contact)
        colours = [(t, 0.2, 1.0 - t) for t in np.linspace(0.0, 1.0, len(FIGURE_AMPLITUDES_UM_PP))]
        for amplitude, colour in zip(FIGURE_AMPLITUDES_UM_PP, colours, strict=True):
            if friction:
                value = cycle_friction_n(amplitude, force_n, phase, p)
                mean = float(np.mean(value[:-1]))
                axis.plot(time_us, value, color=colour, label=f"{amplitude:g} µm ({mean:.3f} N)")
            else:
                axis.plot(time_us, cycle_reaction_n(amplitude, force_n, phase, p), color=colour,
                          label=f"{amplitude:g} µm")
        if friction:
            still = float(cycle_friction_n(0.0, force_n, 0.0, p))
            axis.axhline(still, color="0.3", ls=":", lw=1, label=f"plate at rest ({still:.3f} N)")
        axis.set(xlabel="time over one 20 kHz cycle (µs)", title=titles[contact], xlim=(0, 50))
        axis.legend(title="amplitude p-p" + (" (cycle-mean friction)" if friction else ""), ncol=2,
                    loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=7)
    if friction:
        axes[0].set_ylabel("friction force µ_1N F_reac^n (N)")
        fig.suptitle(f"Fig. 6: instantaneous non-Coulombic friction force over a cycle at {force_n:g} N "
                     f"(n = {params.friction_exponent:.3g}, µ_1N = {params.friction_coefficient_at_1n:g})")
    else:
        axes[0].set_ylabel("plate reaction force F_reac (N)")
        fig.suptitle(f"Fig. 5: plate reaction force over a 20 kHz cycle at {force_n:g} N")
    return save(fig, path)


def figure_7(path: Path, params: FingerParams, force_n: float | None = None) -> list[Path]:
    """The non-Coulombic coefficient of friction against normal force."""
    forces = np.linspace(0.05, 2.0, 200)
    fig, axis = figure(figsize=(6.0, 3.8))
    axis.plot(forces, friction_coefficient(forces, params),
                label=f"µ = µ_1N F^(n−1), n = {params.friction_exponent:.3g}, µ_1N = "
                      f"{params.friction_coefficient_at_1n:g} ")
    axis.plot(forces, np.full_like(forces, params.dynamic_friction), "--", color="0.5",
                label=f"Coulomb friction, constant µd = {params.dynamic_friction:g}")
    if force_n is not None:
        mu = float(friction_coefficient(force_n, params))
        axis.plot([force_n], [mu], "o", color="tab:red", label=f"{force_n:g} N: µ = {mu:.2f}")
    axis.set(xlabel="normal force F_n (N)", ylabel="coefficient of friction µ (dimensionless)", xlim=(0, 2.0),
             ylim=(0, None), title="Fig. 7: non-Coulombic friction of a finger pad on glass")
    axis.legend()
    return save(fig, path)


def figure_8(path: Path, params: FingerParams, force_n: float | None = None) -> list[Path]:
    """Relative coefficient of friction against vibration amplitude (both pressure profiles)."""
    amplitude = np.linspace(0.0, 10.0, 201)
    forces = (0.2, 0.5, 1.0) if force_n is None else (force_n,)
    fig, axis = figure(figsize=(6.0, 3.8))
    for contact, style in (("hertz", "-"), ("uniform", "--")):
        for force, colour in zip(forces, ("tab:blue", "tab:orange", "tab:green"), strict=False):
            ratio = relative_friction(amplitude, force, params.with_(contact=contact))
            axis.plot(amplitude, ratio, style, color=colour, label=f"{contact} pressure, {force:g} N")
    axis.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction F_l(a) / F_l(0)", ylim=(0, 1.05),
             xlim=(0, 10), title="Fig. 8: friction reduction from non-Coulombic friction")
    axis.legend(ncol=2)
    return save(fig, path)


def figure_9(path: Path, params: FingerParams, data_path: Path | None, force_n: float = 0.35,
             model=None) -> list[Path]:
    """The paper's model at its comparison force (0.35 N, three fingers of [16] at 25 kHz, which are
    not bundled); other points or curves are drawn labelled as what they are."""
    amplitude = np.linspace(0.0, 10.0, 201)
    fig, axis = figure(figsize=(6.0, 4.6))
    for contact, style in (("hertz", "-"), ("uniform", "--")):
        axis.plot(amplitude, relative_friction(amplitude, force_n, params.with_(contact=contact)), style,
                  color="k", label=f"paper model, {contact} pressure, {force_n:g} N")
    if model is not None and model.name not in ("paper",):
        axis.plot(amplitude, model.relative_friction(np.minimum(amplitude, model.max_amplitude_um_pp), force_n),
                  "-.", color="tab:purple", label=f"{model.name} model, {force_n:g} N")
    if data_path is not None:
        data = read_measurements(data_path)
        forces = data.force_n if data.force_n is not None else np.full(len(data), np.nan)
        bundled = Path(data.source).name == BUNDLED_FIT_NAME
        for force in np.unique(forces):
            pick = forces == force if np.isfinite(force) else np.isnan(forces)
            what = ("Monnoyer et al. 2018 fit, 34.6 kHz, force not stated (a curve, not data)"
                    if bundled else f"points of {Path(data.source).name}")
            where = f", {force:g} N" if np.isfinite(force) and not bundled else ""
            axis.plot(data.amplitude_um_pp[pick], data.relative_friction[pick], "s" if bundled else "o",
                      mfc="none", label=what + where)
    axis.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction µ/µ0", ylim=(0, 1.05), xlim=(0, 10),
             title=f"Fig. 9: the paper's model at {force_n:g} N\n(the paper's measured fingers [16] are not bundled)")
    axis.legend(loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=1)
    return save(fig, path)


def write_paper_figures(directory: Path, data_path: Path | None, params: FingerParams = FingerParams(),
                        force_n: float | None = None, model=None) -> list[Path]:
    """Write figs. 2–9 into ``directory`` as PNG (300 dpi) and PDF; returns the PNG paths.

    ``force_n``: draw every figure at this force; None draws each at the paper's own force."""
    directory.mkdir(parents=True, exist_ok=True)

    def at(default: float) -> float:
        return default if force_n is None else force_n
    written = [
        figure_2(directory / "fig2-lateral-stick-slip.png", params, at(0.5)),
        figure_3(directory / "fig3-glide-threshold.png", params, force_n),
        figure_4(directory / "fig4-detach-amplitude.png", params, at(0.15)),
        _cycle_figure(directory / "fig5-reaction-force.png", params, friction=False, force_n=at(0.5)),
        _cycle_figure(directory / "fig6-friction-force.png", params, friction=True, force_n=at(0.5)),
        figure_7(directory / "fig7-friction-coefficient.png", params, force_n),
        figure_8(directory / "fig8-relative-friction.png", params, force_n),
        figure_9(directory / "fig9-model-comparison.png", params, data_path, at(0.35), model),
    ]
    return [paths[0] for paths in written]
