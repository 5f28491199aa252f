"""The fitted models' parameters: their names, units and allowed ranges (:data:`PARAMETERS`), a model
built from them, and a fit's result (:class:`Fit`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import FingerParams
from ultraglide.render.physics.friction_models import (
    FORCE_EXPONENT_RANGE,
    RESIDUAL_RANGE,
    SCALE_RANGE_UM_PP,
    SHAPE_RANGE,
    TAU_RANGE_UM_ZP,
    ExponentialModel,
    FrictionModel,
    PaperModel,
    StretchedExponentialModel,
)
from ultraglide.render.physics.measurements import Measurements
from ultraglide.render.physics.squeeze_film import (
    AMBIENT_RANGE_PA,
    FILM_FRACTION_RANGE,
    GAP_RANGE_UM,
    FilmParams,
    SqueezeFilmModel,
)

MODEL_NAMES = ("paper", "paper-uniform", "exponential", "stretched", "squeeze-film")


@dataclass(frozen=True)
class ParameterSpec:
    """One model parameter: its key in calibration files, unit, allowed range and default.

    Examples
    --------
    >>> scale = PARAMETERS["stretched"][0]
    >>> scale.key, scale.unit, scale.check(2.5, "model.toml")
    ('scale_um_pp', ' µm p-p', 2.5)
    >>> scale.check(500, "model.toml")
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: model.toml: parameter scale_um_pp = 500 is outside the allowed range
    [0.05, 100] µm p-p
    """

    key: str
    unit: str
    low: float
    high: float
    default: float
    needs_forces: bool = False  # only identifiable from data at two forces or more
    physical: tuple[float, float] | None = None  # where the model still describes its physics
    reason: str = ""  # what the physical range rests on
    optional: bool = False  # calibration files may leave it out (older ones do): the default applies
    fitted: bool = True  # False: held at the default by every fit (the file may still set it)
    zero_ok: bool = False  # a value at the lower bound 0 is a finding (no floor, no film), not a warning

    def check(self, value, where: str) -> float:
        """``value`` as a float if it is a number within this parameter's range; else ModelError naming ``where``.

        Parameters
        ----------
        value : object
            The value read.
        where : str
            What the error names (the file and key).

        Returns
        -------
        float

        Raises
        ------
        ModelError
            Not a number, or out of the range.

        Examples
        --------
        >>> scale = PARAMETERS["stretched"][0]
        >>> scale.check(3, "model.toml"), (scale.low, scale.high)                  # µm p-p
        (3.0, (0.05, 100.0))
        """
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ModelError(f"{where}: parameter {self.key} must be a number in [{self.low:g}, {self.high:g}]"
                             f"{self.unit}, got {value!r}")
        if not (math.isfinite(value) and self.low <= value <= self.high):
            raise ModelError(f"{where}: parameter {self.key} = {value} is outside the allowed range "
                             f"[{self.low:g}, {self.high:g}]{self.unit}")
        return float(value)


_PAPER = (
    ParameterSpec("youngs_modulus_pa", " Pa", 1e4, 1e9, FingerParams().youngs_modulus_pa,
                  physical=(1e5, 1e8), reason="skin ridges are 0.1-100 MPa"),
    ParameterSpec("friction_exponent", "", 0.05, 1.0, FingerParams().friction_exponent,
                  physical=(0.5, 1.0), reason="finger-pad friction grows as F^n with n from about 2/3 (Hertzian "
                  "asperities) to 1 (Coulomb)"),
    ParameterSpec("area_exponent", "", 0.3, 1.0, FingerParams().area_exponent, needs_forces=True,
                  physical=(0.5, 1.0), reason="contact area grows as F^(2/3) (Hertz) to F (many asperities)",
                  optional=True),
)
_RESIDUAL = ParameterSpec("residual_ratio", "", *RESIDUAL_RANGE, 0.0, optional=True, zero_ok=True)
PARAMETERS: dict[str, tuple[ParameterSpec, ...]] = {
    "exponential": (ParameterSpec("tau_um_zp", " µm zero-to-peak", *TAU_RANGE_UM_ZP, 1.32), _RESIDUAL),
    "stretched": (
        ParameterSpec("scale_um_pp", " µm p-p", *SCALE_RANGE_UM_PP, StretchedExponentialModel().scale_um_pp),
        ParameterSpec("shape", "", *SHAPE_RANGE, 2.0),
        ParameterSpec("force_exponent", "", *FORCE_EXPONENT_RANGE, 1.0 / 3.0, needs_forces=True, optional=True),
        _RESIDUAL,
    ),
    "paper": _PAPER,
    "paper-uniform": _PAPER,
    "squeeze-film": (
        ParameterSpec("gap_um", " µm", *GAP_RANGE_UM, FilmParams().gap_um, physical=(2.0, 50.0),
                      reason="skin on glass leaves air pockets of a few to tens of µm"),
        ParameterSpec("film_fraction", "", *FILM_FRACTION_RANGE, FilmParams().film_fraction, zero_ok=True),
        ParameterSpec("ambient_pressure_pa", " Pa", *AMBIENT_RANGE_PA, FilmParams().ambient_pressure_pa,
                      optional=True, fitted=False),
        ParameterSpec("youngs_modulus_pa", " Pa", 1e5, 1e8, FingerParams().youngs_modulus_pa, optional=True,
                      fitted=False),  # the ridges' physical ranges (the paper model's warnings) are the limits here
        ParameterSpec("friction_exponent", "", 0.5, 1.0, FingerParams().friction_exponent, optional=True,
                      fitted=False),
    ),
}
OPTIONAL_KEYS = {s.key for specs in PARAMETERS.values() for s in specs if s.optional}


def build_model(kind: str, values: dict[str, float]) -> FrictionModel:
    """A model of ``kind`` from parameter values keyed as in :data:`PARAMETERS`.

    Parameters
    ----------
    kind : str
        ``exponential``, ``stretched``, ``paper``, ``paper-uniform`` or ``squeeze-film``.
    values : dict
        Parameter values (units in their keys).

    Returns
    -------
    FrictionModel

    Raises
    ------
    ModelError
        An unknown kind.

    Examples
    --------
    >>> build_model("exponential", {"tau_um_zp": 1.0})
    ExponentialModel(tau_um_zp=1.0)
    """
    if kind == "exponential":
        return ExponentialModel(values["tau_um_zp"], values.get("residual_ratio", 0.0))
    if kind == "stretched":
        return StretchedExponentialModel(values["scale_um_pp"], values["shape"], values["force_exponent"],
                                         values.get("residual_ratio", 0.0))
    if kind in ("paper", "paper-uniform"):
        return PaperModel(ridge_finger(kind, values))
    if kind == "squeeze-film":
        return SqueezeFilmModel(film_params(values), film_finger(values))
    raise ModelError(f"cannot build model {kind!r}; choose one of: {', '.join(MODEL_NAMES)}")


def ridge_finger(kind: str, values: dict[str, float]) -> FingerParams:
    """The ridge model's finger from fitted values (``youngs_modulus_pa``, ``friction_exponent``,
    ``area_exponent``); a uniform contact for ``paper-uniform``, Hertzian otherwise.

    Parameters
    ----------
    kind : str
        ``paper`` or ``paper-uniform``.
    values : dict
        The fitted values (E in Pa).

    Returns
    -------
    FingerParams

    Examples
    --------
    >>> values = {"youngs_modulus_pa": 2e6, "friction_exponent": 0.7, "area_exponent": 0.6}
    >>> ridge_finger("paper-uniform", values).contact, ridge_finger("paper", values).contact
    ('uniform', 'hertz')
    """
    return FingerParams(youngs_modulus_pa=values["youngs_modulus_pa"], friction_exponent=values["friction_exponent"],
                        area_exponent=values["area_exponent"],
                        contact="uniform" if kind == "paper-uniform" else "hertz")


def film_params(values: dict[str, float]) -> FilmParams:
    """The air film from fitted values: ``gap_um`` (µm), ``film_fraction``, ``ambient_pressure_pa`` (Pa).

    Parameters
    ----------
    values : dict

    Returns
    -------
    FilmParams

    Examples
    --------
    >>> film_params({"gap_um": 5.0, "film_fraction": 0.3, "ambient_pressure_pa": 1e5})
    FilmParams(gap_um=5.0, film_fraction=0.3, ambient_pressure_pa=100000.0)
    """
    return FilmParams(values["gap_um"], values["film_fraction"], values["ambient_pressure_pa"])


def film_finger(values: dict[str, float]) -> FingerParams:
    """The squeeze-film model's finger from fitted values (``youngs_modulus_pa``, ``friction_exponent``).

    Parameters
    ----------
    values : dict

    Returns
    -------
    FingerParams

    Examples
    --------
    >>> film_finger({"youngs_modulus_pa": 2e6, "friction_exponent": 0.7}).youngs_modulus_pa     # Pa
    2000000.0
    """
    return FingerParams(youngs_modulus_pa=values["youngs_modulus_pa"], friction_exponent=values["friction_exponent"])


def model_kind(model: FrictionModel) -> str:
    """The name a calibration file gives this model.

    Parameters
    ----------
    model : FrictionModel

    Returns
    -------
    str

    Examples
    --------
    >>> finger = {"youngs_modulus_pa": 1e6, "friction_exponent": 2 / 3, "area_exponent": 2 / 3}
    >>> model_kind(build_model("paper-uniform", finger)), model_kind(build_model("paper", finger))
    ('paper-uniform', 'paper')
    """
    if isinstance(model, PaperModel):
        return "paper-uniform" if model.params.contact == "uniform" else "paper"
    return model.name


@dataclass(frozen=True)
class Parameter:
    """A fitted (or held) parameter value with its standard error (NaN when held fixed).

    Examples
    --------
    >>> scale = PARAMETERS["stretched"][0]
    >>> Parameter(scale, 100.0, 0.5, fixed=False).at_bound, Parameter(scale, 2.5, 0.1, fixed=False).at_bound
    (True, False)
    """

    spec: ParameterSpec
    value: float
    stderr: float
    fixed: bool

    @property
    def at_bound(self) -> bool:
        """Within 0.1 % of a bound (ranges span decades, so relative to the bound itself).

        Examples
        --------
        >>> scale = PARAMETERS["stretched"][0]                     # 0.05..100 µm p-p
        >>> Parameter(scale, 99.95, 0.5, fixed=False).at_bound, Parameter(scale, 99.0, 0.5, fixed=False).at_bound
        (True, False)
        """
        span = self.spec.high - self.spec.low
        bounds = (self.spec.high,) if self.spec.zero_ok and self.spec.low == 0 else (self.spec.low, self.spec.high)
        return not self.fixed and any(abs(self.value - bound) <= (1e-3 * abs(bound) if bound else 1e-6 * span)
                                      for bound in bounds)


@dataclass(frozen=True)
class Fit:
    """A fitted model with its residuals (measured minus modelled ratio) at each point.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.render.physics.fitting import fit_model
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.linspace(0.0, 6.0, 13)
    >>> fit = fit_model(Measurements(amplitude, np.exp(-(amplitude / 2.5) ** 2), None, "example"), "stretched",
    ...                 hold={"residual_ratio": 0.0})
    >>> fit.kind, [p.spec.key for p in fit.parameters if not p.fixed], fit.rms_residual < 1e-6
    ('stretched', ['scale_um_pp', 'shape'], True)
    """

    model: FrictionModel
    residuals: np.ndarray
    data: Measurements
    kind: str = ""
    parameters: tuple[Parameter, ...] = ()
    cross_validation: dict[str, float] = field(default_factory=dict)  # name → RMS of held-out residuals
    bootstrap: dict[str, dict[str, float]] = field(default_factory=dict)  # scheme → parameter → standard error

    @property
    def rms_residual(self) -> float:
        """The root mean square of the fit's residuals (friction ratio).

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> data = Measurements(np.array([0.0, 2.0]), np.array([1.0, 0.5]), None, "bench")
        >>> fit = Fit(StretchedExponentialModel(), np.array([0.03, -0.04]), data)
        >>> round(fit.rms_residual, 6), round(float(np.sqrt((0.03 ** 2 + 0.04 ** 2) / 2)), 6)
        (0.035355, 0.035355)
        """
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def max_abs_residual(self) -> float:
        """The largest residual of the fit, in absolute value (friction ratio).

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> data = Measurements(np.array([0.0, 2.0]), np.array([1.0, 0.5]), None, "bench")
        >>> Fit(StretchedExponentialModel(), np.array([0.03, -0.04]), data).max_abs_residual
        0.04
        """
        return float(np.max(np.abs(self.residuals)))

    @property
    def cv_rms(self) -> float:
        """The fit's headline out-of-sample error: k-fold RMS (NaN if there were too few points).

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> data = Measurements(np.array([0.0, 2.0]), np.array([1.0, 0.5]), None, "bench")
        >>> Fit(StretchedExponentialModel(), np.zeros(2), data, cross_validation={"k_fold": 0.05}).cv_rms
        0.05
        >>> Fit(StretchedExponentialModel(), np.zeros(2), data).cv_rms                  # too few points: none
        nan
        """
        return self.cross_validation.get("k_fold", math.nan)

    def warnings(self) -> list[str]:
        """One line per parameter that sits at a bound of its allowed range or leaves its physics.

        Returns
        -------
        list of str

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.render.physics.measurements import Measurements
        >>> data = Measurements(np.array([0.0, 2.0]), np.array([1.0, 0.5]), None, "bench")
        >>> scale = PARAMETERS["stretched"][0]
        >>> at_top = (Parameter(scale, 100.0, 0.5, fixed=False),)
        >>> Fit(StretchedExponentialModel(), np.zeros(2), data, "stretched", at_top).warnings()     # doctest: +ELLIPSIS
        ['scale_um_pp = 100 sits at the bound 100 of its allowed range [0.05, 100] µm p-p: the data push ...']
        """
        lines = []
        for p in self.parameters:
            physical = p.spec.physical
            if not p.fixed and physical and not physical[0] <= p.value <= physical[1]:
                lines.append(f"{p.spec.key} = {p.value:.4g} is outside [{physical[0]:g}, {physical[1]:g}]"
                             f"{p.spec.unit}, where the {self.kind} model means what it says ({p.spec.reason}): "
                             "it fits these data only by leaving its physics")
            elif p.at_bound:
                bound = p.spec.low if p.value - p.spec.low < p.spec.high - p.value else p.spec.high
                lines.append(f"{p.spec.key} = {p.value:.4g} sits at the bound {bound:g} of its allowed range "
                             f"[{p.spec.low:g}, {p.spec.high:g}]{p.spec.unit}: the data push the {self.kind} model "
                             "beyond what it describes")
        return lines
