"""``plate check``: a plate driver exercised against docs/protocol.md rule by rule: the probe that speaks the
protocol frame by frame (`probe`), the rules of the link, the device and the stream (`link`, `device`,
`stream`), and the check that runs them (`check`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "check_device": "check",
    "CheckReport": "probe",
}
__all__ = ["check_device", "CheckReport"]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.conformance.check import check_device
    from ultraglide.devices.conformance.probe import CheckReport
