"""The simulated plate: the firmware core in the loop driving a simulated resonator (`plate`), served on a
pseudo-terminal (`pty_plate`) at a link path (`links`), with a simulated finger (`finger`, `finger_log`) and the
force sensors under the plate (`force_sensors`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "PlateSimulator": "plate",
    "PtyPlate": "pty_plate",
    "SimulatedFinger": "finger",
    "FingerParams": "finger",
}
__all__ = ["PlateSimulator", "PtyPlate", "SimulatedFinger", "FingerParams"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.sim.finger import FingerParams, SimulatedFinger
    from ultraglide.devices.sim.plate import PlateSimulator
    from ultraglide.devices.sim.pty_plate import PtyPlate
