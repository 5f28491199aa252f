"""Measured friction points from CSV: ``amplitude_um_pp,relative_friction[,force_n]``.

Lines starting with ``#`` are comments. Amplitudes are peak-to-peak; convert zero-to-peak data
(as many published fits are) by doubling before saving.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from render.errors import ModelError

REQUIRED_COLUMNS = ("amplitude_um_pp", "relative_friction")


@dataclass(frozen=True)
class Measurements:
    """Measured relative friction against amplitude (µm p-p), with the normal force (N) if known."""

    amplitude_um_pp: np.ndarray
    relative_friction: np.ndarray
    force_n: np.ndarray | None
    source: str

    def __len__(self) -> int:
        return len(self.amplitude_um_pp)


def read_measurements(path: str | Path) -> Measurements:
    """Read and validate a measurement CSV; raise :class:`ModelError` with the line at fault."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise ModelError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ModelError(f"{path}: cannot read it as text ({error})") from None
    rows = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise ModelError(f"{path}: no data; expected a header line {','.join(REQUIRED_COLUMNS)}")
    header_number, header_line = rows[0]
    header = [name.strip() for name in next(csv.reader(io.StringIO(header_line)))]
    missing = [name for name in REQUIRED_COLUMNS if name not in header]
    if missing:
        raise ModelError(
            f"{path}:{header_number}: missing column {', '.join(missing)}; "
            f"the header must name amplitude_um_pp,relative_friction[,force_n]"
        )
    wanted = list(REQUIRED_COLUMNS) + (["force_n"] if "force_n" in header else [])
    index = {name: header.index(name) for name in wanted}
    values: dict[str, list[float]] = {name: [] for name in wanted}
    for number, line in rows[1:]:
        cells = next(csv.reader(io.StringIO(line)))
        for name in wanted:
            if index[name] >= len(cells):
                raise ModelError(f"{path}:{number}: no value for {name}")
            cell = cells[index[name]].strip()
            try:
                value = float(cell)
            except ValueError:
                raise ModelError(f"{path}:{number}: {name} is not a number: {cell!r}") from None
            if not math.isfinite(value):
                raise ModelError(f"{path}:{number}: {name} must be finite, got {cell}")
            values[name].append(value)
    amplitude = np.array(values["amplitude_um_pp"])
    ratio = np.array(values["relative_friction"])
    force = np.array(values["force_n"]) if "force_n" in values else None
    if len(amplitude) < 2:
        raise ModelError(f"{path}: at least two data rows are needed, found {len(amplitude)}")
    if np.any(amplitude < 0):
        raise ModelError(f"{path}: amplitude_um_pp must not be negative")
    if np.any((ratio <= 0) | (ratio > 1.2)):
        raise ModelError(f"{path}: relative_friction must lie in (0, 1.2]")
    if force is not None and np.any(force <= 0):
        raise ModelError(f"{path}: force_n must be positive")
    return Measurements(amplitude, ratio, force, str(path))
