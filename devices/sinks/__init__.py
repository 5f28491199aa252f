"""Outputs that are not plate drivers: the audio DAC (`audio`), the paced WAV recorder and null sink
(`paced`), and the listing of what outputs a machine has (`listing`)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module of this room that defines it; imported on first use (PEP 562)
_EXPORTS = {
    "AudioPlate": "audio",
    "WavRecorder": "paced",
    "PacedSink": "paced",
    "list_devices": "listing",
}
__all__ = ["AudioPlate", "WavRecorder", "PacedSink", "list_devices"]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


if TYPE_CHECKING:
    from ultraglide.devices.sinks.audio import AudioPlate
    from ultraglide.devices.sinks.listing import list_devices
    from ultraglide.devices.sinks.paced import PacedSink, WavRecorder
