"""What a device pulls from: it never sees the renderer, only this protocol (see DESIGN.md)."""

from __future__ import annotations

from typing import Protocol

import numpy as np


class BlockSource(Protocol):
    """A stream of blocks. Audio devices get float32 samples in [-1, 1] (1 = full-scale drive);
    control devices get amplitude setpoints in µm peak-to-peak."""

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        """The next ``n`` values; ``now_s`` is when (perf_counter s) the first reaches the plate."""

    def request_stop(self) -> None:
        """Start ramping down to rest."""

    @property
    def finished(self) -> bool:
        """True once the ramp down has reached rest."""
