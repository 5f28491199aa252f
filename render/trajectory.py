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
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render import kernels
from ultraglide.render.errors import RenderError

PREDICTORS = ("lsq", "linear", "hold")
MERGE_S = 0.002  # reports closer than this are one instant (events read from a queue in one go)
MAX_SPEED_MM_S = 3000.0  # exploring fingers move at 40-200 mm/s; flicks reach about 1 m/s
Chunk = tuple[np.ndarray, np.ndarray, np.ndarray, "np.ndarray | None"]  # t_s, x_mm, y_mm, force_n or None


@dataclass(frozen=True)
class FingerState:
    """The finger at a set of instants. ``force_n`` and ``down`` may be scalars (the same for all);
    ``velocity_mm_s`` is set when the motion is a straight line over these instants (live prediction).

    Examples
    --------
    A finger moving along x at 100 mm/s, reported every 10 ms, asked where it is at 50 and 100 ms:

    >>> import numpy as np
    >>> live = LiveTrajectory()
    >>> for k in range(10):
    ...     live.push(0.01 * k, 10.0 + k, 5.0)
    >>> state = live.state(np.array([0.05, 0.1]))
    >>> isinstance(state, FingerState), state.x_mm.round(6).tolist(), state.down, round(state.velocity_mm_s[0], 6)
    (True, [15.0, 20.0], True, 100.0)
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    force_n: np.ndarray | float  # NaN where the panel does not measure force
    down: np.ndarray | bool
    velocity_mm_s: tuple[float, float] | None = None


class _Fit(NamedTuple):
    """The prediction line through the latest reports: position at t_ref plus velocity.
    A named tuple: made on every report, and a tuple is built several times faster than a frozen dataclass."""

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
    touches from the first record to the last. Records with the same time are one instant: the
    last of them stands (a logger that reads queued events in one go writes such rows).

    The records come in chunks, from arrays in memory or streamed from a file
    (:meth:`streaming`), and only a window of them is held: the rows around the instants asked
    for, which moves forward as the renderer pulls blocks. PCHIP is local (the slope at a record
    depends on its neighbours only), so interpolating within the window, with two records of
    margin either side, gives what interpolating the whole path would (a compiled kernel,
    :func:`ultraglide.render.kernels.recorded_path`, the slopes and the Horner form of scipy's
    PchipInterpolator). Asking for an earlier instant than the window holds re-reads the chunks
    from the start.

    Parameters
    ----------
    t_s : array_like
        The records' times (s), not decreasing.
    x_mm, y_mm : array_like
        The finger's position (mm).
    force_n : array_like, optional
        Its normal force (N), from a pressure-sensing panel.

    Raises
    ------
    RenderError
        Fewer than two instants, time going back, values not finite.

    Examples
    --------
    >>> path = RecordedTrajectory([0.0, 1.0], [0.0, 10.0], [5.0, 5.0])       # s, mm, mm
    >>> path.start_s, path.end_s, path.state([0.5]).x_mm.tolist()
    (0.0, 1.0, [5.0])
    """

    MARGIN = 2  # records kept either side of the instants asked for

    def __init__(self, t_s: ArrayLike, x_mm: ArrayLike, y_mm: ArrayLike, force_n: ArrayLike | None = None) -> None:
        t = np.asarray(t_s, dtype=float)
        x = np.asarray(x_mm, dtype=float)
        y = np.asarray(y_mm, dtype=float)
        if t.ndim != 1 or len(t) < 2 or x.shape != t.shape or y.shape != t.shape:
            raise RenderError("a trajectory needs at least two records of t_s, x_mm, y_mm")
        columns = {"t_s": t, "x_mm": x, "y_mm": y}
        if force_n is not None:
            columns["force_n"] = np.asarray(force_n, dtype=float)
            if columns["force_n"].shape != t.shape:
                raise RenderError("a trajectory's force_n needs one value per record")
        for name, values in columns.items():
            bad = np.flatnonzero(~np.isfinite(values))
            if len(bad):
                raise RenderError(f"trajectory record {bad[0] + 1}: {name} is not a finite number")
        backwards = np.flatnonzero(np.diff(t) < 0)
        if len(backwards):
            raise RenderError(f"trajectory record {backwards[0] + 2}: time does not increase "
                              f"({t[backwards[0] + 1]:g} s after {t[backwards[0]]:g} s)")
        if t[-1] == t[0]:
            raise RenderError("a trajectory needs records at two different times at least")
        force = columns.get("force_n")
        if force is not None and np.any(force < 0):
            raise RenderError("trajectory forces must not be negative")
        chunk = (t, x, y, force)
        span = None if force is None else (float(force.min()), float(force.max()))
        self._setup(lambda: iter([chunk]), float(t[0]), float(t[-1]), force is not None, span)

    @classmethod
    def streaming(cls, open_chunks: Callable[[], Iterator[Chunk]], start_s: float, end_s: float, has_force: bool,
                  force_range_n: tuple[float, float] | None = None) -> RecordedTrajectory:
        """A trajectory read in chunks: ``open_chunks()`` returns a fresh iterator of
        ``(t_s, x_mm, y_mm, force_n or None)`` arrays, checked already (finite, time never going
        back, from ``start_s`` to ``end_s``); ``force_range_n`` is the lowest and highest force.

        Parameters
        ----------
        open_chunks : callable
            Returns a fresh iterator of ``(t_s, x_mm, y_mm, force_n or None)`` arrays (s, mm, mm, N).
        start_s, end_s : float
            The first and last record's time, s.
        has_force : bool
            Whether the chunks carry a force.
        force_range_n : (float, float), optional
            The lowest and highest force, N.

        Returns
        -------
        RecordedTrajectory

        Raises
        ------
        RenderError
            ``end_s`` not after ``start_s``.

        Examples
        --------
        Two chunks, x = 10 mm a second throughout: between them the finger is interpolated across the gap:

        >>> import numpy as np
        >>> first = (np.array([0.0, 1.0]), np.array([0.0, 10.0]), np.array([5.0, 5.0]), None)
        >>> second = (np.array([2.0, 3.0]), np.array([20.0, 30.0]), np.array([5.0, 5.0]), None)
        >>> path = RecordedTrajectory.streaming(lambda: iter([first, second]), 0.0, 3.0, False)
        >>> path.state([1.5, 2.5]).x_mm.tolist()
        [15.0, 25.0]
        """
        if not end_s > start_s:
            raise RenderError("a trajectory needs records at two different times at least")
        trajectory = cls.__new__(cls)
        trajectory._setup(open_chunks, float(start_s), float(end_s), has_force, force_range_n)
        return trajectory

    def _setup(self, open_chunks, start_s: float, end_s: float, has_force: bool, force_range_n) -> None:
        self._open_chunks = open_chunks
        self.start_s, self.end_s, self.has_force = start_s, end_s, has_force
        self.force_range_n = force_range_n  # (lowest, highest) logged force, N; None when not logged
        self._rewind()

    def _rewind(self) -> None:
        self._chunks = self._open_chunks()
        self._exhausted = False
        self._trimmed = False  # whether rows before the window were dropped
        self._t = self._x = self._y = self._f = np.zeros(0)

    def chunks(self) -> Iterator[Chunk]:
        """The records, chunk by chunk, as ``(t_s, x_mm, y_mm, force_n or None)`` arrays.

        Returns
        -------
        iterator of tuple
            ``(t_s, x_mm, y_mm, force_n or None)`` arrays (s, mm, mm, N).

        Examples
        --------
        A trajectory made of arrays is one chunk:

        >>> chunks = list(RecordedTrajectory([0.0, 1.0], [0.0, 10.0], [5.0, 5.0]).chunks())
        >>> len(chunks), chunks[0][1].tolist(), chunks[0][3]
        (1, [0.0, 10.0], None)
        """
        return self._open_chunks()

    def records(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Every record at once, ``(t_s, x_mm, y_mm, force_n or None)``: the whole log in memory, for
        small logs and tests (rendering and ``play`` stream it instead).

        Returns
        -------
        (numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray or None)
            Times (s), x and y (mm), forces (N) or None.

        Examples
        --------
        >>> path = RecordedTrajectory([0.0, 0.5, 1.0], [0.0, 5.0, 10.0], [5.0, 5.0, 5.0], [0.2, 0.4, 0.6])
        >>> t, x, y, force = path.records()
        >>> t.tolist(), force.tolist()
        ([0.0, 0.5, 1.0], [0.2, 0.4, 0.6])
        """
        parts = list(self.chunks())
        t, x, y = (np.concatenate([part[k] for part in parts]) for k in range(3))
        return t, x, y, np.concatenate([part[3] for part in parts]) if self.has_force else None

    t_s = property(lambda self: self.records()[0], doc="Every record's time, s (reads the whole log).")
    x_mm = property(lambda self: self.records()[1], doc="Every record's x, mm (reads the whole log).")
    y_mm = property(lambda self: self.records()[2], doc="Every record's y, mm (reads the whole log).")
    force_n = property(lambda self: self.records()[3] if self.has_force else None,
                       doc="Every record's force, N, or None (reads the whole log).")

    def _extend(self, high: float) -> None:
        """Read chunks until the window holds MARGIN + 1 records after ``high`` (or the end)."""
        pending = []
        beyond = np.count_nonzero(self._t > high)
        while not self._exhausted and beyond <= self.MARGIN:
            try:
                t, x, y, force = next(self._chunks)
            except StopIteration:
                self._exhausted = True
                break
            pending.append((t, x, y, np.full(len(t), np.nan) if force is None else force))
            beyond += np.count_nonzero(t > high)
        if not pending:
            return
        columns = [np.concatenate([held, *(chunk[k] for chunk in pending)])  # one copy, however many chunks
                   for k, held in enumerate((self._t, self._x, self._y, self._f))]
        keep = np.ones(len(columns[0]), dtype=bool)
        keep[:-1] = columns[0][1:] != columns[0][:-1]  # an instant logged twice: the last row stands
        if not keep.all():
            columns = [column[keep] for column in columns]
        self._t, self._x, self._y, self._f = columns

    def _cover(self, low: float, high: float) -> int:
        """Hold the records around [low, high], from the window's start; return where they end in it."""
        if self._trimmed and low < self._t[0]:
            self._rewind()
        for _ in range(2):  # drop what lies behind (the window moves forward), before and after reading on
            first = max(int(np.searchsorted(self._t, low, side="right")) - 1 - self.MARGIN, 0)
            if first > 0:
                self._t, self._x, self._y, self._f = (a[first:].copy() for a in (self._t, self._x, self._y, self._f))
                self._trimmed = True
            self._extend(high)
        return min(int(np.searchsorted(self._t, high, side="left")) + 1 + self.MARGIN, len(self._t))

    def state(self, times_s: ArrayLike, out: tuple[np.ndarray, np.ndarray] | None = None) -> FingerState:
        """Where the finger is at each time (s), whether it touches, and its force (NaN: not logged).
        ``out``: two arrays (x, y) of the times' length to fill instead of new ones.

        Parameters
        ----------
        times_s : array_like
            Times (s).
        out : (numpy.ndarray, numpy.ndarray), optional
            Arrays (x, y) to fill.

        Returns
        -------
        FingerState

        Examples
        --------
        >>> path = RecordedTrajectory([0.0, 1.0], [0.0, 10.0], [5.0, 5.0])
        >>> state = path.state([0.0, 0.5, 1.5])
        >>> state.x_mm.tolist(), state.down.tolist()                    # mm; lifted after the last record
        ([0.0, 5.0, 10.0], [True, True, False])
        """
        requested = np.asarray(times_s, dtype=float)
        if requested.size == 0:
            return FingerState(requested, requested, requested, np.zeros(requested.shape, dtype=bool))
        low, high = (min(max(float(end), self.start_s), self.end_s) for end in (requested.min(), requested.max()))
        last = self._cover(low, high)
        x, y = out if out is not None else (np.empty(requested.shape), np.empty(requested.shape))
        force, down = np.empty(requested.shape), np.empty(requested.shape, dtype=bool)
        kernels.recorded_path(self._t[:last], self._x[:last], self._y[:last], self._f[:last], self.has_force,
                              self.start_s, self.end_s, requested.reshape(-1), x.reshape(-1), y.reshape(-1),
                              force.reshape(-1), down.reshape(-1))  # one compiled pass
        return FingerState(x, y, force, down)


class LiveTrajectory:
    """Touch reports pushed from any thread; predicted at the instants the renderer asks for.

    Parameters
    ----------
    predictor : str
        How the finger is predicted between and past reports (``lsq``: a line through the latest reports).
    lookahead_s : float
        How far ahead the renderer asks, s.
    fit_reports : int
        Reports the line is fitted through.
    fit_window_s : float
        The oldest report fitted, s back.
    max_extrapolation_s : float
        The furthest past the last report it predicts, s.

    Examples
    --------
    Reports on a line (x = 10 + 100 t mm): the prediction 50 ms past the last is on it, within the furthest
    extrapolation allowed:

    >>> import numpy as np
    >>> live = LiveTrajectory()
    >>> for k in range(10):
    ...     live.push(0.01 * k, 10.0 + k, 5.0)
    >>> live.state(np.array([0.09, 0.14])).x_mm.round(6).tolist()
    [19.0, 24.0]
    """

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

        The prediction line is fitted here, on whichever thread calls ``push``, in plain floats (a handful
        of reports: 5–10 µs a report on this machine), and swapped in whole, so :meth:`state` reads it
        without the lock. In the engine the thread that pushes is the block thread itself, as it drains
        the touch ring before each block (at 60–240 reports a second: one report every few blocks), which
        keeps the engine to one real-time thread and leaves the lock uncontended; an app that renders in
        its own process pushes from its UI thread. See ``BlockSource.pull`` for the real-time contract.

        Parameters
        ----------
        t_s : float
            When, perf_counter s.
        x_mm, y_mm : float
            Where, mm.
        force_n : float, optional
            N; None: not measured.
        down : bool
            False lifts the finger.

        Examples
        --------
        >>> import numpy as np
        >>> live = LiveTrajectory()
        >>> live.push(0.0, 10.0, 5.0)
        >>> live.state(np.array([0.0])).down
        True
        >>> live.push(0.01, 10.0, 5.0, down=False)
        >>> live.state(np.array([0.02])).down, live.reports
        (False, 2)
        """
        with self._lock:
            self.reports += 1
            if not down:
                self._down = False
                if self._fit is not None:
                    self._fit = self._fit._replace(down=False, vx=0.0, vy=0.0)
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
        t0 = recent[0][0]  # times relative to the first: the sums stay well conditioned
        st = sx = sy = stt = stx = sty = 0.0
        for t, x, y, _ in recent:  # one pass over a handful of reports, in plain floats
            t -= t0
            st += t
            sx += x
            sy += y
            stt += t * t
            stx += t * x
            sty += t * y
        mean_t, mean_x, mean_y = st / count, sx / count, sy / count
        spread = stt - st * mean_t
        vx = (stx - st * mean_x) / spread
        vy = (sty - st * mean_y) / spread
        mean_t += t0
        speed = math.hypot(vx, vy)
        if speed > MAX_SPEED_MM_S:  # no finger explores this fast: a glitch, not motion
            vx, vy = vx * MAX_SPEED_MM_S / speed, vy * MAX_SPEED_MM_S / speed
        return _Fit(mean_t, mean_x, mean_y, vx, vy, last[0], force, True)

    def state(self, times_s, out=None) -> FingerState:
        """The finger at ``times_s``; ``out``: two preallocated arrays (x, y) to fill (no allocation).

        Parameters
        ----------
        times_s : array_like
            Times, perf_counter s.
        out : (numpy.ndarray, numpy.ndarray), optional
            Arrays (x, y) of the times' length to fill.

        Returns
        -------
        FingerState

        Examples
        --------
        Before any report the finger is not on the plate; one report holds it there:

        >>> import numpy as np
        >>> live = LiveTrajectory()
        >>> live.state(np.array([0.0])).down
        False
        >>> live.push(1.0, 12.0, 7.0)
        >>> state = live.state(np.array([1.0]))
        >>> state.down, state.x_mm.tolist(), state.y_mm.tolist()
        (True, [12.0], [7.0])
        """
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
        latest = fit.t_last + self.max_extrapolation_s
        kernels.line_path(times.reshape(-1), latest, self.lookahead_s - fit.t_ref, fit.vx, fit.vy, fit.x_ref,
                          fit.y_ref, x.reshape(-1), y.reshape(-1))  # one compiled pass: every block asks
        moving = times[-1] <= latest if times.ndim else True
        velocity = (fit.vx, fit.vy) if moving else (0.0, 0.0)
        return FingerState(x, y, fit.force_n, fit.down, velocity)
