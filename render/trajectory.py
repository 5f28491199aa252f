"""Where the finger is at any instant: recorded paths (offline) and live touch reports (real time).

Both answer ``state(times_s)`` with the finger's position (mm), force (N, NaN when unknown) and
whether it touches, at the control-rate instants the renderer asks for.

Live reports arrive at 60–240 Hz and describe where the finger was 30–80 ms ago. Between
reports, :class:`LiveTrajectory` predicts: a least-squares line through the last few reports of
the current stroke (which averages out the panel's jitter, unlike the TPad's two-point
extrapolation) evaluated ``lookahead_s`` ahead, so the panel's latency is cancelled. A finger that
stops moving usually stops producing reports, so prediction never runs further than
``max_extrapolation_s`` past the newest report.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from render.errors import RenderError

PREDICTORS = ("lsq", "linear", "hold")


@dataclass(frozen=True)
class FingerState:
    """The finger at a set of instants."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    force_n: np.ndarray  # NaN where the panel does not measure force
    down: np.ndarray  # bool


class RecordedTrajectory:
    """A path known in advance, as a touch logger records it (uneven rate allowed).

    Positions between records are interpolated monotonically (PCHIP, no overshoot); the finger
    touches from the first record to the last.
    """

    def __init__(self, t_s, x_mm, y_mm, force_n=None):
        t = np.asarray(t_s, dtype=float)
        x = np.asarray(x_mm, dtype=float)
        y = np.asarray(y_mm, dtype=float)
        if t.ndim != 1 or len(t) < 2 or x.shape != t.shape or y.shape != t.shape:
            raise RenderError("a trajectory needs at least two records of t_s, x_mm, y_mm")
        columns = {"t_s": t, "x_mm": x, "y_mm": y}
        if force_n is not None:
            columns["force_n"] = np.asarray(force_n, dtype=float)
        for name, values in columns.items():
            bad = np.flatnonzero(~np.isfinite(values))
            if len(bad):
                raise RenderError(f"trajectory record {bad[0] + 1}: {name} is not a finite number")
        backwards = np.flatnonzero(np.diff(t) <= 0)
        if len(backwards):
            raise RenderError(f"trajectory record {backwards[0] + 2}: time does not increase "
                              f"({t[backwards[0] + 1]:g} s after {t[backwards[0]]:g} s)")
        if force_n is not None and np.any(columns["force_n"] < 0):
            raise RenderError("trajectory forces must not be negative")
        self.t_s, self.x_mm, self.y_mm = t, x, y
        self.force_n = columns.get("force_n")
        self._x = PchipInterpolator(t, x, extrapolate=False)
        self._y = PchipInterpolator(t, y, extrapolate=False)

    @property
    def start_s(self) -> float:
        return float(self.t_s[0])

    @property
    def end_s(self) -> float:
        return float(self.t_s[-1])

    def state(self, times_s) -> FingerState:
        times = np.clip(np.asarray(times_s, dtype=float), self.t_s[0], self.t_s[-1])
        down = (np.asarray(times_s) >= self.t_s[0]) & (np.asarray(times_s) <= self.t_s[-1])
        force = (np.interp(times, self.t_s, self.force_n) if self.force_n is not None
                 else np.full(times.shape, np.nan))
        return FingerState(self._x(times), self._y(times), force, down)


class LiveTrajectory:
    """Touch reports pushed from any thread; predicted at the instants the renderer asks for."""

    CAPACITY = 64

    def __init__(self, predictor: str = "lsq", lookahead_s: float = 0.0, fit_reports: int = 5,
                 fit_window_s: float = 0.06, max_extrapolation_s: float = 0.05):
        if predictor not in PREDICTORS:
            raise RenderError(f"predictor must be one of {', '.join(PREDICTORS)}, got {predictor!r}")
        if lookahead_s < 0 or fit_reports < 2 or fit_window_s <= 0 or max_extrapolation_s < 0:
            raise RenderError("lookahead and extrapolation must be >= 0, fit_reports >= 2, fit_window_s > 0")
        self.predictor = predictor
        self.lookahead_s = lookahead_s
        self.fit_reports = fit_reports
        self.fit_window_s = fit_window_s
        self.max_extrapolation_s = max_extrapolation_s
        self._lock = threading.Lock()
        self._records = np.zeros((self.CAPACITY, 4))  # t, x, y, force per report of this stroke
        self._count = 0
        self._down = False
        self.reports = 0

    def push(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None = None, down: bool = True) -> None:
        """Record one touch report (time in perf_counter seconds). ``down=False`` lifts the finger."""
        record = (t_s, x_mm, y_mm, np.nan if force_n is None else force_n)
        with self._lock:
            self.reports += 1
            if not down:
                self._down = False
                return
            if not self._down:  # a new stroke: never fit across strokes
                self._count = 0
                self._down = True
            if self._count and t_s <= self._records[(self._count - 1) % self.CAPACITY, 0]:
                return  # out of order or duplicate: the newer report already stands
            self._records[self._count % self.CAPACITY] = record
            self._count += 1

    def _snapshot(self) -> tuple[np.ndarray, bool]:
        with self._lock:  # held for a copy of at most 64 rows
            count, down = self._count, self._down
            n = min(count, self.fit_reports)
            index = np.arange(count - n, count) % self.CAPACITY
            return self._records[index].copy(), down

    def state(self, times_s) -> FingerState:
        times = np.asarray(times_s, dtype=float)
        records, down = self._snapshot()
        shape = times.shape
        if len(records) == 0:
            nothing = np.zeros(shape)
            return FingerState(nothing, nothing.copy(), np.full(shape, np.nan), np.zeros(shape, bool))
        last = records[-1]
        recent = records[records[:, 0] >= last[0] - self.fit_window_s]
        horizon = np.minimum(times + self.lookahead_s, last[0] + self.max_extrapolation_s)
        if self.predictor == "hold" or len(recent) < 2:
            x = np.full(shape, last[1])
            y = np.full(shape, last[2])
        elif self.predictor == "linear":  # the TPad's: through the last two reports
            before = recent[-2]
            span = last[0] - before[0]
            x = last[1] + (last[1] - before[1]) / span * (horizon - last[0])
            y = last[2] + (last[2] - before[2]) / span * (horizon - last[0])
        else:
            t = recent[:, 0] - recent[:, 0].mean()
            spread = np.dot(t, t)
            mean_x, mean_y = recent[:, 1].mean(), recent[:, 2].mean()
            vx = np.dot(t, recent[:, 1] - mean_x) / spread
            vy = np.dot(t, recent[:, 2] - mean_y) / spread
            offset = horizon - recent[:, 0].mean()
            x = mean_x + vx * offset
            y = mean_y + vy * offset
        return FingerState(x, y, np.full(shape, last[3]), np.full(shape, down))
