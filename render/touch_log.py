"""Touch logs: CSV files of ``t_s,x_mm,y_mm[,force_n]`` as a touch logger records them.

A log of any length is read in bounded memory: :func:`read_touch_log` checks the whole file in
one streaming pass (every value in range, time never going back, two instants at least), then
returns a :class:`~ultraglide.render.trajectory.RecordedTrajectory`. A file of up to ``HELD_BYTES``
(4 MiB) is kept from that pass (a 10-minute log at 120 Hz is 72 000 rows, 2.3 MB); a larger one is
read again in chunks as the renderer moves along. Times are seconds on the logger's clock
(perf_counter or Unix time alike); the trajectory starts at zero.
"""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from ultraglide.render.errors import RenderError
from ultraglide.render.physics.csv_table import Column, NumericCsv
from ultraglide.render.trajectory import RecordedTrajectory

TIME = Column("t_s", -1e10, 1e10, "s")  # Unix time is 1.7e9 s; 1e10 s is three centuries on
X = Column("x_mm", -10_000.0, 10_000.0, "mm")  # no plate is 10 m across
Y = Column("y_mm", -10_000.0, 10_000.0, "mm")
FORCE = Column("force_n", 0.0, 50.0, "N")  # fingers press with 0.1 to a few newtons
COLUMNS = (TIME.name, X.name, Y.name)
MAX_SPAN_S = 86_400.0  # a day of touches; longer logs are someone's clock in milliseconds
HELD_BYTES = 4 << 20  # logs up to this size stay in memory after the check (about 4 MB of arrays): read once


@dataclass(frozen=True)
class TouchLog:
    r"""A checked touch-log file: where it is, its first and last time (s) and its row count.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "drag.csv"
    >>> _ = path.write_text("t_s,x_mm,y_mm,force_n\n0.0,10,20,0.4\n0.5,60,20,0.6\n")
    >>> log = check_touch_log(path)
    >>> log.rows, log.has_force, log.force_range_n, log.trajectory().state([0.25]).x_mm.tolist()
    (2, True, (0.4, 0.6), [35.0])
    """

    table: NumericCsv
    first_s: float
    last_s: float
    rows: int
    force_range_n: tuple[float, float] | None = None  # lowest and highest force, N, when logged
    held: tuple | None = field(default=None, compare=False, repr=False)  # the checked chunks when short enough

    @property
    def has_force(self) -> bool:
        r"""Whether the log has a ``force_n`` column (a pressure-sensing panel's).

        Examples
        --------
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "drag.csv"
        >>> _ = path.write_text("t_s,x_mm,y_mm\n0.0,10,20\n0.5,60,20\n")
        >>> check_touch_log(path).has_force
        False
        """
        return "force_n" in self.table.names

    def chunks(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]]:
        r"""``(t_s from zero, x_mm, y_mm, force_n or None)`` arrays, a block of the file at a time.
        Each block's values are checked again (ranges, time order), in case the file changed since;
        a log held in memory since its check is not read again.

        Returns
        -------
        iterator of tuple
            ``(t_s, x_mm, y_mm, force_n or None)`` arrays (s from the first record, mm, mm, N).

        Examples
        --------
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "drag.csv"
        >>> _ = path.write_text("t_s,x_mm,y_mm,force_n\n100.0,10,20,0.4\n100.5,60,20,0.6\n")
        >>> [(t.tolist(), x.tolist(), force.tolist()) for t, x, y, force in check_touch_log(path).chunks()]
        [([0.0, 0.5], [10.0, 60.0], [0.4, 0.6])]
        """
        if self.held is not None:
            yield from self.held
            return
        previous = self.first_s
        for block in self.table.blocks():
            values = block.values
            t = values["t_s"]
            if len(t) and (t[0] < previous or np.any(np.diff(t) < 0) or t[-1] > self.last_s):
                raise RenderError(f"{self.table.path}: the file changed while it was being read; "
                                  "copy the log somewhere else and read the copy")
            previous = t[-1] if len(t) else previous
            yield (t - self.first_s, values["x_mm"], values["y_mm"], values.get("force_n"))

    def trajectory(self) -> RecordedTrajectory:
        r"""The log as a recorded trajectory, streamed from the file block by block (times from 0 s).

        Returns
        -------
        RecordedTrajectory

        Examples
        --------
        A log whose clock starts at 100 s: its trajectory starts at 0:

        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "drag.csv"
        >>> _ = path.write_text("t_s,x_mm,y_mm\n100.0,10,20\n100.5,60,20\n")
        >>> path = check_touch_log(path).trajectory()
        >>> path.start_s, path.end_s, path.state([0.25]).x_mm.tolist()
        (0.0, 0.5, [35.0])
        """
        return RecordedTrajectory.streaming(self.chunks, 0.0, self.last_s - self.first_s, self.has_force,
                                            self.force_range_n)


def _size_of(path: str | Path) -> float:
    """The file's size in bytes (infinite when it has none, a pipe: streamed, never held)."""
    try:
        info = os.stat(path)
    except OSError:
        return math.inf  # the table's own reading says what is wrong
    return info.st_size if stat.S_ISREG(info.st_mode) else math.inf


def check_touch_log(path: str | Path) -> TouchLog:
    """Read a touch log through once, checking it; :class:`RenderError` names the line at fault.

    Parameters
    ----------
    path : str or pathlib.Path
        A CSV of ``t_s,x_mm,y_mm[,force_n]``.

    Returns
    -------
    TouchLog
        Where it is, its first and last time (s) and its rows.

    Raises
    ------
    RenderError
        A value out of range, time going back, fewer than two instants: the line at fault, in one line.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "drag.csv"
    >>> _ = path.write_text("t_s,x_mm,y_mm\\n0.0,10,20\\n0.5,60,20\\n")
    >>> log = check_touch_log(path)
    >>> log.rows, log.first_s, log.last_s, log.has_force
    (2, 0.0, 0.5, False)
    >>> _ = path.write_text("t_s,x_mm,y_mm\\n0.5,10,20\\n0.0,60,20\\n")
    >>> check_touch_log(path)                                           # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.errors.RenderError: ...drag.csv:3: time goes backwards (0 s after 0.5 s); sort the log by time
    """
    table = NumericCsv(path, (TIME, X, Y), (FORCE,), RenderError, "trajectory file")
    first = previous = None
    rows = 0
    forces = [math.inf, -math.inf]
    held: list | None = [] if _size_of(path) <= HELD_BYTES else None
    for block in table.blocks():
        t = block.values["t_s"]
        if not len(t):
            continue
        if "force_n" in block.values:
            forces = [min(forces[0], block.values["force_n"].min()), max(forces[1], block.values["force_n"].max())]
        if first is None:
            first = previous = float(t[0])
        backwards = np.flatnonzero(np.diff(t, prepend=previous) < 0)
        if len(backwards):
            k = int(backwards[0])
            before = t[k - 1] if k else previous
            raise RenderError(f"{path}:{block.line_of(k)}: time goes backwards ({t[k]:g} s after {before:g} s); "
                              "sort the log by time")
        previous = float(t[-1])
        rows += len(t)
        if held is not None:
            force = block.values.get("force_n")
            held.append((t.copy(), block.values["x_mm"].copy(), block.values["y_mm"].copy(),
                         None if force is None else force.copy()))  # columns of their own, not the block's table
    if rows < 2:
        raise RenderError(f"{path}: at least two rows are needed, found {rows}")
    if previous == first:
        raise RenderError(f"{path}: every row has the same time ({first:g} s); a trajectory needs two instants")
    if previous - first > MAX_SPAN_S:
        raise RenderError(f"{path}: the log spans {previous - first:.3g} s, more than a day ({MAX_SPAN_S:g} s); "
                          "t_s is in seconds (divide milliseconds by 1000)")
    span = (float(forces[0]), float(forces[1])) if "force_n" in table.names else None
    if held is not None:
        held = tuple((t - first, x, y, force) for t, x, y, force in held)
    return TouchLog(table, first, previous, rows, span, held)


def read_touch_log(path: str | Path) -> RecordedTrajectory:
    """A recorded finger path from a touch log CSV (``ultraglide demo --record``), checked whole first.

    Rows ``t_s,x_mm,y_mm[,force_n]`` (s; mm from the texture's top-left corner; N); ``#`` lines are
    comments; a row with empty x and y is a lift. Streamed, so a long log does not fill memory.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    RecordedTrajectory
        The path, to give a renderer or :func:`ultraglide.export_wav` as its trajectory.

    Raises
    ------
    RenderError
        The line at fault and what is wrong with it.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "drag.csv"
    >>> _ = path.write_text("t_s,x_mm,y_mm\\n0.0,10,20\\n0.5,60,20\\n")
    >>> log = read_touch_log(path)
    >>> log.start_s, log.end_s, log.state([0.25]).x_mm.tolist()
    (0.0, 0.5, [35.0])
    """
    return check_touch_log(path).trajectory()
