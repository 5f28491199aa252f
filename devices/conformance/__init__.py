"""``plate check``: a plate driver exercised against docs/protocol.md rule by rule: the probe that speaks the
protocol frame by frame (`probe`), the rules of the link, the device and the stream (`link`, `device`,
`stream`), and the check that runs them (`check`)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# public name -> the module of this room that defines it; imported on first use (PEP 562)
_EXPORTS = {
    "check_device": "check",
    "CheckReport": "probe",
}
__all__ = ["check_device", "CheckReport"]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


if TYPE_CHECKING:
    from ultraglide.devices.conformance.check import check_device
    from ultraglide.devices.conformance.probe import CheckReport
