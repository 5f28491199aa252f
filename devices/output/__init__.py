"""The output stage, one path from a drive envelope to any device: what a device pulls from (`source`),
the drive limiter (`limiter`), the carrier (`carrier`), the stage that joins them (`stage`) and their compiled
inner loops (`kernels`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "BlockSource": "source",
    "Device": "source",
    "DriveLimiter": "limiter",
    "Carrier": "carrier",
    "OutputStage": "stage",
    "output_stage": "stage",
}
__all__ = ["BlockSource", "Device", "DriveLimiter", "Carrier", "OutputStage", "output_stage"]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.output.carrier import Carrier
    from ultraglide.devices.output.limiter import DriveLimiter
    from ultraglide.devices.output.source import BlockSource, Device
    from ultraglide.devices.output.stage import OutputStage, output_stage
