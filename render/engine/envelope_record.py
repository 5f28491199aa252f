"""The engine's envelope, recorded to CSV as it plays (``play --envelope-csv``), off the block path.

The block path copies each block's columns into a ring made once (:meth:`EnvelopeRecord.add`: no allocation,
no I/O); a writer thread drains the ring to ``FILE.part`` and renames it to ``FILE`` when closed. Columns:
``t_s`` (perf_counter s, the clock every ultraglide log uses: when the value plays on the plate, see below),
``index`` (the sample's number in the device's stream: a plate driver's SENSORS name the index playing, which
``play --sensors-csv`` records), ``x_mm``, ``y_mm``, ``down``, ``target_ratio`` (the texture's friction there),
``target_um_pp`` (the model's amplitude for it: the closed loop's, when it follows), ``commanded_um_pp`` (what
the device was given, after the limiter), ``planned_ratio`` (the static ratio the model's inverse was asked for:
with a model that has friction dynamics the planner's command, whose response through them is the friction the
plan means felt; else the target itself) and ``plan_s`` (perf_counter s: when the renderer meant the value to
reach the plate). A writer that falls a whole ring behind loses rows: they are counted
(:attr:`EnvelopeRecord.dropped`) and the run says so.

``t_s``, with a play clock (:attr:`EnvelopeRecord.clock`, a :class:`~ultraglide.render.engine.play_clock.PlayClock`
fed by a plate driver's SENSORS frames, which say which value plays when, and its CLOCK replies where it states its
clock): when the value plays by the plate's own account. The writer holds rows back the clock's look ahead and a
piece (4.2 s at 12 kHz, less where its ring holds less: :func:`hold_s`; the frames read up to 4 s after their time
have come) and places each ``PIECE_S`` of them by the clock there. Rows the clock cannot place (no frame read within
its window: before the stream plays, a plate that sends no SENSORS) and every row of a device without a sensor
listener (a wav file, an audio output, the null device) keep the plan, ``t_s`` = ``plan_s``: the renderer re-anchors
its plan only when the plate's buffer drifts past its deadband, and values play up to a few ms after it
(bench/bench_record_timing.py).
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np
from ultraglide.render.engine.csv_record import CsvRecord

COLUMNS = ("t_s", "index", "x_mm", "y_mm", "down", "target_ratio", "target_um_pp", "commanded_um_pp", "planned_ratio",
           "plan_s")
RING_COLUMNS = len(COLUMNS) - 1  # the plan's time is the ring's t_s, copied by the writer
RING_ROWS = 1 << 17  # 11 s at 12 kHz
WRITE_PERIOD_S = 0.2
FORMAT = ("%.6f", "%d", "%.4f", "%.4f", "%d", "%.5f", "%.5f", "%.5f", "%.5f", "%.6f")
PIECE_S = 0.2  # rows placed by one reading of the play clock


class EnvelopeRecord(CsvRecord):
    """See the module docstring.

    Parameters
    ----------
    path : str or path-like
        The CSV file written (``FILE.part`` until closed).

    Examples
    --------
    Two samples of a block, read back by the csv module once closed:

    >>> import csv, pathlib, tempfile
    >>> import numpy as np
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "envelope.csv"
    >>> record = EnvelopeRecord(path)
    >>> record.add(np.array([1.0, 1.5]), 100, np.array([2.0, 3.0]), np.zeros(2), True, np.array([0.5, 0.6]),
    ...            np.array([3.1, 2.8]), np.array([3.0, 2.8]))
    >>> record.close() is None
    True
    >>> rows = list(csv.DictReader(path.open()))
    >>> [(row["index"], row["x_mm"], row["commanded_um_pp"]) for row in rows]
    [('100', '2.0000', '3.00000'), ('101', '3.0000', '2.80000')]
    """

    def __init__(self, path: str | os.PathLike):
        super().__init__(path, COLUMNS)
        self._ring = np.zeros((RING_ROWS, RING_COLUMNS))
        self._steps = np.arange(RING_ROWS, dtype=float)
        self._written = 0  # rows added (the block path's count)
        self._taken = 0  # rows written out (the writer's)
        self.clock = None  # a PlayClock: rows written at its times (see the module docstring); None: the plan's
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._write_loop, name="envelope-record", daemon=True)
        self._thread.start()

    def add(self, time_s, first_index, x_mm, y_mm, down, ratio, target_um_pp, commanded_um_pp,
            planned_ratio=None) -> None:
        """One block's columns (arrays of its length; ``down`` a bool or one per sample; ``first_index`` the stream
        index of its first sample). Block path: copies only.

        Parameters
        ----------
        time_s : numpy.ndarray
            The samples' times, s.
        first_index : int
            The first sample's index in the stream.
        x_mm, y_mm : numpy.ndarray
            The finger, mm.
        down : numpy.ndarray or bool
            Whether it touches.
        ratio : numpy.ndarray
            The target friction ratio.
        target_um_pp, commanded_um_pp : numpy.ndarray
            The amplitude asked and sent, µm p-p.
        planned_ratio : numpy.ndarray, optional
            The static ratio the model's inverse was asked for (the planner's command); None: ``ratio``.

        Examples
        --------
        A lifted finger is logged as 0, one row per sample, read back by the csv module:

        >>> import csv, pathlib, tempfile
        >>> import numpy as np
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "envelope.csv"
        >>> record = EnvelopeRecord(path)
        >>> nothing = np.zeros(3)
        >>> record.add(np.array([0.0, 0.5, 1.0]), 7, nothing, nothing, False, np.ones(3), nothing, nothing)
        >>> record.close() is None
        True
        >>> [(row["index"], row["down"]) for row in csv.DictReader(path.open())]
        [('7', '0'), ('8', '0'), ('9', '0')]
        """
        n = len(time_s)
        if n > RING_ROWS:
            self.dropped += n
            return
        start = self._written % RING_ROWS
        first = min(n, RING_ROWS - start)
        ring = self._ring
        planned = ratio if planned_ratio is None else planned_ratio
        columns = (time_s, None, x_mm, y_mm, down, ratio, target_um_pp, commanded_um_pp, planned)
        for column, values in enumerate(columns):
            if values is None:  # the stream index: counted, not copied
                np.add(self._steps[:first], first_index, out=ring[start:start + first, column])
                np.add(self._steps[first:n], first_index, out=ring[:n - first, column])
                continue
            if np.ndim(values) == 0:
                ring[start:start + first, column] = values
                ring[:n - first, column] = values
            else:
                ring[start:start + first, column] = values[:first]
                ring[:n - first, column] = values[first:]
        self._written += n

    def _write_loop(self) -> None:
        while not self._stop.wait(WRITE_PERIOD_S):
            self._drain()

    def _drain(self, finish: bool = False) -> None:
        written = self._written
        if written - self._taken > RING_ROWS:  # overwritten before the writer came: lost
            self.dropped += written - self._taken - RING_ROWS
            self._taken = written - RING_ROWS
        if written == self._taken or self.error is not None:
            return
        ring_rows = np.take(self._ring, np.arange(self._taken, written) % RING_ROWS, axis=0)
        rows = np.column_stack((ring_rows, ring_rows[:, 0]))  # plan_s: the renderer's time, kept
        clock = self.clock
        if clock is not None:
            if not finish:  # the rows whose time is the clock's look ahead and a piece past: its frames have come
                late = rows[:, 0] > time.perf_counter() - (hold_s(clock) + PIECE_S)
                rows = rows[:int(np.argmax(late))] if late.any() else rows
                if not len(rows):
                    return
            self._place(rows, clock)
        self._taken += len(rows)
        self._write_rows(rows, FORMAT)

    @staticmethod
    def _place(rows: np.ndarray, clock) -> None:
        """``t_s`` of ``rows`` (in place) by the play clock, ``PIECE_S`` at a time; rows it cannot place keep theirs."""
        piece = max(1, int(PIECE_S * clock.stream_rate_hz))
        for start in range(0, len(rows), piece):
            part = rows[start:start + piece]
            times = clock.times_s(part[:, 1], float(part[len(part) // 2, 0]))
            if times is not None:
                part[:, 0] = times

    def _stop_writer(self, finish: bool) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        if finish:
            self._drain(finish=True)


def hold_s(clock) -> float:
    """How long the writer holds rows back for ``clock`` (s): its look ahead, within half the ring at its rate.

    Parameters
    ----------
    clock : PlayClock
        The record's play clock.

    Returns
    -------
    float
        The hold, s.

    Examples
    --------
    >>> from ultraglide.render.engine.play_clock import PlayClock
    >>> hold_s(PlayClock(12000.0)), round(hold_s(PlayClock(48000.0)), 3)     # 4 s; half of 2.73 s of rows
    (4.0, 1.365)
    """
    return min(clock.ahead_s, RING_ROWS / clock.stream_rate_hz / 2)

