"""Measuring a plate: its resonance fitted and tracked (`resonance`), and the sweep that measures it
(`sweep`)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module of this room that defines it; imported on first use (PEP 562)
_EXPORTS = {
    "FitError": "resonance",
    "fit_resonance": "resonance",
    "ResonanceTracker": "resonance",
    "sweep": "sweep",
    "measured_profile": "sweep",
}
__all__ = ["FitError", "fit_resonance", "ResonanceTracker", "sweep", "measured_profile"]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


if TYPE_CHECKING:
    from ultraglide.devices.characterisation.resonance import FitError, ResonanceTracker, fit_resonance
    from ultraglide.devices.characterisation.sweep import measured_profile, sweep
