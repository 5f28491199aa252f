"""Synthetic finger paths for export and tests: straight swipes, circles, zig-zags.

Each is analytic (constant memory whatever its duration) and answers ``state(times_s)`` like a
recorded trajectory. Positions in mm, speed in mm/s, the finger touching from 0 to ``duration_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render import kernels
from ultraglide.render.errors import RenderError
from ultraglide.render.trajectory import FingerState

PATH_KINDS = ("straight", "circle", "zigzag")


@dataclass(frozen=True)
class SwipePath:
    """A finger's path at constant speed: a straight swipe, a circle or a zig-zag.

    Parameters
    ----------
    kind : {"straight", "circle", "zigzag"}
        The path's shape.
    speed_mm_s : float
        The finger's speed along the path (mm/s).
    duration_s : float
        How long the finger touches (s), from 0.
    start_mm : (float, float), optional
        Where the finger lands (mm from the texture's top-left corner, x right, y down). None (the
        default): where :meth:`across` starts it on the texture being rendered (a straight swipe at
        10 % of the width across the middle; a circle centred; a zig-zag's passes centred), placed by
        the renderer (:meth:`placed_on`).
    direction_deg : float
        The heading of a straight swipe or a zig-zag's passes (degrees, 0 = left to right, 90 = down).
    radius_mm : float
        A circle's radius (mm).
    width_mm, pitch_mm : float
        A zig-zag's pass length and the distance between passes (mm).
    force_n : float, optional
        The finger's force (N); None: the renderer's default force.

    Raises
    ------
    RenderError
        A kind not listed, or a speed, duration or size that is not a positive number.

    Examples
    --------
    >>> path = SwipePath(speed_mm_s=50.0, duration_s=0.2, start_mm=(5.0, 10.0))
    >>> state = path.state([0.0, 0.1, 0.3])
    >>> state.x_mm.tolist(), state.down.tolist()        # 5 mm/s·0.1 s further; lifted after 0.2 s
    ([5.0, 10.0, 15.0], [True, True, False])
    """

    kind: str = "straight"
    speed_mm_s: float = 100.0
    duration_s: float = 1.0
    start_mm: tuple[float, float] | None = None
    direction_deg: float = 0.0
    radius_mm: float = 15.0  # circle
    width_mm: float = 40.0  # zigzag: length of each pass
    pitch_mm: float = 3.0  # zigzag: distance between passes
    force_n: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in PATH_KINDS:
            raise RenderError(f"path must be one of {', '.join(PATH_KINDS)}, got {self.kind!r}")
        for name in ("speed_mm_s", "duration_s", "radius_mm", "width_mm", "pitch_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise RenderError(f"{name} must be a positive number, got {value}")
        if self.force_n is not None and not self.force_n > 0:
            raise RenderError(f"force must be positive, got {self.force_n} N")

    start_s = 0.0

    @classmethod
    def across(cls, width_mm: float, height_mm: float, kind: str = "straight", speed_mm_s: float = 100.0,
               duration_s: float = 5.0, start_mm: tuple[float, float] | None = None, direction_deg: float = 0.0,
               radius_mm: float = 15.0, width_of_pass_mm: float = 40.0, force_n: float | None = None) -> SwipePath:
        """The default swipe over a texture of ``width_mm`` × ``height_mm``: a straight one starts at 10 % of the
        width and crosses the middle; a circle is centred; a zig-zag starts at a fifth of the height with its
        passes centred. ``start_mm`` overrides where it starts (mm from the texture's top-left corner).

        Parameters
        ----------
        width_mm, height_mm : float
            The texture's size (mm).
        kind : {"straight", "circle", "zigzag"}
            The path's shape.
        speed_mm_s : float
            The finger's speed (mm/s).
        duration_s : float
            How long the finger touches (s).
        start_mm : (float, float), optional
            Where it starts (mm).
        direction_deg : float
            A straight path's heading (degrees; 0: to the right).
        radius_mm : float
            A circle's radius (mm).
        width_of_pass_mm : float
            A zig-zag's pass width (mm).
        force_n : float, optional
            The finger's force (N); the renderer's default when None.

        Returns
        -------
        SwipePath

        Examples
        --------
        >>> SwipePath.across(80.0, 50.0).start_mm, SwipePath.across(80.0, 50.0, kind="circle").start_mm   # mm
        ((8.0, 25.0), (25.0, 25.0))
        """
        if start_mm is None:
            if kind == "circle":
                start_mm = (width_mm / 2 - radius_mm, height_mm / 2)
            elif kind == "zigzag":
                start_mm = (max(0.0, (width_mm - width_of_pass_mm) / 2), height_mm * 0.2)
            else:
                start_mm = (width_mm * 0.1, height_mm / 2)
        return cls(kind, speed_mm_s, duration_s, start_mm, direction_deg, radius_mm=radius_mm,
                   width_mm=width_of_pass_mm, force_n=force_n)

    def placed_on(self, width_mm: float, height_mm: float) -> SwipePath:
        """This path with its start chosen for a texture of ``width_mm`` × ``height_mm`` (mm) when it has none
        (as :meth:`across` chooses it); a path with a start is returned as it is.

        Parameters
        ----------
        width_mm, height_mm : float
            The texture's size (mm).

        Returns
        -------
        SwipePath

        Examples
        --------
        >>> SwipePath(duration_s=0.5).placed_on(80.0, 50.0).start_mm
        (8.0, 25.0)
        """
        if self.start_mm is not None:
            return self
        placed = SwipePath.across(width_mm, height_mm, self.kind, radius_mm=self.radius_mm,
                                  width_of_pass_mm=self.width_mm, speed_mm_s=self.speed_mm_s,
                                  duration_s=self.duration_s)
        return replace(self, start_mm=placed.start_mm)

    @property
    def end_s(self) -> float:
        """When the finger lifts (s): the path's duration.

        Examples
        --------
        >>> SwipePath(duration_s=0.5).end_s
        0.5
        """
        return self.duration_s

    def state(self, times_s: ArrayLike, out: tuple[np.ndarray, np.ndarray] | None = None) -> FingerState:
        """Where the finger is at each time (s from the swipe's start), and whether it touches. ``out``: two
        one-dimensional arrays (x, y) of the times' length to fill instead of new ones.

        Parameters
        ----------
        times_s : array_like
            Times (s) from the swipe's start.
        out : (numpy.ndarray, numpy.ndarray), optional
            Arrays (x, y) to fill.

        Returns
        -------
        FingerState
            ``x_mm``, ``y_mm`` (mm), ``down`` and ``force_n`` at each time.

        Raises
        ------
        RenderError
            A path with no start (the renderer places one on its texture).

        Examples
        --------
        >>> state = SwipePath.across(80.0, 50.0, speed_mm_s=100.0, duration_s=0.5).state([0.0, 0.25, 0.6])
        >>> state.x_mm.tolist(), state.down.tolist()                    # 100 mm/s from 8 mm; lifted after 0.5 s
        ([8.0, 33.0, 58.0], [True, True, False])
        """
        times = np.asarray(times_s, dtype=float)
        flat = times.reshape(-1)
        x, y = out if out is not None else (np.empty(flat.shape), np.empty(flat.shape))
        down = np.empty(flat.shape, dtype=bool)
        if self.start_mm is None:
            raise RenderError("this path has no start: give start_mm=(x, y) in mm, or render it (the renderer "
                              "places it on its texture)")
        heading = math.radians(self.direction_deg)
        x0, y0 = self.start_mm
        kernels.swipe_path(PATH_KINDS.index(self.kind), flat, self.duration_s, self.speed_mm_s, float(x0), float(y0),
                           math.cos(heading), math.sin(heading), self.radius_mm, self.width_mm, self.pitch_mm,
                           x, y, down)
        force = math.nan if self.force_n is None else float(self.force_n)
        return FingerState(x.reshape(times.shape), y.reshape(times.shape), force, down.reshape(times.shape))
