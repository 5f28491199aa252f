"""The serial plate driver (docs/protocol.md) and its parts: the link under it (`link`), the handshake
(`handshake`), what comes back (`telemetry`), the writer thread (`writer`), and what a run came to
(`report`, `run_report`); `plate` composes them into :class:`SerialPlate`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "SerialPlate": "plate",
    "open_port": "link",
    "RunReport": "run_report",
}
__all__ = ["SerialPlate", "open_port", "RunReport"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.serial.link import open_port
    from ultraglide.devices.serial.plate import SerialPlate
    from ultraglide.devices.serial.run_report import RunReport
