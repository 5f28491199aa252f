"""The simulated finger's true state, logged as it goes.

Columns ``t_s,amplitude_um_pp,normal_force_n,relative_friction,sliding``.

``t_s`` is on the host's clock (``time.perf_counter`` seconds, which every process on the machine shares),
so the log lines up with what the host recorded (``play --envelope-csv``, the engine's history). Rows are
the finger's instantaneous state every 1/``rate_hz`` s of the plate's clock (2 kHz by default); the file is
written to ``FILE.csv.part``, flushed every ``FLUSH_S`` of plate time, and renamed to ``FILE.csv`` when the
log is closed (a run that dies leaves the ``.part``, never a file that looks whole).

Without a path the rows are kept in memory (the last ``max_rows``), for a program that runs the finger in
its own process: :meth:`FingerLog.rows`.
"""

from __future__ import annotations

import contextlib
import io
import os
import threading
import time
from pathlib import Path

import numpy as np
from ultraglide.devices.errors import DeviceError

from ultraglide.atomic import AtomicFile, OutputRefused

HEADER = "t_s,amplitude_um_pp,normal_force_n,relative_friction,sliding"
FLUSH_S = 0.1


class FingerLog:
    """See the module docstring. ``clock_origin_s``: the perf_counter time of the plate's sample 0 (the
    simulated plate sets it; None: estimated at the first chunk from the time it is written)."""

    def __init__(self, path: str | os.PathLike | None = None, rate_hz: float = 2000.0, sample_rate_hz: int = 48000,
                 clock_origin_s: float | None = None, max_rows: int = 2_000_000):
        if not 1.0 <= rate_hz <= sample_rate_hz:
            raise DeviceError(f"the finger log's rate must be 1 Hz to {sample_rate_hz} Hz, got {rate_hz:g}")
        self.path = None if path is None else Path(path)
        self.rate_hz = float(rate_hz)
        self.sample_rate_hz = int(sample_rate_hz)
        self.clock_origin_s = clock_origin_s
        self._every = max(1, int(round(sample_rate_hz / rate_hz)))
        self._lock = threading.Lock()
        self._chunks: list[tuple] = []  # chunks of truth not yet sampled into rows
        self._rows: list[np.ndarray] = []  # rows kept in memory (no path)
        self._kept = 0
        self._max_rows = max_rows
        self._handle = None
        self._part = None
        self._unflushed = 0
        self._closed = False
        self.rows_written = 0
        if self.path is not None:
            try:
                self._target = AtomicFile(self.path, partial=True)  # FILE.csv.part; never renamed over a non-file
                self._part = self._target.temporary
                self._handle = open(self._part, "w", encoding="utf-8", newline="")  # noqa: SIM115 - closed by close()
                self._handle.write(HEADER + "\n")
            except OSError as error:
                raise DeviceError(f"{self.path}: cannot write the finger log: "
                                  f"{(error.strerror or str(error)).lower()}") from None
            except OutputRefused as error:
                raise DeviceError(f"the finger log: {error}") from None

    def __repr__(self) -> str:
        where = str(self.path) if self.path else "memory"
        return f"FingerLog({where}, {self.rate_hz:g} Hz, {self.rows_written} rows)"

    def write(self, truth) -> None:
        """One chunk of the finger's truth (:class:`~ultraglide.devices.sim.finger.FingerTruth`); kept as it is,
        sampled and formatted when flushed (every ``FLUSH_S``: a millisecond's chunk costs next to nothing)."""
        if self._closed or not len(truth.t_s):
            return
        if self.clock_origin_s is None:
            self.clock_origin_s = time.perf_counter() - float(truth.t_s[-1])
        with self._lock:
            self._chunks.append((truth.t_s, truth.amplitude_um_pp, truth.normal_force_n, truth.relative_friction,
                                 truth.sliding))
            self._unflushed += len(truth.t_s)
            if self._unflushed >= FLUSH_S * self.sample_rate_hz:
                self._take()

    def _take(self) -> None:
        """The chunks so far, sampled every 1/rate_hz s into rows (written out, or kept in memory)."""
        if not self._chunks:
            return
        columns = [np.concatenate(parts) for parts in zip(*self._chunks, strict=True)]
        self._chunks = []
        self._unflushed = 0
        samples = np.round(columns[0] * self.sample_rate_hz).astype(np.int64)
        pick = np.flatnonzero(samples % self._every == 0)
        rows = np.column_stack([columns[0][pick] + self.clock_origin_s]
                               + [column[pick].astype(float) for column in columns[1:]])
        self.rows_written += len(rows)
        if self._handle is None:
            self._rows.append(rows)
            self._kept += len(rows)
            while len(self._rows) > 1 and self._kept - len(self._rows[0]) >= self._max_rows:
                self._kept -= len(self._rows.pop(0))
            return
        text = io.StringIO()
        np.savetxt(text, rows[:, :4], fmt=("%.6f", "%.5f", "%.5f", "%.5f"), delimiter=",")
        lines = text.getvalue().splitlines()
        flags = rows[:, 4].astype(int)
        self._handle.write("".join(f"{line},{flag}\n" for line, flag in zip(lines, flags, strict=True)))
        self._handle.flush()

    def rows(self) -> np.ndarray:
        """The rows kept in memory so far (a log without a path): t_s, amplitude, force, ratio, sliding."""
        with self._lock:
            if self._handle is None:
                self._take()
            return np.concatenate(self._rows) if self._rows else np.zeros((0, 5))

    def close(self) -> None:
        """Write what is left and rename ``FILE.csv.part`` to ``FILE.csv``. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._handle is None:
                return
            try:
                self._take()
                self._handle.close()
                self._target.commit()
            except OSError as error:
                with contextlib.suppress(OSError):
                    self._handle.close()
                raise DeviceError(f"{self.path}: the finger log could not be finished: "
                                  f"{(error.strerror or str(error)).lower()}") from None
