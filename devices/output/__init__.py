"""The output stage, one path from a drive envelope to any device: what a device pulls from (`source`),
the drive limiter (`limiter`), the carrier (`carrier`), the stage that joins them (`stage`) and their compiled
inner loops (`kernels`)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module of this room that defines it; imported on first use (PEP 562)
_EXPORTS = {
    "BlockSource": "source",
    "Device": "source",
    "DriveLimiter": "limiter",
    "Carrier": "carrier",
    "OutputStage": "stage",
    "output_stage": "stage",
}
__all__ = ["BlockSource", "Device", "DriveLimiter", "Carrier", "OutputStage", "output_stage"]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


if TYPE_CHECKING:
    from ultraglide.devices.output.carrier import Carrier
    from ultraglide.devices.output.limiter import DriveLimiter
    from ultraglide.devices.output.source import BlockSource, Device
    from ultraglide.devices.output.stage import OutputStage, output_stage
