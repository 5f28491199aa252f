"""Measured friction points from CSV: ``amplitude_um_pp,relative_friction[,force_n][,participant]``.

Lines starting with ``#`` are comments. Amplitudes are peak-to-peak; convert zero-to-peak data
(as many published fits are) by doubling before saving. ``participant`` is a number naming whose
finger each point is (for cross-validation across people).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from ultraglide.render.physics.csv_table import Column, read_numeric_csv
from ultraglide.render.physics.errors import ModelError

AMPLITUDE = Column("amplitude_um_pp", 0.0, 100.0, "µm p-p")  # plates reach a few µm; 100 is no plate
RELATIVE_FRICTION = Column("relative_friction", 0.0, 1.2, low_open=True)  # above 1: measurement noise
FORCE = Column("force_n", 0.0, 50.0, "N", low_open=True)
PARTICIPANT = Column("participant", -1e9, 1e9)  # a number naming whose finger it is
REQUIRED_COLUMNS = (AMPLITUDE.name, RELATIVE_FRICTION.name)
MAX_ROWS = 100_000  # measured tables hold tens to thousands of points
MIN_STEP_UM = 0.001  # distinct amplitudes at one force closer than a nanometre are one measurement, or noise


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
    """Read and validate a measurement CSV; raise :class:`ModelError` with the line at fault.

    Ranges: amplitude_um_pp 0..100, relative_friction in (0, 1.2], force_n in (0, 50], at most
    100 000 rows. There must be two different amplitudes or more, at one force never closer than
    0.001 µm, and the friction must fall below 1 somewhere (a flat table says nothing about how
    friction falls, so it can neither be inverted nor fitted).
    """
    columns = read_numeric_csv(path, (AMPLITUDE, RELATIVE_FRICTION), (FORCE, PARTICIPANT), ModelError,
                               "measurement file", MAX_ROWS)
    amplitude = columns["amplitude_um_pp"]
    ratio = columns["relative_friction"]
    force = columns.get("force_n")
    if len(amplitude) < 2:
        raise ModelError(f"{path}: at least two data rows are needed, found {len(amplitude)}")
    if len(np.unique(amplitude)) < 2:
        raise ModelError(f"{path}: every row has the same amplitude; two different amplitudes or more are needed")
    if not np.min(ratio) < 1.0:
        raise ModelError(f"{path}: relative_friction never falls below 1: a flat table cannot be inverted or "
                         "fitted; measure at amplitudes where the finger glides")
    for value in np.unique(force) if force is not None else [None]:
        distinct = np.unique(amplitude if value is None else amplitude[force == value])
        steps = np.diff(distinct)
        if len(steps) and steps.min() < MIN_STEP_UM:
            k = int(np.argmin(steps))
            at = "" if value is None else f" at {value:g} N"
            raise ModelError(f"{path}: amplitudes {distinct[k]:g} and {distinct[k + 1]:g} µm{at} differ by less than "
                             f"{MIN_STEP_UM:g} µm, below any vibrometer's resolution; merge them")
    return Measurements(amplitude, ratio, force, str(path), columns.get("participant"))
