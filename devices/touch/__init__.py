"""Touch panels read by ultraglide itself, rather than through a window's toolkit: :mod:`.evdev` reads a Linux
input device (``/dev/input/eventN``, the kernel's multi-touch protocol B or a single-touch panel) into touch
frames in the panel's own units. Mapping them onto the display is the rig's :class:`devices.rig.TouchPanel`."""
