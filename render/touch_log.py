"""Touch logs: CSV files of ``t_s,x_mm,y_mm[,force_n]`` as a touch logger records them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ultraglide.render.csv_table import read_numeric_csv
from ultraglide.render.errors import RenderError
from ultraglide.render.trajectory import RecordedTrajectory

COLUMNS = ("t_s", "x_mm", "y_mm")


def read_touch_log(path: str | Path) -> RecordedTrajectory:
    """A recorded trajectory from a CSV; errors name the line at fault. ``#`` lines are comments."""
    columns = read_numeric_csv(path, COLUMNS, ("force_n",), RenderError, "trajectory file")
    t, lines = columns["t_s"], columns["_line"]
    backwards = np.flatnonzero(np.diff(t) <= 0)
    if len(backwards):
        k = backwards[0] + 1
        raise RenderError(f"{path}:{lines[k]}: time goes backwards or repeats ({t[k]:g} s after {t[k - 1]:g} s); "
                          "sort the log by time")
    force = columns.get("force_n")
    if force is not None and np.any(force < 0):
        raise RenderError(f"{path}:{lines[np.argmax(force < 0)]}: force_n must not be negative")
    if len(t) < 2:
        raise RenderError(f"{path}: at least two rows are needed, found {len(t)}")
    return RecordedTrajectory(t - t[0], columns["x_mm"], columns["y_mm"], force)  # the log's clock from zero
