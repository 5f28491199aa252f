"""A friction model from a measured table: ratio against amplitude at one or more forces."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.measurements import Measurements, check_describes_reduction
from ultraglide.render.physics.model_base import (
    DEFAULT_FORCE_N,
    MAX_FORCE_N,
    MIN_FORCE_N,
    RATIO_GRID_POINTS,
    FrictionModel,
    UniformTable,
    check_amplitude,
)

REACHES_ZERO = 1e-6  # a table whose lowest ratio is at most this reaches 0 (its points' interpolation rounds)


class TableModel(FrictionModel):
    """Measured points, interpolated monotonically (PCHIP) in amplitude and linearly in force.

    Points that rise with amplitude (measurement noise) are first made non-increasing by isotonic
    regression, per force. With several forces, amplitudes for a ratio are interpolated linearly
    between the neighbouring forces and held beyond the ends; the forward model is the exact
    inverse of that, found by bisection. The reachable range ends at the largest measured amplitude.

    Parameters
    ----------
    data : Measurements
        The measured points (:func:`render.physics.measurements.read_measurements`): amplitudes (µm p-p), ratios,
        and the forces (N) when measured at several; two amplitudes or more at each force.

    Raises
    ------
    ModelError
        Points that never fall below a ratio of 1, or a force with fewer than two amplitudes.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> points = Measurements(np.array([0.0, 2.0, 4.0, 6.0]), np.array([1.0, 0.8, 0.5, 0.3]), None, "bench")
    >>> model = TableModel(points)
    >>> model
    TableModel('bench', force 0.5 N)
    >>> model.relative_friction([0.0, 2.0, 4.0]).round(3)                 # through the points
    array([1. , 0.8, 0.5])
    >>> model.max_amplitude_um_pp                                         # µm p-p, the largest measured
    6.0
    """

    name = "table"

    def warm_up(self) -> None:
        """Load the table's compiled inverse (numba's cache) before a real-time block needs it.

        Examples
        --------
        Amplitude is linear in ratio between the points: 0.65, half way from 0.8 (2 µm) to 0.5 (4 µm), needs 3 µm:

        >>> import numpy as np
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> points = Measurements(np.array([0.0, 2.0, 4.0, 6.0]), np.array([1.0, 0.8, 0.5, 0.3]), None, "bench")
        >>> model = TableModel(points)
        >>> model.warm_up()
        >>> model.amplitude_um_pp(np.array([0.65]), 0.5).amplitude_um_pp.round(6).tolist()
        [3.0]
        """
        kernels.warm_up_table()

    def __init__(self, data: Measurements):
        from scipy.interpolate import PchipInterpolator  # imported here: scipy.interpolate takes 0.3-0.8 s to load
        from scipy.optimize import isotonic_regression  # imported here: it loads all of scipy.optimize

        check_describes_reduction(data, data.source)
        if data.speed_mm_s is not None and len(np.unique(data.speed_mm_s)) > 1:
            raise ModelError(f"{data.source}: a table holds one sliding speed, these points have "
                             f"{len(np.unique(data.speed_mm_s))}; keep one speed's points, or fit a model and its "
                             "speed law to them (ultraglide calibrate)")
        forces = data.force_n if data.force_n is not None else np.full(len(data), DEFAULT_FORCE_N)
        self.source = data.source
        self.forces = np.unique(forces)
        self.max_amplitude_um_pp = float(min(
            data.amplitude_um_pp[forces == f].max() for f in self.forces
        ))
        rows = []
        self.floors = []
        for force in self.forces:
            pick = forces == force
            amplitude = data.amplitude_um_pp[pick]
            if len(np.unique(amplitude)) < 2:
                raise ModelError(f"{self.source}: at {force:g} N there must be two amplitudes or more")
            order = np.argsort(amplitude)
            amplitude, ratio = amplitude[order], data.relative_friction[pick][order]
            amplitude, which = np.unique(amplitude, return_inverse=True)  # repeats at one amplitude: their mean
            ratio = np.bincount(which, weights=ratio) / np.bincount(which)
            ratio = np.minimum(isotonic_regression(ratio, increasing=False).x, 1.0)
            curve = PchipInterpolator(amplitude, ratio, extrapolate=False)
            fine = np.linspace(0.0, self.max_amplitude_um_pp, 2049)
            fine_ratio = curve(np.clip(fine, amplitude[0], amplitude[-1]))
            fine_ratio = np.minimum.accumulate(np.minimum(fine_ratio, 1.0))
            self.floors.append(fine_ratio[-1])
            rows.append(fine_ratio)
        if not min(self.floors) < 1.0 - 1e-6:  # no force's points, repeats averaged, fall below 1
            raise ModelError(f"{self.source}: relative_friction never falls below 1 at any force once repeated "
                             "amplitudes are averaged: a flat table cannot be inverted; measure amplitudes where "
                             "friction falls")
        self.floor = float(max(self.floors))
        grid = np.linspace(min(self.floors), 1.0, RATIO_GRID_POINTS)
        fine = np.linspace(0.0, self.max_amplitude_um_pp, 2049)
        inverse = np.array([np.interp(grid, r[::-1], fine[::-1]) for r in rows])
        self._table = UniformTable(grid[0], 1.0, inverse)

    def _row_weights(self, force_n):
        force = np.clip(np.asarray(force_n, dtype=float), self.forces[0], self.forces[-1])
        upper = np.clip(np.searchsorted(self.forces, force), 1, max(len(self.forces) - 1, 1))
        if len(self.forces) == 1:
            return np.zeros_like(force, dtype=np.intp), np.zeros_like(force)
        lower = upper - 1
        weight = (force - self.forces[lower]) / (self.forces[upper] - self.forces[lower])
        return lower, weight

    def _amplitude_in_reach(self, ratio, force_n):
        if len(self.forces) == 1:
            return self._table(ratio)
        lower, weight = self._row_weights(force_n)
        shape = np.broadcast(ratio, lower).shape
        ratio, lower, weight = (np.broadcast_to(x, shape).ravel() for x in (ratio, lower, weight))
        low = np.empty(len(ratio))
        high = np.empty(len(ratio))
        for row in np.unique(lower):  # a handful of force rows, not samples
            pick = lower == row
            low[pick] = self._table(ratio[pick], int(row))
            high[pick] = self._table(ratio[pick], int(row) + 1)
        return ((1.0 - weight) * low + weight * high).reshape(shape)

    compiled = True

    def _inverse_one_force(self, ratio, force_n, limit, out) -> int:
        table = self._table
        return kernels.inverse_table_force(ratio, force_n, limit, table.start, table.scale, table.values,
                                           table.slopes, self.forces, out)

    def _inverse_forces(self, ratio, force_n, limit, out) -> int:
        table = self._table
        return kernels.inverse_table_forces(ratio, force_n, limit, table.start, table.scale, table.values,
                                            table.slopes, self.forces, out)

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """The exact inverse of the tabulated amplitudes, by bisection; see :meth:`FrictionModel.relative_friction`.
        Amplitudes beyond the largest measured one are held there.

        Parameters
        ----------
        amplitude_um_pp : array_like
            Vibration amplitude, µm p-p.
        force_n : array_like
            Normal force, N.

        Returns
        -------
        numpy.ndarray
            mu / mu0.

        Examples
        --------
        Half way between the points at 2 µm (0.8) and 4 µm (0.5):

        >>> import numpy as np
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> points = Measurements(np.array([0.0, 2.0, 4.0, 6.0]), np.array([1.0, 0.8, 0.5, 0.3]), None, "bench")
        >>> model = TableModel(points)
        >>> model.relative_friction([3.0]).round(6).tolist()
        [0.65]
        """
        self._checked_force(force_n)
        amplitude = np.asarray(amplitude_um_pp, dtype=float)
        check_amplitude(amplitude)
        shape = np.broadcast(amplitude, np.asarray(force_n)).shape
        low = np.full(shape, float(self._table.start))
        high = np.ones(shape)
        target = np.broadcast_to(np.minimum(amplitude, self.max_amplitude_um_pp), shape)
        # bisection for the largest ratio whose amplitude reaches the target: where a force's curve
        # ends above the lowest floor, its inverse holds the end amplitude, and the answer is its floor
        for _ in range(48):
            middle = 0.5 * (low + high)
            above = self._amplitude_in_reach(middle, force_n) >= target
            low = np.where(above, middle, low)
            high = np.where(above, high, middle)
        return 0.5 * (low + high)

    def force_law(self) -> str:
        """None when measured at one force; else amplitudes linear in force between the measured forces.

        Returns
        -------
        str

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> points = Measurements(np.array([0.0, 2.0, 4.0, 6.0]), np.array([1.0, 0.8, 0.5, 0.3]), None, "bench")
        >>> model = TableModel(points)
        >>> model.force_law()
        'none: measured at 0.5 N only, the same curve at every force'
        """
        if len(self.forces) == 1:
            return f"none: measured at {self.forces[0]:g} N only, the same curve at every force"
        return f"measured at {len(self.forces)} forces, amplitudes linear in force between them"

    def _own_force_range_n(self) -> tuple[float, float]:
        if len(self.forces) == 1:
            return (MIN_FORCE_N, MAX_FORCE_N)
        return (float(self.forces[0]), float(self.forces[-1]))

    def _range_reason(self) -> str:
        return "the forces measured; beyond them the nearest force's curve is held"

    def describe(self) -> str:
        """One line: the file, its forces (N) and its largest amplitude (µm p-p).

        Returns
        -------
        str

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> points = Measurements(np.array([0.0, 2.0, 4.0, 6.0]), np.array([1.0, 0.8, 0.5, 0.3]), None, "bench")
        >>> model = TableModel(points)
        >>> model.describe()
        'table: bench (0.5 N, up to 6 µm p-p)'

        A table whose points fall to 0 says that it reaches 0, as the other models that do say it:

        >>> TableModel(Measurements(np.array([0.0, 3.0, 6.0]), np.array([1.0, 0.4, 0.0]), None, "zero")).describe()
        'table: zero (0.5 N, up to 6 µm p-p), reaches 0 (its points fall to 0), which no measured finger does'
        """
        forces = ", ".join(f"{f:g}" for f in self.forces)
        zero = ", reaches 0 (its points fall to 0), which no measured finger does" \
            if min(self.floors) <= REACHES_ZERO else ""
        return f"table: {self.source} ({forces} N, up to {self.max_amplitude_um_pp:g} µm p-p){zero}"

    def parameters(self) -> dict[str, float | str]:
        """``source``: the file the points came from.

        Returns
        -------
        dict

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> points = Measurements(np.array([0.0, 2.0, 4.0, 6.0]), np.array([1.0, 0.8, 0.5, 0.3]), None, "bench")
        >>> model = TableModel(points)
        >>> model.parameters()
        {'source': 'bench'}
        """
        return {"source": self.source}

    def __repr__(self) -> str:
        """``TableModel('finger.csv', forces 0.2–1 N)``: where its points came from."""
        forces = (f"force {self.forces[0]:g} N" if len(self.forces) == 1
                  else f"forces {self.forces[0]:g}–{self.forces[-1]:g} N")
        return f"TableModel({self.source!r}, {forces})"
