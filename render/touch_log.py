"""Touch logs: CSV files of ``t_s,x_mm,y_mm[,force_n]`` as a touch logger records them."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from render.errors import RenderError
from render.trajectory import RecordedTrajectory

COLUMNS = ("t_s", "x_mm", "y_mm")


def read_touch_log(path: str | Path) -> RecordedTrajectory:
    """A recorded trajectory from a CSV; errors name the line at fault. ``#`` lines are comments."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise RenderError(f"{path}: no such trajectory file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise RenderError(f"{path}: cannot read it as text ({error})") from None
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise RenderError(f"{path}: empty; expected a header t_s,x_mm,y_mm[,force_n] and rows")
    header = [name.strip() for name in next(csv.reader(io.StringIO(lines[0][1])))]
    missing = [name for name in COLUMNS if name not in header]
    if missing:
        raise RenderError(f"{path}:{lines[0][0]}: missing column {', '.join(missing)}; "
                          "the header must be t_s,x_mm,y_mm[,force_n]")
    wanted = list(COLUMNS) + (["force_n"] if "force_n" in header else [])
    index = [header.index(name) for name in wanted]
    rows = []
    previous_t = -math.inf
    for number, line in lines[1:]:
        cells = next(csv.reader(io.StringIO(line)))
        if len(cells) < len(header):
            raise RenderError(f"{path}:{number}: expected {len(header)} values, found {len(cells)}")
        row = []
        for name, column in zip(wanted, index, strict=True):
            try:
                value = float(cells[column])
            except ValueError:
                raise RenderError(f"{path}:{number}: {name} is not a number: {cells[column].strip()!r}") from None
            if not math.isfinite(value):
                raise RenderError(f"{path}:{number}: {name} must be a finite number, got {cells[column].strip()}")
            row.append(value)
        if row[0] <= previous_t:
            raise RenderError(f"{path}:{number}: time goes backwards or repeats ({row[0]:g} s after "
                              f"{previous_t:g} s); sort the log by time")
        if len(row) == 4 and row[3] < 0:
            raise RenderError(f"{path}:{number}: force_n must not be negative")
        previous_t = row[0]
        rows.append(row)
    if len(rows) < 2:
        raise RenderError(f"{path}: at least two rows are needed, found {len(rows)}")
    data = np.array(rows)
    data[:, 0] -= data[0, 0]  # the log's own clock: start at zero
    force = data[:, 3] if data.shape[1] == 4 else None
    return RecordedTrajectory(data[:, 0], data[:, 1], data[:, 2], force)
