"""Sleep until the window has an event or a timeout passes, without polling.

pygame's ``event.wait(timeout)`` polls: it pumps SDL's events and sleeps 1 ms, over and over (about
800 wake-ups a second, 2–3 % of a core for a window where nothing happens). SDL itself can block on
the display's connection (``SDL_WaitEventTimeout``, on X11 a ``poll`` of the X socket); called with no
event to fill, it only looks, so the event stays in the queue for pygame to take. This calls it in the
SDL library pygame loaded, and falls back to pygame's own wait where that library cannot be found.
"""

from __future__ import annotations

import ctypes
from pathlib import Path


def _loaded_sdl() -> ctypes.CDLL | None:
    """The SDL2 library already mapped into this process (pygame's), or None."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return None
    for line in maps.splitlines():
        path = line.split()[-1] if line.split() else ""
        if "/libSDL2-2" in path or path.endswith("/libSDL2.so") or "/libSDL2-2.0.so" in path:
            try:
                library = ctypes.CDLL(path)
                library.SDL_WaitEventTimeout.argtypes = (ctypes.c_void_p, ctypes.c_int)
                library.SDL_WaitEventTimeout.restype = ctypes.c_int
                return library
            except (OSError, AttributeError):
                return None
    return None


class EventWaiter:
    """``wait(timeout_s)``: returns once an event is queued (left there) or the timeout has passed."""

    def __init__(self, pygame):
        self.pg = pygame
        self._sdl = _loaded_sdl()

    @property
    def blocking(self) -> bool:
        """True when the wait sleeps in SDL (no polling); False on pygame's polling fallback."""
        return self._sdl is not None

    def wait(self, timeout_s: float):
        """The first event if it came within ``timeout_s`` (taken from the queue), else a NOEVENT."""
        milliseconds = max(1, round(timeout_s * 1000))
        if self._sdl is None:
            return self.pg.event.wait(milliseconds)
        self._sdl.SDL_WaitEventTimeout(None, milliseconds)
        return self.pg.event.poll()
