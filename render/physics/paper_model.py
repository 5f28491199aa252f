"""The paper's ridge model as a friction model (eqs. 1-9): amplitude and force to friction ratio, and back."""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.fingerprint import (
    MM2_TO_M2,
    FingerParams,
    area_saturation_force_n,
    detach_amplitude_um_pp,
)
from ultraglide.render.physics.model_base import (
    CEILING_UM_PP,
    DEFAULT_FORCE_N,
    MAX_FORCE_N,
    MIN_FORCE_N,
    RATIO_GRID_POINTS,
    FrictionModel,
    UniformTable,
    check_amplitude,
    clip_force,
)
from ultraglide.render.physics.normal_contact import relative_friction_of_u


@functools.lru_cache(maxsize=32)
def _tables(params: FingerParams, u_max: float, nodes: int) -> tuple[np.ndarray, np.ndarray, UniformTable]:
    """The ratio over u (``nodes`` points up to ``u_max``, made monotone) and its inverse for ``params``: 40 ms of
    CPU, and the same finger's model is made again and again (every command's default, a fit's repeated
    candidates). Models of the same finger share the arrays: nothing writes to them (left writable: a read-only
    array is another type to the compiled kernels that read them, compiled again)."""
    u_nodes = u_max * np.linspace(0.0, 1.0, nodes) ** 2
    ratio = relative_friction_of_u(u_nodes, params, phase_points=192, ring_nodes=32)
    ratio_nodes = np.minimum.accumulate(ratio)  # guard monotonicity against rounding
    ratio_grid = np.linspace(ratio_nodes[-1], 1.0, RATIO_GRID_POINTS)
    # the inverse of a flat stretch is its smallest amplitude: interp on reversed nodes
    u_of_ratio = np.interp(ratio_grid, ratio_nodes[::-1], u_nodes[::-1])
    return u_nodes, ratio_nodes, UniformTable(ratio_grid[0], 1.0, u_of_ratio)


class PaperModel(FrictionModel):
    """The seed paper's non-Coulombic bed-of-springs model (section IV), tabulated.

    The ratio depends on amplitude and force only through u = a_pp / detach_amplitude_um_pp(F)
    (see :mod:`render.physics.normal_contact`), so one table over u serves every force. The detachment
    amplitude scales as F^(1 - area_exponent) (F^(1/3) with the paper's A = k F^(2/3)). It predicts
    a modest reduction (to about 0.72 at 10 µm and 0.5 N) and never full levitation.

    Parameters
    ----------
    params : FingerParams
        The finger (:class:`render.physics.fingerprint.FingerParams`): the paper's Table I by default.

    Examples
    --------
    >>> model = PaperModel()
    >>> model.relative_friction([0.0, 10.0], force_n=0.5).round(2)          # µm p-p in, mu/mu0 out
    array([1.  , 0.72])
    >>> round(float(model.amplitude_um_pp(0.8, force_n=0.5).amplitude_um_pp), 2)   # µm p-p for 0.8
    4.67
    """

    name = "paper"
    U_NODES = 384

    def warm_up(self) -> None:
        """Load the compiled inverse over u (numba's cache) before a real-time block needs it.

        Examples
        --------
        >>> import numpy as np
        >>> model = PaperModel()
        >>> model.warm_up()
        >>> model.amplitude_um_pp(np.array([1.0]), 0.5).amplitude_um_pp.tolist()      # at rest: no vibration
        [0.0]
        """
        kernels.warm_up_uniform()

    def __init__(self, params: FingerParams = FingerParams()):
        self.params = params
        self._detach_exponent = 1.0 - params.area_exponent
        # eq. (6) without the area's cap: 2 F / k_n at 1 N, k_n = E k (1 N)^(2/3) / h
        self._detach_at_1n = 2.0e6 * params.ridge_height_m / (
            params.youngs_modulus_pa * params.area_coefficient_mm2 * MM2_TO_M2)
        self._saturation_n = area_saturation_force_n(params)
        # the table covers every amplitude up to the ceiling at every force in range
        smallest_detach = float(np.min(self._detach_um_pp(np.array([MIN_FORCE_N, MAX_FORCE_N]))))
        u_max = max(CEILING_UM_PP / smallest_detach, 4.0)
        self.u_nodes, self.ratio_nodes, self._u_table = _tables(params, u_max, self.U_NODES)

    def _detach_um_pp(self, force_n, clip: bool = True):
        """W_c (µm p-p) at each force: ∝ F^(1 - area exponent) until the area reaches a fingertip's, then ∝ F.
        Forces are clipped to the models' range unless ``clip`` is False."""
        force = clip_force(force_n) if clip else np.asarray(force_n, dtype=float)
        return (self._detach_at_1n * np.power(np.minimum(force, self._saturation_n), self._detach_exponent)
                * np.maximum(force / self._saturation_n, 1.0))

    def force_law(self) -> str:
        """W_c ∝ F^(1 - area exponent) (eqs. 1, 3, 6), ∝ F above the force where the contact is a fingertip's.

        Returns
        -------
        str

        Examples
        --------
        >>> PaperModel().force_law()
        "W_c ∝ F^0.333 from eqs. (1), (3), (6), ∝ F above 2.44 N where the area is a fingertip's"
        """
        return (f"W_c ∝ F^{self._detach_exponent:.3g} from eqs. (1), (3), (6), ∝ F above "
                f"{self._saturation_n:.3g} N where the area is a fingertip's")

    def _own_force_range_n(self) -> tuple[float, float]:
        return (MIN_FORCE_N, min(self._saturation_n, MAX_FORCE_N))

    def _range_reason(self) -> str:
        return (f"above {self._saturation_n:.3g} N eq. (3)'s contact area would exceed a fingertip's pad, "
                f"{self.params.max_contact_area_mm2:g} mm², and is held there")

    @staticmethod
    def detach_um_pp_for(params: FingerParams, force_n):
        """Detachment amplitude (µm p-p) at each force, forces clipped to the models' range.

        Parameters
        ----------
        params : FingerParams
            The finger.
        force_n : array_like
            Normal force (N).

        Returns
        -------
        numpy.ndarray or float
            µm p-p.

        Examples
        --------
        >>> round(float(PaperModel.detach_um_pp_for(FingerParams(), 0.15)), 2)      # the paper's worked example
        1.15
        """
        return detach_amplitude_um_pp(clip_force(force_n), params)

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """The ratio from the table over u = a_pp / W_c(F); see :meth:`FrictionModel.relative_friction`.

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
        The ratio depends on a_pp / W_c(F) alone, and W_c ∝ F^(1/3) below 2.44 N: twice the force needs 2^(1/3) times
        the amplitude for the same ratio:

        >>> import numpy as np
        >>> model = PaperModel()
        >>> bool(np.allclose(model.relative_friction([2.0], 0.5), model.relative_friction([2.0 * 2 ** (1 / 3)], 1.0)))
        True
        >>> model.relative_friction([0.0], 0.5).tolist()
        [1.0]
        """
        self._checked_force(force_n)
        amplitude = np.asarray(amplitude_um_pp, dtype=float)
        check_amplitude(amplitude)
        return np.interp(amplitude / self._detach_um_pp(force_n), self.u_nodes, self.ratio_nodes)

    def _amplitude_in_reach(self, ratio, force_n):
        return self._u_table(ratio) * self._detach_um_pp(force_n)

    def _detach_at(self, force_n) -> float:
        """The detachment amplitude at one force, remembered for the last force (the live case)."""
        force = float(force_n)
        cached = getattr(self, "_detach_cache", None)
        if cached is None or cached[0] != force:
            cached = self._detach_cache = (force, float(self._detach_um_pp(force)))
        return cached[1]

    compiled = True

    def _inverse_one_force(self, ratio, force_n, limit, out) -> int:
        table = self._u_table
        return kernels.inverse_uniform(ratio, self._floor(force_n, limit), limit, table.start, table.scale,
                                       table.values, table.slopes, self._detach_at(force_n), out)

    def _inverse_forces(self, ratio, force_n, limit, out) -> int:
        table = self._u_table
        return kernels.inverse_uniform_forces(ratio, force_n, limit, table.start, table.scale, table.values,
                                              table.slopes, self._detach_at_1n, self._detach_exponent,
                                              self._saturation_n, MIN_FORCE_N, MAX_FORCE_N, out)

    def describe(self) -> str:
        """One line: the model and its finger's parameters (E in MPa, n, the area exponent, the contact).

        Returns
        -------
        str

        Examples
        --------
        >>> PaperModel().describe()
        'paper: ridge springs with non-Coulombic friction (E = 1 MPa, n = 0.667, A ∝ F^0.667, hertz contact)'
        """
        p = self.params
        return (
            f"paper: ridge springs with non-Coulombic friction (E = {p.youngs_modulus_pa / 1e6:g} MPa, "
            f"n = {p.friction_exponent:.3g}, A ∝ F^{p.area_exponent:.3g}, {p.contact} contact)"
        )

    def parameters(self) -> dict[str, float | str]:
        """The finger's fitted parameters: ``youngs_modulus_pa`` (Pa), ``friction_exponent``, ``area_exponent``.

        Returns
        -------
        dict

        Examples
        --------
        >>> PaperModel().parameters()["youngs_modulus_pa"]                   # Pa: the paper's 1 MPa
        1000000.0
        """
        p = self.params
        return {
            "youngs_modulus_pa": p.youngs_modulus_pa,
            "friction_exponent": p.friction_exponent,
            "area_exponent": p.area_exponent,
        }

    def __repr__(self) -> str:
        """``PaperModel()`` with the paper's parameters, else ``PaperModel(FingerParams(...))`` with those that
        differ."""
        changed = {k: v for k, v in vars(self.params).items() if v != getattr(FingerParams(), k)}
        inner = f"FingerParams({', '.join(f'{k}={v!r}' for k, v in changed.items())})" if changed else ""
        return f"PaperModel({inner})"
