"""The simulated plate: the firmware core in the loop driving a simulated resonator (`plate`), served on a
pseudo-terminal (`pty_plate`) at a link path (`links`), with a simulated finger (`finger`, `finger_log`) and the
force sensors under the plate (`force_sensors`)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module of this room that defines it; imported on first use (PEP 562)
_EXPORTS = {
    "PlateSimulator": "plate",
    "PtyPlate": "pty_plate",
    "SimulatedFinger": "finger",
    "FingerParams": "finger",
}
__all__ = ["PlateSimulator", "PtyPlate", "SimulatedFinger", "FingerParams"]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


if TYPE_CHECKING:
    from ultraglide.devices.sim.finger import FingerParams, SimulatedFinger
    from ultraglide.devices.sim.plate import PlateSimulator
    from ultraglide.devices.sim.pty_plate import PtyPlate
