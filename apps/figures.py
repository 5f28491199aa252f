"""The paper's figures 2–9, drawn from our implementation of its model."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from ultraglide.apps.atomic import atomic_path  # noqa: E402
from ultraglide.render.calibration import load_model  # noqa: E402
from ultraglide.render.fingerprint import (  # noqa: E402
    FingerParams,
    detach_amplitude_um_pp,
    friction_coefficient,
    glide_threshold_um_pp,
)
from ultraglide.render.lateral import (  # noqa: E402
    simulate_lateral,
    simulated_glide_threshold_um_pp,
    steady_glide_threshold_um_pp,
)
from ultraglide.render.measurements import read_measurements  # noqa: E402
from ultraglide.render.normal_contact import cycle_reaction_n, relative_friction  # noqa: E402

FIGURE_AMPLITUDES_UM_PP = (0.1, 0.5, 1.0, 2.0, 4.0, 8.0)
FORCES_N = np.linspace(0.05, 1.0, 96)


def _save(figure, path: Path) -> Path:
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=120, format="png")
    plt.close(figure)
    return path


def figure_2(path: Path, params: FingerParams) -> Path:
    """Lateral stick–slip over a cycle: mu_s = 1, mu_d = 0.7, 0.5 N, 20 kHz, 5 µm p-p."""
    sim = simulate_lateral(5.0, 0.5, 20e3, cycles=3, steps_per_cycle=2000, params=params)
    last = slice(-2001, None)
    t_us = (sim.time_s[last] - sim.time_s[last][0]) * 1e6
    figure, axis = plt.subplots(figsize=(8, 4.5))
    position, velocity = sim.plate_position_m[last], sim.plate_velocity_m_per_s[last]
    axis.plot(t_us, position / np.abs(position).max(), label="plate position x (normalised)")
    axis.plot(t_us, velocity / np.abs(velocity).max(), label="plate velocity V (normalised)")
    axis.plot(t_us, sim.lateral_force_n[last] / 0.5, label="lateral force F_l / F_n")
    sliding = sim.sliding[last]
    axis.fill_between(t_us, -1.1, 1.1, where=~sliding, color="0.85", label="sticking")
    axis.fill_between(t_us, -1.1, 1.1, where=sliding, color="tab:green", alpha=0.15, hatch="xx", label="sliding")
    axis.set(xlabel="time (µs)", ylabel="normalised value", ylim=(-1.1, 1.1),
             title="Fig. 2: steady lateral stick–slip, 20 kHz, 5 µm p-p, 0.5 N, µs = 1, µd = 0.7")
    axis.legend(loc="lower left", fontsize=8)
    return _save(figure, path)


def figure_3(path: Path, params: FingerParams) -> Path:
    """Glide threshold against normal force, closed form (5) and simulation."""
    figure, axis = plt.subplots(figsize=(7, 4.5))
    axis.plot(FORCES_N, glide_threshold_um_pp(FORCES_N, params), label="onset, eq. (5)")
    axis.plot(FORCES_N, steady_glide_threshold_um_pp(FORCES_N, params), "--", label="steady slip, (µs + µd) F / k_t")
    forces = np.array([0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0])
    simulated = [simulated_glide_threshold_um_pp(f, params, tolerance_um=0.01) for f in forces]
    axis.plot(forces, simulated, "o", label="time-domain simulation")
    axis.plot([0.4], [4.0], "k*", markersize=12, label="psychophysics: slip felt at 4 µm, ~0.4 N")
    axis.set(xlabel="normal force (N)", ylabel="glide threshold (µm p-p)",
             title="Fig. 3a: glide threshold of lateral vibration")
    axis.legend(fontsize=8)
    axis.grid(alpha=0.3)
    return _save(figure, path)


def figure_4(path: Path, params: FingerParams) -> Path:
    """Detachment amplitude against normal force (6), with the paper's worked example."""
    figure, axis = plt.subplots(figsize=(7, 4.5))
    axis.plot(FORCES_N, detach_amplitude_um_pp(FORCES_N, params), label="W_c = F_n / k_n, eq. (6)")
    example = float(detach_amplitude_um_pp(0.15, params))
    axis.plot([0.15], [example], "o", label=f"0.15 N needs {example:.2f} µm")
    axis.set(xlabel="normal force (N)", ylabel="detachment amplitude (µm p-p)",
             title="Fig. 4: detach condition of the fingerprint ridges")
    axis.legend()
    axis.grid(alpha=0.3)
    return _save(figure, path)


def _cycle_figure(path: Path, params: FingerParams, friction: bool) -> Path:
    phase = np.linspace(0.0, 2.0 * np.pi, 721)
    time_us = phase / (2.0 * np.pi) * 50.0  # 20 kHz
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for axis, contact in zip(axes, ("uniform", "hertz"), strict=True):
        p = params.with_(contact=contact)
        colours = plt.cm.coolwarm(np.linspace(0.0, 1.0, len(FIGURE_AMPLITUDES_UM_PP)))
        for amplitude, colour in zip(FIGURE_AMPLITUDES_UM_PP, colours, strict=True):
            reaction = cycle_reaction_n(amplitude, 0.5, phase, p)
            value = p.dynamic_friction * reaction if friction else reaction
            axis.plot(time_us, value, color=colour, label=f"{amplitude:g} µm")
        axis.set(xlabel="time (µs)", title=f"{contact} pressure profile")
        axis.grid(alpha=0.3)
    axes[0].set_ylabel("friction force µd F_reac (N)" if friction else "plate reaction force (N)")
    axes[1].legend(title="amplitude p-p", fontsize=8)
    number = 6 if friction else 5
    what = "frictional force" if friction else "plate reaction force"
    figure.suptitle(f"Fig. {number}: {what} over a 20 kHz cycle at 0.5 N")
    return _save(figure, path)


def figure_7(path: Path, params: FingerParams) -> Path:
    """The non-Coulombic coefficient of friction against normal force."""
    forces = np.linspace(0.02, 2.0, 200)
    figure, axis = plt.subplots(figsize=(7, 4.5))
    axis.plot(forces, friction_coefficient(forces, params),
              label=f"µ = {params.friction_coefficient_at_1n:g} F^({params.friction_exponent - 1:.2f})")
    axis.axhline(params.dynamic_friction, color="0.5", ls="--", label="Coulomb (constant µ)")
    axis.set(xlabel="normal force (N)", ylabel="coefficient of friction",
             title="Fig. 7: non-Coulombic friction of a finger pad on glass", ylim=(0, None))
    axis.legend()
    axis.grid(alpha=0.3)
    return _save(figure, path)


def figure_8(path: Path, params: FingerParams) -> Path:
    """Relative coefficient of friction against vibration amplitude."""
    amplitude = np.linspace(0.0, 10.0, 201)
    figure, axis = plt.subplots(figsize=(7, 4.5))
    for contact, style in (("hertz", "-"), ("uniform", "--")):
        for force in (0.2, 0.5, 1.0):
            ratio = relative_friction(amplitude, force, params.with_(contact=contact))
            axis.plot(amplitude, ratio, style, label=f"{contact}, {force:g} N")
    axis.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction µ/µ0",
             title="Fig. 8: friction reduction from non-Coulombic friction", ylim=(0, 1.05))
    axis.legend(fontsize=8, ncol=2)
    axis.grid(alpha=0.3)
    return _save(figure, path)


def figure_9(path: Path, params: FingerParams, model_spec: str, data_path: Path) -> Path:
    """Model against measured points (the paper compares with three fingers at 0.35 N)."""
    data = read_measurements(data_path)
    forces = data.force_n if data.force_n is not None else np.full(len(data), 0.5)
    amplitude = np.linspace(0.0, max(10.0, float(data.amplitude_um_pp.max())), 201)
    figure, axis = plt.subplots(figsize=(7, 4.5))
    for force in np.unique(forces):
        pick = forces == force
        axis.plot(data.amplitude_um_pp[pick], data.relative_friction[pick], "o", label=f"measured, {force:g} N")
        axis.plot(amplitude, relative_friction(amplitude, force, params), label=f"paper model, {force:g} N")
        if model_spec not in ("paper",):
            model = load_model(model_spec)
            axis.plot(amplitude, model.relative_friction(amplitude, force), "--",
                      label=f"{model.name}, {force:g} N")
    axis.set(xlabel="vibration amplitude (µm p-p)", ylabel="relative friction µ/µ0",
             title=f"Fig. 9: model against {Path(data.source).name}", ylim=(0, 1.05))
    axis.legend(fontsize=8)
    axis.grid(alpha=0.3)
    return _save(figure, path)


def write_paper_figures(directory: Path, model_spec: str, data_path: Path,
                        params: FingerParams = FingerParams()) -> list[Path]:
    """Write fig2.png … fig9.png into ``directory``; returns their paths."""
    directory.mkdir(parents=True, exist_ok=True)
    return [
        figure_2(directory / "fig2-lateral-stick-slip.png", params),
        figure_3(directory / "fig3-glide-threshold.png", params),
        figure_4(directory / "fig4-detach-amplitude.png", params),
        _cycle_figure(directory / "fig5-reaction-force.png", params, friction=False),
        _cycle_figure(directory / "fig6-friction-force.png", params, friction=True),
        figure_7(directory / "fig7-friction-coefficient.png", params),
        figure_8(directory / "fig8-relative-friction.png", params),
        figure_9(directory / "fig9-measured-comparison.png", params, model_spec, data_path),
    ]
