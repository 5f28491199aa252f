"""Measuring a plate: its resonance fitted and tracked (`resonance`), and the sweep that measures it
(`sweep`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "FitError": "resonance",
    "fit_resonance": "resonance",
    "ResonanceTracker": "resonance",
    "sweep": "sweep",
    "measured_profile": "sweep",
}
__all__ = ["FitError", "fit_resonance", "ResonanceTracker", "sweep", "measured_profile"]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.characterisation.resonance import FitError, ResonanceTracker, fit_resonance
    from ultraglide.devices.characterisation.sweep import measured_profile, sweep
