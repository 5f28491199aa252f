"""The settled reduction against amplitude at three sliding speeds, through a model's speed law (ours: the law of
``render/physics/speed_law.py`` is an assumption, and the figure says so)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.apps.figures.style import figure, save, width_of

SPEEDS_MM_S = (22.0, 100.0, 200.0)
CURVE_END_UM = 10.0


def speed_figure(path: Path, model, force_n: float, limit_um_pp: float, width=None) -> list[Path]:
    """The friction ratio against the plate's amplitude (µm p-p) at 22, 100 and 200 mm/s for ``model`` (one with a
    speed law: :class:`~ultraglide.render.physics.speed_law.SpeedLawModel`, or a dynamic model around one) at
    ``force_n`` (N), with the limit ``limit_um_pp`` marked and the floor reachable under it at each speed."""
    law = model.speed_law
    amplitude = np.linspace(0.0, CURVE_END_UM, 201)
    fig, axis = figure(1, 1, figsize=(width_of(width), 2.9))
    colours = ("0.3", "tab:blue", "tab:purple")
    for speed, colour in zip(SPEEDS_MM_S, colours, strict=True):
        scale = law.one_scale(speed)
        ratio = model.relative_friction(amplitude / scale, force_n)
        floor = float(model.relative_friction(limit_um_pp / scale, force_n))
        axis.plot(amplitude, ratio, color=colour, label=f"{speed:g} mm/s (floor {floor:.2f})")
        axis.plot([limit_um_pp], [floor], marker="o", color=colour, linestyle="none")
    axis.axvline(limit_um_pp, color="0.5", linestyle=":", label=f"limit {limit_um_pp:g} µm p-p")
    axis.set(xlabel="amplitude (µm p-p)", ylabel="friction ratio", ylim=(0, 1.05), xlim=(0, CURVE_END_UM),
             title=f"Reduction vs speed, s = {law.exponent:g} (assumed, ours)")
    fig.legend(*axis.get_legend_handles_labels(), loc="outside lower center", ncol=2)
    return save(fig, path)
