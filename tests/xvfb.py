"""A virtual screen for the tests that open windows: Xvfb on a free display."""

from __future__ import annotations

import os
import subprocess

ATTEMPTS = 5  # two test workers starting Xvfb at once may pick the same display; the loser exits


def start_xvfb(width: int = 1280, height: int = 800) -> tuple[subprocess.Popen, str]:
    """Xvfb on a display it chose, once it accepts clients: the process and ``DISPLAY`` (``":N"``)."""
    for _ in range(ATTEMPTS):
        read_fd, write_fd = os.pipe()
        # -noreset: else Xvfb starts over whenever its last client leaves, and a client connecting meanwhile is
        # refused (5 of 300 xdotool calls in a row beside two CPU hogs; none of 1500 with it)
        xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(write_fd), "-screen", "0", f"{width}x{height}x24",
                                 "-nolisten", "tcp", "-noreset"], pass_fds=(write_fd,), stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        os.close(write_fd)
        with os.fdopen(read_fd) as numbers:  # Xvfb writes its display number once it accepts clients
            number = numbers.readline().strip()  # or nothing, when it exits first
        if number:
            return xvfb, f":{number}"
        xvfb.kill()
        xvfb.wait(timeout=30)
    raise RuntimeError(f"Xvfb did not start in {ATTEMPTS} attempts")
