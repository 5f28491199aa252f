"""The screen a window opens on: whether there is one, and its scale when its size is not given."""

from __future__ import annotations

import os

DEFAULT_MM_PER_PX = 25.4 / 96  # when the screen's size is not given: a 96 dpi screen


def display_available() -> bool:
    """Whether SDL has a display to open a window on (an X or Wayland display, or a video driver named)."""
    driver = os.environ.get("SDL_VIDEODRIVER", "")
    return bool(driver or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
