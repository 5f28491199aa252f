"""A session's figures at print quality: the track of levels over trials, and the psychometric fit.

Each is written as a 300 dpi PNG and a PDF (``apps.figures.style``): ``track.png|pdf``,
``psychometric.png|pdf``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.apps.figures import SESSION_FIGURES
from ultraglide.apps.figures import style as figure_style

from ultraglide.experiment import psychometric as pf

CORRECT, WRONG, FIT = "#1b6ca8", "#c8553d", "#333333"


def _level_label(design) -> str:
    return {"contrast": "friction contrast, 1 − ratio", "wavelength": "wavelength difference Δλ (mm)",
            "amplitude": "vibration amplitude (µm p-p)"}[design.parameter]


def draw_figures(directory: Path, config, design, rows: list[dict], result: dict, width=None) -> list[Path]:
    """The track and the psychometric figure, laid out for one IEEE column (``width`` "page": two)."""
    levels = np.array([float(r["level"]) for r in rows])
    correct = np.array([int(r["correct"]) for r in rows], dtype=bool)
    from ultraglide.apps.experiment.session import outcome

    positive = np.array([outcome(config, r) for r in rows])
    width_in = figure_style.width_of(width)
    track, psychometric = (directory / f"{stem}.png" for stem in SESSION_FIGURES)
    written = _track(track, config, design, levels, correct, rows, result, width_in)
    written += _psychometric(psychometric, config, design, levels, positive, result, width_in)
    return written


def _threshold_band(ax, result: dict, horizontal: bool) -> None:
    if result.get("threshold") is None:
        return
    t, (lo, hi) = result["threshold"], result["ci"]
    label = f"threshold {t:.3g} (95 % CI {lo:.3g}–{hi:.3g})"
    if horizontal:
        ax.axhspan(lo, hi, color="0.85", zorder=0)
        ax.axhline(t, color=FIT, lw=1.0, ls="--", label=label)
    else:
        ax.axvspan(lo, hi, color="0.85", zorder=0)
        ax.axvline(t, color=FIT, lw=1.0, ls="--", label=label)


def _track(path: Path, config, design, levels, correct, rows, result, width_in: float) -> list[Path]:
    fig, ax = figure_style.figure(figsize=(width_in, min(0.62 * width_in, 3.2) + 1.3))
    trials = np.arange(1, len(levels) + 1)
    ax.plot(trials, levels, color="0.6", lw=0.8, zorder=1)
    ax.scatter(trials[correct], levels[correct], color=CORRECT, s=14, zorder=3, label="correct")
    ax.scatter(trials[~correct], levels[~correct], facecolor="white", edgecolor=WRONG, s=14, zorder=3,
               label="incorrect")
    reversal = np.array([r.get("reversal") in (1, "1") for r in rows])
    if reversal.any():
        ax.scatter(trials[reversal], levels[reversal], facecolor="none", edgecolor=FIT, s=60, lw=0.8, zorder=4,
                   label="reversal")
    breaks = [int(r["trial"]) for r in rows if str(r.get("break_before")) == "1"]
    for index, trial in enumerate(breaks):
        ax.axvline(trial - 0.5, color="0.5", lw=0.6, ls=":", label="break" if index == 0 else None)
    _threshold_band(ax, result, horizontal=True)
    if config.method != "constant" and levels.min() > 0:
        from matplotlib.ticker import FuncFormatter, NullFormatter

        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))  # plain numbers, no mathtext
        ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("trial")
    ax.set_ylabel(_level_label(design))
    ax.set_title(f"{config.condition}: {config.participant}, session {config.session}")
    figure_style.legend_below(ax, ncol=1 if width_in < figure_style.PAGE_IN else 3)
    return figure_style.save(fig, path)


def _psychometric(path: Path, config, design, levels, positive, result, width_in: float) -> list[Path]:
    fig, ax = figure_style.figure(figsize=(width_in, min(0.62 * width_in, 3.2) + 1.0))
    x, n, k = pf.aggregate(levels, positive)
    ax.scatter(x, k / n, s=12 + 60 * n / n.max(), color=CORRECT, alpha=0.8, zorder=3,
               label="observed (area ∝ trials)")
    if len(x) <= 8:  # few levels (constant stimuli): say how many answers each point holds
        for level, count, hits in zip(x, n, k, strict=True):
            ax.annotate(f"{int(hits)}/{int(count)}", (level, hits / count), textcoords="offset points",
                        xytext=(6, -10), fontsize=8)
    fit = result.get("fit")
    if fit:
        top = max(x.max(), result["ci"][1] if result.get("ci") else 0) * 1.15
        grid = np.linspace(0, top, 400)
        curve = pf.probability(fit["function"], grid, fit["threshold"], fit["slope"], fit["guess"], fit["lapse"])
        ax.plot(grid, curve, color=FIT, label=f"ML {fit['function']} fit, α = {fit['threshold']:.3g}")
    _threshold_band(ax, result, horizontal=False)
    if config.intervals > 1:
        ax.axhline(1.0 / config.intervals, color="0.5", lw=0.6, ls=":", label="chance")
        ax.set_ylabel("proportion correct")
    else:
        ax.set_ylabel("proportion “yes”")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel(_level_label(design))
    ax.set_title(f"{config.condition}, {len(levels)} trials")
    figure_style.legend_below(ax, ncol=1 if width_in < figure_style.PAGE_IN else 3)
    return figure_style.save(fig, path)
