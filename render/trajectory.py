"""Where the finger is at any instant: recorded paths (offline) and live touch reports (real time).

Both answer ``state(times_s)`` with the finger's position (mm), force (N, NaN when unknown) and
whether it touches, at the control-rate instants the renderer asks for.

Live reports arrive at 60–240 Hz and describe where the finger was 30–80 ms ago. Between
reports, :class:`LiveTrajectory` predicts: a least-squares line through the last few reports of
the current stroke (which averages out the panel's jitter, unlike the TPad's two-point
extrapolation) evaluated ``lookahead_s`` ahead, so the panel's latency is cancelled. A finger that
stops moving usually stops producing reports, so prediction never runs further than
``max_extrapolation_s`` (plus the look-ahead) past the newest report.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import PchipInterpolator
from ultraglide.render.errors import RenderError

PREDICTORS = ("lsq", "linear", "hold")
MERGE_S = 0.002  # reports closer than this are one instant (events read from a queue in one go)
MAX_SPEED_MM_S = 3000.0  # exploring fingers move at 40-200 mm/s; flicks reach about 1 m/s


@dataclass(frozen=True)
class FingerState:
    """The finger at a set of instants. ``force_n`` and ``down`` may be scalars (the same for all);
    ``velocity_mm_s`` is set when the motion is a straight line over these instants (live prediction)."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    force_n: np.ndarray | float  # NaN where the panel does not measure force
    down: np.ndarray | bool
    velocity_mm_s: tuple[float, float] | None = None


@dataclass(frozen=True)
class _Fit:
    """The prediction line through the latest reports: position at t_ref plus velocity."""

    t_ref: float
    x_ref: float
    y_ref: float
    vx: float
    vy: float
    t_last: float
    force_n: float
    down: bool


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

    def __init__(self, predictor: str = "lsq", lookahead_s: float = 0.0, fit_reports: int = 8,
                 fit_window_s: float = 0.1, max_extrapolation_s: float = 0.05):
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
        self._records: deque[tuple[float, float, float, float]] = deque(maxlen=fit_reports)  # t, x, y, force
        self._down = False
        self._fit: _Fit | None = None
        self.reports = 0

    def push(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None = None, down: bool = True) -> None:
        """Record one touch report (time in perf_counter seconds). ``down=False`` lifts the finger.

        The prediction line is fitted here, on the thread that reports touches, in plain floats
        (a handful of points), so the real-time thread only evaluates it and the GIL is held briefly.
        """
        with self._lock:
            self.reports += 1
            if not down:
                self._down = False
                if self._fit is not None:
                    self._fit = replace(self._fit, down=False, vx=0.0, vy=0.0)
                return
            if not self._down:  # a new stroke: never fit across strokes
                self._records.clear()
                self._down = True
            if self._records and t_s <= self._records[-1][0]:
                return  # out of order or duplicate: the newer report already stands
            if self._records and t_s - self._records[-1][0] < MERGE_S:
                self._records.pop()  # queued events read in one go: the same instant, keep the newest
            self._records.append((float(t_s), float(x_mm), float(y_mm),
                                  math.nan if force_n is None else float(force_n)))
            self._fit = self._line()

    def _line(self) -> _Fit:
        last = self._records[-1]
        recent = [r for r in self._records if r[0] >= last[0] - self.fit_window_s]
        force = last[3]
        if self.predictor == "hold" or len(recent) < 2:
            return _Fit(last[0], last[1], last[2], 0.0, 0.0, last[0], force, True)
        if self.predictor == "linear":  # the TPad's: through the last two reports
            before = recent[-2]
            span = last[0] - before[0]
            vx, vy = (last[1] - before[1]) / span, (last[2] - before[2]) / span
            scale = min(1.0, MAX_SPEED_MM_S / max(math.hypot(vx, vy), 1e-12))
            return _Fit(last[0], last[1], last[2], vx * scale, vy * scale, last[0], force, True)
        count = len(recent)
        mean_t = sum(r[0] for r in recent) / count
        mean_x = sum(r[1] for r in recent) / count
        mean_y = sum(r[2] for r in recent) / count
        spread = sum((r[0] - mean_t) ** 2 for r in recent)
        vx = sum((r[0] - mean_t) * (r[1] - mean_x) for r in recent) / spread
        vy = sum((r[0] - mean_t) * (r[2] - mean_y) for r in recent) / spread
        speed = math.hypot(vx, vy)
        if speed > MAX_SPEED_MM_S:  # no finger explores this fast: a glitch, not motion
            vx, vy = vx * MAX_SPEED_MM_S / speed, vy * MAX_SPEED_MM_S / speed
        return _Fit(mean_t, mean_x, mean_y, vx, vy, last[0], force, True)

    def state(self, times_s, out=None) -> FingerState:
        """The finger at ``times_s``; ``out``: two preallocated arrays (x, y) to fill (no allocation)."""
        fit = self._fit  # one reference, swapped whole by push: no lock needed to read it
        times = np.asarray(times_s, dtype=float)
        if fit is None:
            if out is not None:
                out[0].fill(0.0)
                out[1].fill(0.0)
                return FingerState(out[0], out[1], np.nan, False, (0.0, 0.0))
            nothing = np.zeros(times.shape)
            return FingerState(nothing, nothing, np.nan, False, (0.0, 0.0))
        x, y = out if out is not None else (np.empty(times.shape), np.empty(times.shape))
        np.minimum(times, fit.t_last + self.max_extrapolation_s, out=x)
        x += self.lookahead_s - fit.t_ref  # x holds the horizon until it is scaled
        np.multiply(x, fit.vy, out=y)
        x *= fit.vx
        x += fit.x_ref
        y += fit.y_ref
        moving = times[-1] <= fit.t_last + self.max_extrapolation_s if times.ndim else True
        velocity = (fit.vx, fit.vy) if moving else (0.0, 0.0)
        return FingerState(x, y, fit.force_n, fit.down, velocity)
