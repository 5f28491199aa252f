"""Outputs that are not plate drivers: the audio DAC (`audio`), the paced WAV recorder and null sink
(`paced`), and the listing of what outputs a machine has (`listing`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "AudioPlate": "audio",
    "WavRecorder": "paced",
    "PacedSink": "paced",
    "list_devices": "listing",
}
__all__ = ["AudioPlate", "WavRecorder", "PacedSink", "list_devices"]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.sinks.audio import AudioPlate
    from ultraglide.devices.sinks.listing import list_devices
    from ultraglide.devices.sinks.paced import PacedSink, WavRecorder
