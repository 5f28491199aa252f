"""Touch panels read by ultraglide itself, rather than through a window's toolkit: :mod:`.evdev` reads a Linux
input device (``/dev/input/eventN``, the kernel's multi-touch protocol B or a single-touch panel) into touch
frames in the panel's own units. Mapping them onto the display is the rig's :class:`devices.rig.TouchPanel`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module of this room that defines it; imported on first use (PEP 562, ultraglide.lazy)
_EXPORTS = {
    "PanelReader": "evdev",
    "EventParser": "evdev",
    "PanelRanges": "evdev",
    "AxisRange": "evdev",
    "TouchPanelError": "evdev",
}
__all__ = ["PanelReader", "EventParser", "PanelRanges", "AxisRange", "TouchPanelError"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.devices.touch.evdev import AxisRange, EventParser, PanelRanges, PanelReader, TouchPanelError
