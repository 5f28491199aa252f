"""Measured friction points from CSV: ``amplitude_um_pp,relative_friction[,force_n][,participant]``.

Lines starting with ``#`` are comments. Amplitudes are peak-to-peak; convert zero-to-peak data
(as many published fits are) by doubling before saving. ``participant`` is a number naming whose
finger each point is (for cross-validation across people).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from ultraglide.render.csv_table import read_numeric_csv
from ultraglide.render.errors import ModelError

REQUIRED_COLUMNS = ("amplitude_um_pp", "relative_friction")


@dataclass(frozen=True)
class Measurements:
    """Measured relative friction against amplitude (µm p-p), with the normal force (N) if known."""

    amplitude_um_pp: np.ndarray
    relative_friction: np.ndarray
    force_n: np.ndarray | None
    source: str
    participant: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.amplitude_um_pp)

    def subset(self, pick: np.ndarray) -> Measurements:
        """The points where ``pick`` (a boolean mask or indices) selects."""
        def take(column):
            return None if column is None else column[pick]
        return Measurements(self.amplitude_um_pp[pick], self.relative_friction[pick], take(self.force_n),
                            self.source, take(self.participant))


def read_measurements(path: str | Path) -> Measurements:
    """Read and validate a measurement CSV; raise :class:`ModelError` with the line at fault."""
    columns = read_numeric_csv(path, REQUIRED_COLUMNS, ("force_n", "participant"), ModelError, "file")
    amplitude = columns["amplitude_um_pp"]
    ratio = columns["relative_friction"]
    force = columns.get("force_n")
    if len(amplitude) < 2:
        raise ModelError(f"{path}: at least two data rows are needed, found {len(amplitude)}")
    if np.any(amplitude < 0):
        raise ModelError(f"{path}: amplitude_um_pp must not be negative")
    if np.any((ratio <= 0) | (ratio > 1.2)):
        raise ModelError(f"{path}: relative_friction must lie in (0, 1.2]")
    if force is not None and np.any(force <= 0):
        raise ModelError(f"{path}: force_n must be positive")
    return Measurements(amplitude, ratio, force, str(path), columns.get("participant"))
