"""What ``export`` and ``play`` say about safety: how much the limiter acted, and unreachable friction."""

from __future__ import annotations

import numpy as np
from ultraglide.devices.output.stage import OutputStage
from ultraglide.render.renderer import Renderer


def limiter_fields(stage: OutputStage) -> dict:
    """``limited_fraction`` (of the time) and ``worst_excess_um_pp`` (drive asked above what was let through)."""
    limiter = stage.limiter
    return {"limited_fraction": round(limiter.limited_fraction, 6),
            "worst_excess_um_pp": round(limiter.worst_excess_um_pp, 6)}


def clipped_fraction(renderer: Renderer) -> float:
    """The fraction of control samples whose target friction was below what the model reaches."""
    counters = renderer.counters
    return counters.clipped_samples / counters.control_samples if counters.control_samples else 0.0


def force_words(trajectory, renderer: Renderer) -> str:
    """The finger's force in words: one value, or the logged range."""
    force = getattr(trajectory, "force_range_n", None)  # a recorded log: known without reading it again
    if force is None and not hasattr(trajectory, "force_range_n"):
        force = getattr(trajectory, "force_n", None)
    if force is None:
        return f"{renderer.default_force_n:g} N"
    values = np.atleast_1d(np.asarray(force, dtype=float))
    low, high = float(values.min()), float(values.max())
    return f"{low:g} N" if np.isclose(low, high) else f"{low:g}-{high:g} N"


def share_words(fraction: float) -> str:
    """A share of the time in words, never a "0.0 %" for something that happened (or a "100.0 %" for
    something that did not always happen)."""
    if 0.0 < fraction < 0.0005:
        return "under 0.1 %"
    if 0.9995 <= fraction < 1.0:
        return "over 99.9 %"
    return f"{100 * fraction:.1f} %"


def clipping_warning(renderer: Renderer, model_name: str, trajectory) -> str | None:
    """One line when the texture asked for less friction than the model reaches within the plate's limit."""
    fraction = clipped_fraction(renderer)
    if not renderer.counters.clipped_samples:
        return None
    return (f"warning: {share_words(fraction)} of the time the texture asked for less friction than model "
            f"{model_name} reaches at {force_words(trajectory, renderer)} within "
            f"{renderer.profile.max_amplitude_um_pp:g} µm p-p; held at the limit")
