"""Figures of friction in time: asked against felt (a step, a grating at three speeds), and how much of a grating's
contrast the finger feels against its spatial frequency and speed (ours: the dynamics of
``render/physics/dynamics.py`` and the planner of ``render/planning.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.ticker import NullLocator
from ultraglide.apps.figures.style import PAGE_IN, figure, save, width_of
from ultraglide.render.physics.dynamics import FrictionDynamics
from ultraglide.render.planning import contrast_transfer, grating_felt, step_felt

SPEEDS_MM_S = (50.0, 100.0, 200.0)
RATE_HZ = 12000.0


def friction_in_time(path: Path, dynamics: FrictionDynamics, floor: float, width=None) -> list[Path]:
    """Four panels: a step 1 → 0.3 → 1 at 100 mm/s, and a 1 mm sinusoidal grating (1 down to ``floor``) at 50, 100
    and 200 mm/s; each the friction asked, felt with the instantaneous renderer, felt with the planned one."""
    width_in = width_of(width)
    page = width_in >= PAGE_IN
    rows, columns = (1, 4) if page else (2, 2)
    fig, axes = figure(rows, columns, figsize=(width_in, (2.0 if page else 3.6) + 0.5), sharey=True)
    axes = np.asarray(axes).reshape(-1)
    target, instant, planned = step_felt(dynamics, 100.0, floor)
    panels = [("step\n100 mm/s", target, instant, planned)]
    for speed in SPEEDS_MM_S:
        panels.append((f"1 mm grating\n{speed:g} mm/s", *grating_felt(dynamics, 1.0, speed, floor, RATE_HZ, 0.3)))
    for axis, (title, target, instant, planned) in zip(axes, panels, strict=True):
        time_ms = np.arange(len(target)) / RATE_HZ * 1e3
        shown = slice(0, len(target)) if title.startswith("step") else slice(int(0.2 * RATE_HZ), int(0.25 * RATE_HZ))
        axis.plot(time_ms[shown], target[shown], color="0.4", linestyle=":", label="asked (the texture)")
        axis.plot(time_ms[shown], instant[shown], color="tab:red", label="felt, instantaneous renderer")
        axis.plot(time_ms[shown], planned[shown], color="tab:blue", label="felt, planned renderer")
        axis.set(title=title, xlabel="time (ms)", ylim=(0, 1.05))
    for axis in axes[::columns]:
        axis.set_ylabel("friction ratio")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=3 if page else 1)
    fig.suptitle("Friction in time (ours)")
    return save(fig, path)


def contrast_figure(path: Path, dynamics: FrictionDynamics, floor: float, width=None) -> list[Path]:
    """Felt over asked contrast of a sinusoidal grating (1 down to ``floor``) against its spatial frequency
    (cycles/mm) at 50, 100 and 200 mm/s, instantaneous renderer (dashed) and planned (solid), and the RMS error
    of each below."""
    width_in = width_of(width)
    fig, (top, bottom) = figure(2, 1, figsize=(width_in, 5.6), sharex=True)
    frequencies = np.geomspace(0.05, 4.0, 14)  # cycles/mm: periods of 20 mm down to 0.25 mm
    colours = ("tab:green", "tab:blue", "tab:purple")
    for speed, colour in zip(SPEEDS_MM_S, colours, strict=True):
        kept = [contrast_transfer(dynamics, 1.0 / f, speed, floor, RATE_HZ) for f in frequencies]
        top.plot(frequencies, [k.planned for k in kept], color=colour, label=f"{speed:g} mm/s, planned")
        top.plot(frequencies, [k.instantaneous for k in kept], color=colour, linestyle="--",
                 label=f"{speed:g} mm/s, instantaneous")
        bottom.plot(frequencies, [k.planned_rms for k in kept], color=colour)
        bottom.plot(frequencies, [k.instantaneous_rms for k in kept], color=colour, linestyle="--")
    top.set(xscale="log", ylabel="felt / asked contrast", ylim=(0, 1.05),
            title="Grating contrast the finger feels (ours)")
    bottom.set(xscale="log", xlabel="spatial frequency (cycles/mm)", ylabel="RMS error, felt - asked", ylim=(0, None))
    ticks = (0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 4.0)  # plain numbers: a log axis's 10^-1 prints its exponent below 8 pt
    bottom.set_xticks(ticks, [f"{t:g}" for t in ticks])
    bottom.xaxis.set_minor_locator(NullLocator())
    handles, labels = top.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=1)
    return save(fig, path)
