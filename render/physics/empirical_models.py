"""The empirical friction laws: the stretched exponential with a force exponent and a floor, and its
exponential special case (Monnoyer et al. 2018)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import (
    area_saturation_force_n,
)
from ultraglide.render.physics.model_base import (
    DEFAULT_FORCE_N,
    MAX_FORCE_N,
    MIN_FORCE_N,
    FrictionModel,
    check_amplitude,
    clip_force,
    remembered,
)

REFERENCE_FORCE_N = 0.5  # the force at which a stretched model's scale is stated
MONNOYER_TAU_UM_ZP = 1.32  # Monnoyer et al. 2018, zero-to-peak
MONNOYER_SCALE_UM_PP = 2.0 * np.sqrt(2.0) * MONNOYER_TAU_UM_ZP  # exp(-a²/2tau²) = exp(-(a_pp/scale)²)
# Allowed ranges, the same for the constructor, calibration files and the fit's bounds.
SCALE_RANGE_UM_PP = (0.05, 100.0)
SHAPE_RANGE = (0.3, 8.0)
FORCE_EXPONENT_RANGE = (-2.0, 2.0)


def _in_range(name: str, value: float, allowed: tuple[float, float], unit: str = "") -> float:
    value = float(value)
    if not allowed[0] <= value <= allowed[1]:
        raise ModelError(f"{name} must lie in [{allowed[0]:g}, {allowed[1]:g}]{unit}, got {value}")
    return value


RESIDUAL_RANGE = (0.0, 0.9)  # a floor of friction vibration does not remove, as a share of friction at rest
# The default model's floor: the mean ratio measured at full amplitude, 6 µm p-p at 29 kHz, across people (0.02-0.30
# from one person to another): Wiertlewski, Fenton Friesen and Colgate (PNAS 2016); see sources.FIGURES "floor_mean"
# and "floor_range".
MEASURED_FLOOR = 0.10
ASSUMED_FORCE_EXPONENT = 1.0 / 3.0  # W_c ∝ F^(1/3): eq. (6) with eq. (3)'s A ∝ F^(2/3)


class StretchedExponentialModel(FrictionModel):
    """A force-aware empirical law with a floor: mu/mu0 = d + (1 - d) exp(-(a_pp / s(F))^beta),
    s(F) = s0 (F / 0.5 N)^p.

    ``scale_um_pp`` s0 is the amplitude (µm p-p) at which the reducible part of friction falls to
    1/e at 0.5 N; ``shape`` beta sets how sudden the fall is (2 is Gaussian, Monnoyer's law; below 1
    it starts steeply); ``force_exponent`` p makes harder presses need more vibration;
    ``residual_ratio`` d is the lowest ratio vibration reaches: by default 0.10, the mean measured at full
    amplitude (Wiertlewski, Fenton Friesen and Colgate 2016: 0.10 at 6 µm p-p and 29 kHz, 0.02-0.30
    across people), since measured fingers never reach 0. The form d + (1 - d) exp(...) is Huloux et
    al. (2018)'s f = f0 exp(-a² tau) + d over friction at rest; whether their d is a floor or a bounded
    disturbance varying in time was not checked against their text (docs/physics.md): here it is a
    constant. The other defaults are the law Monnoyer et al. fitted (s0 = 2 sqrt 2 x 1.32 µm = 3.73 µm p-p
    in our units, beta = 2) with p = 1/3,
    **assumed** (no measurement supports it): the force law of the paper's detachment amplitude
    (W_c = 2 F / k_n with A ∝ F^(2/3), eqs. 1, 3, 6), since the bundled curve has a single force. It holds where eq. (3)
    does, up to the force at which the contact area is a fingertip's (2.4 N). A calibration at two
    forces or more fits p and replaces that range by the forces it was fitted on (:attr:`fitted`).
    Any s0 > 0, beta > 0 gives a strictly decreasing curve; values outside the allowed ranges are
    refused.

    Parameters
    ----------
    scale_um_pp : float
        s0 (µm p-p), in [0.05, 100]: where the reducible friction falls to 1/e at 0.5 N; 3.73 by default.
    shape : float
        beta, in [0.3, 8]: 2 is Gaussian.
    force_exponent : float
        p, in [-2, 2]: s(F) = s0 (F / 0.5 N)^p; 1/3 (assumed) by default.
    residual_ratio : float
        d, in [0, 0.9]: the lowest ratio vibration reaches; 0.10 (measured mean) by default.

    Raises
    ------
    ModelError
        A parameter outside its range.

    Examples
    --------
    >>> model = StretchedExponentialModel(scale_um_pp=4.0, shape=2.0, force_exponent=0.0, residual_ratio=0.1)
    >>> model.relative_friction([0.0, 4.0], force_n=0.5).round(4)            # at s0: 0.1 + 0.9 / e
    array([1.    , 0.4311])
    >>> round(float(model.scale_at_um_pp(2.0)), 3)                           # p = 0: the same at every force
    4.0
    """

    name = "stretched"
    default_floor = MEASURED_FLOOR

    def warm_up(self) -> None:
        """Load the stretched law's compiled inverse (numba's cache) before a real-time block needs it.

        Examples
        --------
        The inverse, compiled and loaded: a ratio of d + (1 - d)/e needs the scale s0 at 0.5 N:

        >>> import math
        >>> import numpy as np
        >>> model = StretchedExponentialModel(scale_um_pp=4.0)
        >>> model.warm_up()
        >>> model.amplitude_um_pp(np.array([0.1 + 0.9 / math.e]), 0.5).amplitude_um_pp.round(6).tolist()
        [4.0]
        """
        kernels.warm_up_stretched()

    def __init__(self, scale_um_pp: float = MONNOYER_SCALE_UM_PP, shape: float = 2.0,
                 force_exponent: float = ASSUMED_FORCE_EXPONENT, residual_ratio: float = MEASURED_FLOOR):
        self.scale_um_pp = _in_range("scale_um_pp", scale_um_pp, SCALE_RANGE_UM_PP, " µm p-p")
        self.shape = _in_range("shape", shape, SHAPE_RANGE)
        self.force_exponent = _in_range("force_exponent", force_exponent, FORCE_EXPONENT_RANGE)
        self.residual_ratio = _in_range("residual_ratio", residual_ratio, RESIDUAL_RANGE)

    def force_law(self) -> str:
        """s ∝ F^p, and where p comes from: fitted on the forces of a calibration, or assumed from eq. (6).

        Returns
        -------
        str

        Examples
        --------
        >>> StretchedExponentialModel().force_law()
        "s ∝ F^0.333, assumed from the paper's detachment law W_c ∝ F^(1/3) (eq. 6), not measured"
        >>> StretchedExponentialModel(force_exponent=0.0).force_law()
        'none: the same curve at every force'
        """
        law = f"s ∝ F^{self.force_exponent:.3g}"
        fitted = self.fitted
        if self.force_exponent == 0.0:
            return "none: the same curve at every force" + (f" ({fitted.words()})" if fitted is not None else "")
        if fitted is not None and len(fitted.forces_n) >= 3:
            return f"{law}, fitted on {fitted.words()}"
        if fitted is not None and len(fitted.forces_n) == 2:
            return f"{law}, fitted on two forces ({fitted.words()}): not tested"
        if self.force_exponent == ASSUMED_FORCE_EXPONENT:
            return f"{law}, assumed from the paper's detachment law W_c ∝ F^(1/3) (eq. 6), not measured"
        return f"{law}, as given"

    def _own_force_range_n(self) -> tuple[float, float]:
        return (MIN_FORCE_N, area_saturation_force_n())

    def _range_reason(self) -> str:
        return "eq. (3)'s area law, on which the assumed exponent rests, ends where the area is a fingertip's"

    def scale_at_um_pp(self, force_n: ArrayLike) -> np.ndarray | float:
        """s(F), µm p-p: the amplitude that brings the reducible friction to 1/e at this force.

        Parameters
        ----------
        force_n : array_like
            Normal force (N), clipped to the models' range.

        Returns
        -------
        numpy.ndarray or float
            µm p-p.

        Examples
        --------
        >>> model = StretchedExponentialModel(scale_um_pp=4.0, force_exponent=1 / 3)
        >>> round(float(model.scale_at_um_pp(0.5)), 6), round(float(model.scale_at_um_pp(4.0)), 6)   # × 8^(1/3)
        (4.0, 8.0)
        """
        return self.scale_um_pp * np.power(clip_force(force_n) / REFERENCE_FORCE_N, self.force_exponent)

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """d + (1 - d) exp(-(a_pp / s(F))^beta); see :meth:`FrictionModel.relative_friction`.

        Parameters
        ----------
        amplitude_um_pp : array_like
            Vibration amplitude, µm p-p.
        force_n : array_like
            Normal force, N.

        Returns
        -------
        numpy.ndarray
            mu / mu0, d..1.

        Examples
        --------
        At rest the ratio is 1; at a_pp = s(F) it is d + (1 - d)/e, with s(1 N) = s0 × 2^(1/3):

        >>> import math
        >>> model = StretchedExponentialModel(scale_um_pp=4.0, residual_ratio=0.1)
        >>> ratios = model.relative_friction([0.0, 4.0 * 2 ** (1 / 3)], 1.0)
        >>> ratios.round(6).tolist(), round(0.1 + 0.9 / math.e, 6)
        ([1.0, 0.431091], 0.431091)
        """
        self._checked_force(force_n)
        amplitude = np.asarray(amplitude_um_pp, dtype=float)
        check_amplitude(amplitude)
        falling = np.exp(-np.power(amplitude / self.scale_at_um_pp(force_n), self.shape))
        if self.residual_ratio == 0.0:
            return falling
        return self.residual_ratio + (1.0 - self.residual_ratio) * falling

    def _amplitude_in_reach(self, ratio, force_n):
        ratio = np.asarray(ratio, dtype=float)
        if self.residual_ratio:
            ratio = (ratio - self.residual_ratio) / (1.0 - self.residual_ratio)
        depth = -np.log(ratio) + 0.0  # +0.0: log(1) gives -0.0
        return self.scale_at_um_pp(force_n) * np.power(depth, 1.0 / self.shape)

    def _scale_at(self, force_n) -> float:
        """s(F) at one force as a float, remembered for the last few forces (the live case: a closed loop asks at
        its measured force and at ±5 % of it)."""
        force = float(force_n)
        return remembered(self, "_scales", force, lambda: float(self.scale_at_um_pp(force)))

    compiled = True

    def _inverse_one_force(self, ratio, force_n, limit, out) -> int:
        return kernels.inverse_stretched(ratio, self._floor(force_n, limit), limit, self._scale_at(force_n),
                                         1.0 / self.shape, self.residual_ratio, out)

    def _inverse_forces(self, ratio, force_n, limit, out) -> int:
        return kernels.inverse_stretched_forces(ratio, force_n, limit, self.scale_um_pp, 1.0 / self.shape,
                                                self.force_exponent, REFERENCE_FORCE_N, MIN_FORCE_N, MAX_FORCE_N,
                                                self.residual_ratio, out)

    def _floor_form(self) -> str:
        """The law's floor as written before its exponential: "d + (1 - d) " with a floor, "" without."""
        return "d + (1 - d) " if self.residual_ratio else ""

    def _floor_words(self) -> str:
        if not self.residual_ratio:
            return ", no floor: reaches 0, which no measured finger does"
        if self.residual_ratio == MEASURED_FLOOR:
            return (f", floor d = {self.residual_ratio:.3g} (the mean measured at 6 µm p-p, 0.02-0.30 across people: "
                    f"Wiertlewski et al. 2016)")
        return f", floor d = {self.residual_ratio:.3g}"

    def describe(self) -> str:
        """One line: the law with s0 (µm p-p), p, beta, the floor and the force law.

        Returns
        -------
        str

        Examples
        --------
        The law as written is the one evaluated, its floor d included (0.1 by default):

        >>> StretchedExponentialModel(scale_um_pp=4.0).describe().split(", floor")[0]
        'stretched: mu/mu0 = d + (1 - d) exp(-(a/s)^beta), s = 4 µm p-p x (F/0.5 N)^0.333, beta = 2'
        >>> StretchedExponentialModel(scale_um_pp=4.0, residual_ratio=0.0).describe().split(", ")[0]
        'stretched: mu/mu0 = exp(-(a/s)^beta)'
        """
        return (f"stretched: mu/mu0 = {self._floor_form()}exp(-(a/s)^beta), s = {self.scale_um_pp:.4g} µm p-p x "
                f"(F/0.5 N)^"
                f"{self.force_exponent:.3g}, beta = {self.shape:.3g}{self._floor_words()}; force law: "
                f"{self.force_law()}")

    def parameters(self) -> dict[str, float | str]:
        """``scale_um_pp`` (µm p-p), ``shape``, ``force_exponent``, ``residual_ratio``: what the constructor takes.

        Returns
        -------
        dict

        Examples
        --------
        What the constructor takes back:

        >>> model = StretchedExponentialModel(scale_um_pp=4.0, shape=1.5)
        >>> StretchedExponentialModel(**model.parameters()).parameters() == model.parameters()
        True
        >>> model.parameters()["scale_um_pp"], model.parameters()["shape"]
        (4.0, 1.5)
        """
        return {"scale_um_pp": self.scale_um_pp, "shape": self.shape, "force_exponent": self.force_exponent,
                "residual_ratio": self.residual_ratio}


TAU_RANGE_UM_ZP = (0.02, 35.0)  # within the scale range once converted: s0 = 2 sqrt 2 tau


class ExponentialModel(StretchedExponentialModel):
    """Empirical law of Monnoyer et al. (IEEE Trans. Haptics 2018): mu/mu0 = exp(-a²/(2 tau²)), with
    Huloux et al. (2018)'s floor d when ``residual_ratio`` is given: d + (1 - d) exp(-a²/(2 tau²)).

    The published a and tau are zero-to-peak (tau = 1.32 µm); here a = a_pp / 2. The law has no
    force term (Monnoyer et al. did not state the force), so the force is checked and otherwise
    ignored: the stretched model with beta = 2, p = 0 and s0 = 2 sqrt 2 tau.

    Parameters
    ----------
    tau_um_zp : float
        tau (µm zero-to-peak), in [0.02, 35]; Monnoyer et al.'s 1.32 by default.
    residual_ratio : float
        d, in [0, 0.9]: the lowest ratio vibration reaches; 0 by default (the published law).

    Raises
    ------
    ModelError
        A parameter outside its range.

    Examples
    --------
    >>> model = ExponentialModel(tau_um_zp=1.0)
    >>> model
    ExponentialModel(tau_um_zp=1.0)
    >>> round(float(model.relative_friction(2.0)), 4)                      # 2 µm p-p = tau zero-to-peak
    0.6065
    """

    name = "exponential"
    default_floor = 0.0

    def __init__(self, tau_um_zp: float = MONNOYER_TAU_UM_ZP, residual_ratio: float = 0.0):
        self.tau_um_zp = _in_range("tau_um_zp", tau_um_zp, TAU_RANGE_UM_ZP, " µm zero-to-peak")
        super().__init__(2.0 * np.sqrt(2.0) * self.tau_um_zp, 2.0, 0.0, residual_ratio)

    def force_law(self) -> str:
        """None: Monnoyer et al.'s curve is the same at every force.

        Returns
        -------
        str

        Examples
        --------
        >>> ExponentialModel().force_law()
        'none: the same curve at every force (Monnoyer et al. did not state theirs)'
        """
        return "none: the same curve at every force (Monnoyer et al. did not state theirs)"

    def _own_force_range_n(self) -> tuple[float, float]:
        return (MIN_FORCE_N, MAX_FORCE_N)

    def describe(self) -> str:
        """One line: the law with tau (µm zero-to-peak) and the floor.

        Returns
        -------
        str

        Examples
        --------
        >>> ExponentialModel().describe().split(",")[0]
        'exponential: mu/mu0 = exp(-a²/2tau²)'
        >>> ExponentialModel(residual_ratio=0.2).describe().split(",")[0]   # with a floor, the law as evaluated
        'exponential: mu/mu0 = d + (1 - d) exp(-a²/2tau²)'
        """
        return (f"exponential: mu/mu0 = {self._floor_form()}exp(-a²/2tau²), tau = {self.tau_um_zp:.4g} µm "
                f"zero-to-peak"
                f"{self._floor_words()}; force law: {self.force_law()}")

    def parameters(self) -> dict[str, float | str]:
        """``tau_um_zp`` (µm zero-to-peak) and ``residual_ratio``, as the constructor takes them.

        Returns
        -------
        dict

        Examples
        --------
        >>> ExponentialModel().parameters()                     # Monnoyer et al.'s tau, no floor by default
        {'tau_um_zp': 1.32, 'residual_ratio': 0.0}
        """
        return {"tau_um_zp": self.tau_um_zp, "residual_ratio": self.residual_ratio}
