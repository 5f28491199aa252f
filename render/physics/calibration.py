"""Fitting friction models to measured points, and calibration files that act as models.

A fit is scipy's bounded least squares on the measured relative friction; each free parameter gets
a standard error from the covariance s² (JᵀJ)⁻¹ at the optimum, and the fit is judged by how well it
predicts points it did not see: k-fold cross-validation, and, when the data hold several forces
(or participants), leave-one-force-out (leave-one-participant-out). A parameter that ends at a bound
of its allowed range is named in a warning: the data push the model outside what it describes.

A calibration file is TOML::

    ultraglide_calibration = 1
    model = "stretched"
    [parameters]
    scale_um_pp = 3.73
    shape = 2.0
    force_exponent = 0.333
    [fit]
    source = "monnoyer2018-fit.csv"
    points = 11
    ...

Every command that takes ``--model`` accepts such a file (see :func:`load_model`). Reading one is
typed: each model's parameters are listed in :data:`PARAMETERS` with their allowed ranges, and a
missing, unknown, non-numeric or out-of-range parameter is refused with a line naming the key.
"""

from __future__ import annotations

import datetime as _dt
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import FingerParams
from ultraglide.render.physics.friction_models import (
    DEFAULT_FORCE_N,
    FORCE_EXPONENT_RANGE,
    SCALE_RANGE_UM_PP,
    SHAPE_RANGE,
    TAU_RANGE_UM_ZP,
    ExponentialModel,
    FrictionModel,
    PaperModel,
    StretchedExponentialModel,
    TableModel,
)
from ultraglide.render.physics.measurements import Measurements, read_measurements
from ultraglide.render.physics.normal_contact import relative_friction_of_u

CALIBRATION_VERSION = 1
MODEL_NAMES = ("paper", "paper-uniform", "exponential", "stretched")
COMPARED_MODELS = ("stretched", "exponential", "paper", "paper-uniform", "table")
K_FOLDS = 5


@dataclass(frozen=True)
class ParameterSpec:
    """One model parameter: its key in calibration files, unit, allowed range and default."""

    key: str
    unit: str
    low: float
    high: float
    default: float
    needs_forces: bool = False  # only identifiable from data at two forces or more
    physical: tuple[float, float] | None = None  # where the model still describes its physics
    reason: str = ""  # what the physical range rests on

    def check(self, value, where: str) -> float:
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
                  physical=(0.5, 1.0), reason="contact area grows as F^(2/3) (Hertz) to F (many asperities)"),
)
PARAMETERS: dict[str, tuple[ParameterSpec, ...]] = {
    "exponential": (ParameterSpec("tau_um_zp", " µm zero-to-peak", *TAU_RANGE_UM_ZP, 1.32),),
    "stretched": (
        ParameterSpec("scale_um_pp", " µm p-p", *SCALE_RANGE_UM_PP, StretchedExponentialModel().scale_um_pp),
        ParameterSpec("shape", "", *SHAPE_RANGE, 2.0),
        ParameterSpec("force_exponent", "", *FORCE_EXPONENT_RANGE, 1.0 / 3.0, needs_forces=True),
    ),
    "paper": _PAPER,
    "paper-uniform": _PAPER,
}
OPTIONAL_KEYS = {"area_exponent", "force_exponent"}  # older files lack them: the defaults apply


def build_model(kind: str, values: dict[str, float]) -> FrictionModel:
    """A model of ``kind`` from parameter values keyed as in :data:`PARAMETERS`."""
    if kind == "exponential":
        return ExponentialModel(values["tau_um_zp"])
    if kind == "stretched":
        return StretchedExponentialModel(values["scale_um_pp"], values["shape"], values["force_exponent"])
    if kind in ("paper", "paper-uniform"):
        return PaperModel(_finger(kind, values))
    raise ModelError(f"cannot build model {kind!r}; choose one of: {', '.join(MODEL_NAMES)}")


def _finger(kind: str, values: dict[str, float]) -> FingerParams:
    return FingerParams(youngs_modulus_pa=values["youngs_modulus_pa"], friction_exponent=values["friction_exponent"],
                        area_exponent=values["area_exponent"],
                        contact="uniform" if kind == "paper-uniform" else "hertz")


def model_kind(model: FrictionModel) -> str:
    """The name a calibration file gives this model."""
    if isinstance(model, PaperModel):
        return "paper-uniform" if model.params.contact == "uniform" else "paper"
    return model.name


@dataclass(frozen=True)
class Parameter:
    """A fitted (or held) parameter value with its standard error (NaN when held fixed)."""

    spec: ParameterSpec
    value: float
    stderr: float
    fixed: bool

    @property
    def at_bound(self) -> bool:
        """Within 0.1 % of a bound (ranges span decades, so relative to the bound itself)."""
        span = self.spec.high - self.spec.low
        return not self.fixed and any(abs(self.value - bound) <= (1e-3 * abs(bound) if bound else 1e-6 * span)
                                      for bound in (self.spec.low, self.spec.high))


@dataclass(frozen=True)
class Fit:
    """A fitted model with its residuals (measured minus modelled ratio) at each point."""

    model: FrictionModel
    residuals: np.ndarray
    data: Measurements
    kind: str = ""
    parameters: tuple[Parameter, ...] = ()
    cross_validation: dict[str, float] = field(default_factory=dict)  # name → RMS of held-out residuals

    @property
    def rms_residual(self) -> float:
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def max_abs_residual(self) -> float:
        return float(np.max(np.abs(self.residuals)))

    @property
    def cv_rms(self) -> float:
        """The fit's headline out-of-sample error: k-fold RMS (NaN if there were too few points)."""
        return self.cross_validation.get("k_fold", math.nan)

    def warnings(self) -> list[str]:
        """One line per parameter that sits at a bound of its allowed range or leaves its physics."""
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


def _forces(data: Measurements) -> np.ndarray:
    return data.force_n if data.force_n is not None else np.full(len(data), DEFAULT_FORCE_N)


def _distinct_forces(data: Measurements) -> int:
    return len(np.unique(_forces(data)))


def _prediction(kind: str, values: dict[str, float], data: Measurements):
    """Modelled ratio at the data's points; the paper model is evaluated directly at each point
    (no table), since only the exponent changes its curve and E only rescales the amplitude."""
    forces = _forces(data)
    if kind in ("paper", "paper-uniform"):
        params = _finger(kind, values)
        detach = PaperModel.detach_um_pp_for(params, forces)
        return relative_friction_of_u(data.amplitude_um_pp / detach, params, phase_points=96, ring_nodes=24)
    return build_model(kind, values).relative_friction(data.amplitude_um_pp, forces)


def fit_model(data: Measurements, kind: str, cross_validate: bool = False) -> Fit:
    """Least-squares fit of a model's free parameters to measured points.

    ``exponential`` fits tau; ``stretched`` fits its scale and shape, and its force exponent when
    the data hold two forces or more; ``paper`` fits the ridge modulus E_e (which sets the
    detachment amplitude) and the friction exponent n, and the area exponent with several forces.
    ``table`` builds the table model (nothing to fit). With ``cross_validate`` the fit also carries
    its k-fold and leave-one-force-out (-participant-out) errors.
    """
    if kind == "table":
        model: FrictionModel = TableModel(data)
        residuals = data.relative_friction - model.relative_friction(
            np.minimum(data.amplitude_um_pp, model.max_amplitude_um_pp), _forces(data))
        fit = Fit(model, residuals, data, kind)
    else:
        fit = _least_squares_fit(data, kind)
    if cross_validate:
        fit = Fit(fit.model, fit.residuals, fit.data, fit.kind, fit.parameters, cross_validation_errors(data, kind))
    return fit


def _least_squares_fit(data: Measurements, kind: str) -> Fit:
    from scipy.optimize import least_squares  # only fitting needs it; keep model loading light

    if kind not in PARAMETERS:
        raise ModelError(f"cannot fit model {kind!r}; choose one of: {', '.join((*MODEL_NAMES, 'table'))}")
    specs = PARAMETERS[kind]
    several_forces = _distinct_forces(data) >= 2
    free = [s for s in specs if several_forces or not s.needs_forces]
    if len(data) <= len(free):
        raise ModelError(f"{data.source}: {len(data)} points cannot fit the {len(free)} parameters of the "
                         f"{kind} model; measure more amplitudes")
    # parameters are fitted in units where they are of order one (E in MPa)
    unit = {s.key: (1e6 if s.key == "youngs_modulus_pa" else 1.0) for s in specs}

    def values_of(x) -> dict[str, float]:
        values = {s.key: s.default for s in specs}
        values.update({s.key: float(v) * unit[s.key] for s, v in zip(free, x, strict=True)})
        return values

    def residual(x):
        return data.relative_friction - _prediction(kind, values_of(x), data)

    x0 = np.array([s.default / unit[s.key] for s in free])
    low = np.array([s.low / unit[s.key] for s in free])
    high = np.array([s.high / unit[s.key] for s in free])
    best = None
    for start in _starts(kind, x0, low, high, free):
        result = least_squares(residual, x0=start, bounds=(low, high), diff_step=1e-4 if kind.startswith("paper")
                               else None)
        if best is None or result.cost < best.cost:
            best = result
    x = best.x
    residuals = residual(x)
    stderr = _standard_errors(best.jac, residuals) * np.array([unit[s.key] for s in free])
    values = values_of(x)
    fitted = {s.key: (float(e), False) for s, e in zip(free, stderr, strict=True)}
    parameters = tuple(Parameter(s, values[s.key], *fitted.get(s.key, (math.nan, True))) for s in specs)
    try:
        model = build_model(kind, values)
    except ValueError as error:  # FingerParams refuses a combination
        raise ModelError(f"the fitted {kind} model is not valid ({error})") from None
    return Fit(model, residuals, data, kind, parameters)


def _starts(kind, x0, low, high, free):
    """Starting points: the defaults, and for the stretched law also a shallow and a sharp shape."""
    yield x0
    if kind == "stretched":
        for shape in (1.0, 3.0):
            start = x0.copy()
            start[[s.key for s in free].index("shape")] = shape
            yield start


def _standard_errors(jacobian: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """sqrt(diag(s² (JᵀJ)⁻¹)), s² = SSR / (points − parameters); NaN where undetermined."""
    points, count = jacobian.shape
    if points <= count:
        return np.full(count, math.nan)
    variance = float(residuals @ residuals) / (points - count)
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * variance
    return np.sqrt(np.maximum(np.diag(covariance), 0.0))


def _held_out_rms(data: Measurements, kind: str, groups: np.ndarray) -> float:
    """RMS over all points of the residual each gets from a fit to the other groups."""
    residuals = np.empty(len(data))
    for group in np.unique(groups):
        held = groups == group
        fit = fit_model(data.subset(~held), kind)
        test = data.subset(held)
        amplitude = np.minimum(test.amplitude_um_pp, fit.model.max_amplitude_um_pp)
        residuals[held] = test.relative_friction - fit.model.relative_friction(amplitude, _forces(test))
    return float(np.sqrt(np.mean(residuals**2)))


def cross_validation_errors(data: Measurements, kind: str) -> dict[str, float]:
    """Out-of-sample RMS errors in relative friction: ``k_fold`` (5 folds, or leave-one-out for
    fewer than 10 points), ``leave_one_force_out`` with several forces, and
    ``leave_one_participant_out`` with several participants. A scheme whose training sets are too
    small for the model is left out."""
    errors = {}
    folds = min(K_FOLDS, len(data)) if len(data) >= 10 else len(data)
    order = np.random.default_rng(0).permutation(len(data))
    groups = np.empty(len(data), dtype=int)
    groups[order] = np.arange(len(data)) % folds
    schemes = [("k_fold", groups)]
    if _distinct_forces(data) >= 2:
        schemes.append(("leave_one_force_out", _forces(data)))
    if data.participant is not None and len(np.unique(data.participant)) >= 2:
        schemes.append(("leave_one_participant_out", data.participant))
    for name, grouping in schemes:
        try:
            errors[name] = _held_out_rms(data, kind, grouping)
        except ModelError:  # a training set too small for this model
            continue
    return errors


def compare_models(data: Measurements, kinds: tuple[str, ...] = COMPARED_MODELS) -> list[Fit]:
    """Every model fitted and cross-validated, best first (by leave-one-force-out RMS when the data
    hold several forces, else by k-fold RMS). Models that cannot be fitted to these data are left out."""
    fits = []
    for kind in kinds:
        try:
            fits.append(fit_model(data, kind, cross_validate=True))
        except ModelError:
            continue

    def score(fit: Fit) -> float:
        value = fit.cross_validation.get("leave_one_force_out", fit.cv_rms)
        return math.inf if math.isnan(value) else value
    return sorted(fits, key=score)


def fit_summary(fit: Fit) -> dict:
    """A fit as plain values (JSON and the calibration file's [fit] table)."""
    return {
        "model": fit.kind,
        "description": fit.model.describe(),
        "source": str(fit.data.source),
        "points": len(fit.data),
        "forces_n": [float(f) for f in np.unique(_forces(fit.data))],
        "parameters": {p.spec.key: {"value": p.value, "stderr": None if math.isnan(p.stderr) else p.stderr,
                                    "fixed": p.fixed, "allowed": [p.spec.low, p.spec.high]}
                       for p in fit.parameters},
        "rms_residual": fit.rms_residual,
        "max_abs_residual": fit.max_abs_residual,
        "cross_validation_rms": dict(fit.cross_validation),
        "warnings": fit.warnings(),
    }


def calibration_toml(fit: Fit) -> str:
    """The calibration file's text for a fit (``ultraglide calibrate`` writes it atomically)."""
    kind = fit.kind or model_kind(fit.model)
    if kind == "table":
        raise ModelError("a table model is its CSV: use --model table:FILE.csv instead of a calibration file")
    summary = fit_summary(fit)
    document = {
        "ultraglide_calibration": CALIBRATION_VERSION,
        "model": kind,
        "parameters": {key: value for key, value in fit.model.parameters().items() if key in
                       {s.key for s in PARAMETERS[kind]}},
        "fit": {
            "source": summary["source"],
            "points": summary["points"],
            "forces_n": summary["forces_n"],
            "rms_residual": fit.rms_residual,
            "max_abs_residual": fit.max_abs_residual,
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        },
    }
    if fit.parameters:
        document["fit"]["stderr"] = {p.spec.key: p.stderr for p in fit.parameters if not p.fixed}
    if fit.cross_validation:
        document["fit"]["cross_validation_rms"] = dict(fit.cross_validation)
    if fit.warnings():
        document["fit"]["warnings"] = fit.warnings()
    return tomli_w.dumps(document)


def read_calibration(path: str | Path) -> FrictionModel:
    """A model from a calibration file; :class:`ModelError` says what is wrong with it."""
    path = Path(path)
    try:
        with path.open("rb") as stream:
            document = tomllib.load(stream)
    except FileNotFoundError:
        raise ModelError(f"{path}: no such calibration file") from None
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ModelError(f"{path}: not a readable calibration file ({error})") from None
    return calibration_from_document(document, str(path))


def calibration_from_document(document: dict, where: str) -> FrictionModel:
    """The typed reading of a calibration file's parsed TOML (see :func:`read_calibration`)."""
    version = document.get("ultraglide_calibration")
    if version != CALIBRATION_VERSION or isinstance(version, bool):
        raise ModelError(f"{where}: not an ultraglide calibration file of version {CALIBRATION_VERSION}"
                         " (make one with `ultraglide calibrate`)")
    kind = document.get("model")
    if kind not in PARAMETERS:
        raise ModelError(f"{where}: unknown model {kind!r}; expected one of {', '.join(MODEL_NAMES)}")
    parameters = document.get("parameters", {})
    if not isinstance(parameters, dict):
        raise ModelError(f"{where}: [parameters] must be a table of numbers")
    specs = {s.key: s for s in PARAMETERS[kind]}
    legacy = {"contact"}  # version-1 files of the paper model named the contact, which the model name says
    unknown = sorted(set(parameters) - set(specs) - legacy)
    if unknown:
        raise ModelError(f"{where}: unknown parameter {unknown[0]} for the {kind} model; "
                         f"expected {', '.join(specs)}")
    values = {}
    for key, spec in specs.items():
        if key not in parameters:
            if key in OPTIONAL_KEYS:
                values[key] = spec.default
                continue
            raise ModelError(f"{where}: parameter {key} is missing (allowed range [{spec.low:g}, {spec.high:g}]"
                             f"{spec.unit})")
        values[key] = spec.check(parameters[key], where)
    try:
        return build_model(kind, values)
    except ValueError as error:  # FingerParams: a combination it refuses
        raise ModelError(f"{where}: {str(error).splitlines()[0]}") from None


def load_model(spec: str) -> FrictionModel:
    """A model by name or file: ``paper``, ``paper-uniform``, ``exponential``, ``stretched``,
    ``table:FILE.csv`` or a calibration file ``CAL.toml``."""
    if spec == "paper":
        return PaperModel()
    if spec == "paper-uniform":
        return PaperModel(FingerParams(contact="uniform"))
    if spec == "exponential":
        return ExponentialModel()
    if spec == "stretched":
        return StretchedExponentialModel()
    if spec.startswith("table:"):
        return TableModel(read_measurements(spec.removeprefix("table:")))
    if spec.endswith(".toml"):
        return read_calibration(spec)
    raise ModelError(
        f"unknown model {spec!r}; use paper, paper-uniform, exponential, stretched, table:FILE.csv or CAL.toml"
    )

