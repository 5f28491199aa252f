"""Numeric CSV files with a header line and ``#`` comments, read with errors that name the line."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np


def read_numeric_csv(path: str | Path, required: tuple[str, ...], optional: tuple[str, ...], error: type,
                     what: str) -> dict[str, np.ndarray]:
    """The named columns as float arrays; ``error(message)`` is raised with the file and line at fault."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError) as problem:
        raise error(f"{path}: cannot read it as text ({problem})") from None
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    expected = ",".join(required) + "".join(f"[,{name}]" for name in optional)
    if not lines:
        raise error(f"{path}: no data; expected a header line {expected}")
    header = [name.strip() for name in next(csv.reader(io.StringIO(lines[0][1])))]
    missing = [name for name in required if name not in header]
    if missing:
        raise error(f"{path}:{lines[0][0]}: missing column {', '.join(missing)}; the header must be {expected}")
    wanted = list(required) + [name for name in optional if name in header]
    index = [header.index(name) for name in wanted]
    values: dict[str, list[float]] = {name: [] for name in wanted}
    for number, line in lines[1:]:
        cells = next(csv.reader(io.StringIO(line)))
        if len(cells) < len(header):
            raise error(f"{path}:{number}: expected {len(header)} values, found {len(cells)}")
        for name, column in zip(wanted, index, strict=True):
            cell = cells[column].strip()
            try:
                value = float(cell)
            except ValueError:
                raise error(f"{path}:{number}: {name} is not a number: {cell!r}") from None
            if not math.isfinite(value):
                raise error(f"{path}:{number}: {name} must be a finite number, got {cell}")
            values[name].append(value)
    columns = {name: np.array(column) for name, column in values.items()}
    columns["_line"] = np.array([number for number, _ in lines[1:]], dtype=int)
    return columns
