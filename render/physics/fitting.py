"""Fitting friction models to measured points.

A fit is scipy's bounded least squares on the measured relative friction; each free parameter gets
a standard error from the covariance s² (JᵀJ)⁻¹ at the optimum, and, since that is optimistic when
the residuals have structure, bootstrap standard errors beside it: points resampled, and whole
forces or participants resampled when there are three or more (:func:`bootstrap_errors`). The fit is
judged by how well it predicts points it did not see: k-fold cross-validation with the folds drawn
within each force, leave-one-force-out when the data hold three forces or more, and
leave-one-participant-out with several participants. Two forces fix a force law's exponent but
cannot test it: with two, models are ranked by k-fold error within each force and the selection
says that the force law was not tested (:func:`selection_note`). A parameter that ends at a bound of
its allowed range is named in a warning: the data push the model outside what it describes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from ultraglide.render.physics.empirical_models import REFERENCE_FORCE_N
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import FingerParams
from ultraglide.render.physics.friction_models import (
    DEFAULT_FORCE_N,
    MAX_FORCE_N,
    FitRange,
    FrictionModel,
    PaperModel,
    TableModel,
)
from ultraglide.render.physics.measurements import Measurements
from ultraglide.render.physics.model_base import clip_force
from ultraglide.render.physics.model_parameters import (
    MODEL_NAMES,
    PARAMETERS,
    Fit,
    Parameter,
    build_model,
    film_finger,
    film_params,
    ridge_finger,
)
from ultraglide.render.physics.normal_contact import relative_friction_of_u
from ultraglide.render.physics.squeeze_film import (
    film_ratio,
)

COMPARED_MODELS = ("stretched", "exponential", "squeeze-film", "paper", "paper-uniform", "table")
K_FOLDS = 5
BOOTSTRAP_SAMPLES = 200
MIN_BOOTSTRAP_GROUPS = 3  # resampling two groups mostly draws the same one twice


def _forces(data: Measurements) -> np.ndarray:
    return data.force_n if data.force_n is not None else np.full(len(data), DEFAULT_FORCE_N)


def _distinct_forces(data: Measurements) -> int:
    return len(np.unique(_forces(data)))


def _prediction(kind: str, values: dict[str, float], data: Measurements):
    """Modelled ratio at the data's points; the paper model is evaluated directly at each point
    (no table), since only the exponent changes its curve and E only rescales the amplitude."""
    forces = _forces(data)
    if kind in ("paper", "paper-uniform"):
        params = ridge_finger(kind, values)
        detach = PaperModel.detach_um_pp_for(params, forces)
        return relative_friction_of_u(data.amplitude_um_pp / detach, params, phase_points=96, ring_nodes=24)
    if kind == "squeeze-film":  # the film's forward model on the ridges' table, no inverse table to build
        return film_ratio(data.amplitude_um_pp, np.clip(forces, 0.01, MAX_FORCE_N), film_params(values),
                          _ridges(film_finger(values)))
    return _forward_model(kind, values).relative_friction(data.amplitude_um_pp, forces)


_RIDGES: dict[FingerParams, PaperModel] = {}


def _ridges(finger: FingerParams) -> PaperModel:
    """The paper's model for these ridges, made once (a squeeze-film fit evaluates it many times)."""
    if finger not in _RIDGES:
        _RIDGES.clear()
        _RIDGES[finger] = PaperModel(finger)
    return _RIDGES[finger]


def _forward_model(kind: str, values: dict[str, float]) -> FrictionModel:
    """A model for evaluating a fit's residuals: its force-range warning silenced (fits sweep freely)."""
    model = build_model(kind, values)
    model._range_said = True
    return model


def fit_model(data: Measurements, kind: str, cross_validate: bool = False, bootstrap: int = 0,
              hold: dict[str, float] | None = None) -> Fit:
    """Least-squares fit of a model's free parameters to measured points.

    ``exponential`` fits tau; ``stretched`` fits its scale and shape, and its force exponent when
    the data hold two forces or more; ``paper`` fits the ridge modulus E_e (which sets the
    detachment amplitude) and the friction exponent n, and the area exponent with several forces.
    ``exponential`` and ``stretched`` also fit their floor (``residual_ratio``, Huloux et al. 2018; it
    may come out 0); ``squeeze-film`` fits its air gap and the film's share of the contact, the ridges
    held at Table I. ``table`` builds the table model (nothing to fit).

    Parameters
    ----------
    data : Measurements
        The points (:func:`read_measurements`).
    kind : str
        ``exponential``, ``stretched``, ``squeeze-film``, ``paper``, ``paper-uniform`` or ``table``.
    cross_validate : bool
        Also compute the fit's cross-validated errors (:func:`cross_validation_errors`).
    bootstrap : int
        A number of resamples for bootstrap standard errors (:func:`bootstrap_errors`); 0: none.
    hold : dict, optional
        Parameters fixed at given values (``{"residual_ratio": 0.0}``: the law without a floor).

    Returns
    -------
    Fit
        The model, its parameters and their uncertainties, the RMS error.

    Raises
    ------
    ModelError
        A kind not known, or data this model cannot be fitted to, in one line.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import read_measurements
    >>> import numpy as np
    >>> amplitude = np.linspace(0.0, 5.0, 30)
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "m.csv"
    >>> rows = "\\n".join(f"{a},{np.exp(-(a / 2) ** 2 / (2 * 1.3**2))}" for a in amplitude)
    >>> _ = path.write_text("amplitude_um_pp,relative_friction\\n" + rows + "\\n")
    >>> fit = fit_model(read_measurements(path), "exponential", hold={"residual_ratio": 0.0})
    >>> fit.rms_residual < 1e-6
    True
    """
    optimum = None
    if kind == "table":
        model: FrictionModel = TableModel(data)
        residuals = data.relative_friction - model.relative_friction(
            np.minimum(data.amplitude_um_pp, model.max_amplitude_um_pp), _forces(data))
        fit = Fit(model, residuals, data, kind)
    else:
        fit, optimum = _least_squares_fit(data, kind, hold)
    if cross_validate:
        fit = replace(fit, cross_validation=_cross_validation_errors(data, kind, hold, optimum))
    if bootstrap:
        fit = replace(fit, bootstrap=_bootstrap_errors(data, kind, bootstrap, 0, hold, optimum))
    return fit


def _least_squares_fit(data: Measurements, kind: str, hold: dict[str, float] | None = None,
                       near: _Optimum | None = None) -> tuple[Fit, _Optimum]:
    """The fit and its optimum (where refits of parts of these data start: :func:`_solve`)."""
    specs, free, values, best, residuals, unit, optimum = _solve(data, kind, hold, near)
    stderr = _standard_errors(best.jac, residuals) * np.array([unit[s.key] for s in free])
    fitted = {s.key: (float(e), False) for s, e in zip(free, stderr, strict=True)}
    parameters = tuple(Parameter(s, values[s.key], *fitted.get(s.key, (math.nan, True))) for s in specs)
    try:
        model = build_model(kind, values)
    except ValueError as error:  # FingerParams refuses a combination
        raise ModelError(f"the fitted {kind} model is not valid ({error})") from None
    model.fitted = fit_range(data)
    return Fit(model, residuals, data, kind, parameters), optimum


def _fitted_values(data: Measurements, kind: str, hold: dict[str, float] | None = None,
                   near: _Optimum | None = None) -> dict[str, float]:
    """The free parameters' fitted values alone (a bootstrap refit): no model built, no errors estimated
    (building the paper model's table was a sixth of each paper refit)."""
    _, free, values, *_ = _solve(data, kind, hold, near)
    try:  # what a built model would refuse: its parameter objects' checks (a full fit builds the model)
        if kind in ("paper", "paper-uniform"):
            ridge_finger(kind, values)
        elif kind == "squeeze-film":
            film_params(values), film_finger(values)
        else:
            build_model(kind, values)
    except ValueError as error:
        raise ModelError(f"the fitted {kind} model is not valid ({error})") from None
    return {s.key: values[s.key] for s in free}


@dataclass(frozen=True)
class _Optimum:
    """Where a fit ended: each free parameter's value and whether it lies at its lower bound (-1), inside
    (0) or at its upper bound (1), as scipy's ``active_mask`` says."""

    values: dict[str, float]
    bounds: dict[str, int]


def _solve(data: Measurements, kind: str, hold: dict[str, float] | None = None, near: _Optimum | None = None):
    """The least-squares optimum: (specs, free specs, every parameter's value, scipy's best result, its
    residuals, each parameter's fitting unit, the optimum as an :class:`_Optimum`).

    ``near``: the optimum of a fit to data like these (a bootstrap resample's or a cross-validation
    fold's refit starts from the full fit's): tried alone first, and kept when it converges with the same
    parameters at the same bounds; otherwise the usual starts are tried too and the best kept. Only the
    empirical laws take it: the paper's and the squeeze-film models have several optima on these data
    (parameters at their bounds), and their refits from every start land on others (a bootstrap from the
    full fit's optimum alone gave the paper model's E half the spread, its n a tenth)."""
    from scipy.optimize import least_squares  # only fitting needs it; keep model loading light

    if kind not in PARAMETERS:
        raise ModelError(f"cannot fit model {kind!r}; choose one of: {', '.join((*MODEL_NAMES, 'table'))}")
    specs = PARAMETERS[kind]
    several_forces = _distinct_forces(data) >= 2
    hold = dict(hold or {})
    unknown = sorted(set(hold) - {s.key for s in specs})
    if unknown:
        raise ModelError(f"the {kind} model has no parameter {unknown[0]} to hold; its parameters are "
                         f"{', '.join(s.key for s in specs)}")
    held_values = {key: next(s for s in specs if s.key == key).check(value, "hold") for key, value in hold.items()}
    free = [s for s in specs if s.fitted and s.key not in hold and (several_forces or not s.needs_forces)]
    if len(data) <= len(free):
        raise ModelError(f"{data.source}: {len(data)} points cannot fit the {len(free)} parameters of the "
                         f"{kind} model; measure more amplitudes")
    # parameters are fitted in units where they are of order one (E in MPa)
    unit = {s.key: (1e6 if s.key == "youngs_modulus_pa" else 1.0) for s in specs}

    def values_of(x) -> dict[str, float]:
        values = {s.key: s.default for s in specs}
        values.update(held_values)
        values.update({s.key: float(v) * unit[s.key] for s, v in zip(free, x, strict=True)})
        return values

    x0 = np.array([s.default / unit[s.key] for s in free])
    low = np.array([s.low / unit[s.key] for s in free])
    high = np.array([s.high / unit[s.key] for s in free])
    if kind in _EmpiricalLaw.KINDS:  # a closed form: evaluated without the model's per-call checks, and its Jacobian
        law = _EmpiricalLaw(kind, data, [s.key for s in free], values_of)
        residual, jacobian = law.residual, law.jacobian
    else:
        def residual(x):
            return data.relative_friction - _prediction(kind, values_of(x), data)
        jacobian = "2-point"
    diff_step = 1e-4 if kind.startswith("paper") else None
    keys = [s.key for s in free]
    starts = _starts(kind, x0, low, high, free)
    best = None
    if near is not None and kind in _EmpiricalLaw.KINDS and set(near.values) == set(keys):
        best = least_squares(residual, x0=np.clip([near.values[k] / unit[k] for k in keys], low, high), jac=jacobian,
                             bounds=(low, high), diff_step=diff_step)
        if best.status > 0 and all(int(m) == near.bounds[k] for k, m in zip(keys, best.active_mask, strict=True)):
            starts = iter(())
    for start in starts:
        result = least_squares(residual, x0=start, jac=jacobian, bounds=(low, high), diff_step=diff_step)
        if best is None or result.cost < best.cost:
            best = result
    optimum = _Optimum({k: float(v) * unit[k] for k, v in zip(keys, best.x, strict=True)},
                       {k: int(m) for k, m in zip(keys, best.active_mask, strict=True)})
    return specs, free, values_of(best.x), best, residual(best.x), unit, optimum


class _EmpiricalLaw:
    """The stretched law at the data's points, mu/mu0 = d + (1 - d) exp(-(a / s)^beta) with
    s = s0 (F / 0.5 N)^p (the exponential law: s0 = 2 sqrt 2 tau, beta = 2, p = 0), and its analytic
    Jacobian: what :class:`StretchedExponentialModel` computes, without the checks it makes on every call
    (the data were checked when read; the fit's bounds lie within the model's ranges). A fit evaluated
    the model about forty times per refit, each call building and checking it anew."""

    KINDS = ("stretched", "exponential")

    def __init__(self, kind: str, data: Measurements, keys: list[str], values_of):
        self.kind, self.keys, self.values_of = kind, keys, values_of
        self.measured = data.relative_friction
        self.amplitude = np.asarray(data.amplitude_um_pp, dtype=float)
        self.force_ratio = clip_force(_forces(data)) / REFERENCE_FORCE_N
        self.log_force_ratio = np.log(self.force_ratio)
        self.log_amplitude = np.log(np.where(self.amplitude > 0.0, self.amplitude, 1.0))  # where a = 0, power is 0

    def _parts(self, x):
        values = self.values_of(x)
        if self.kind == "exponential":
            scale, shape, exponent = 2.0 * np.sqrt(2.0) * values["tau_um_zp"], 2.0, 0.0
        else:
            scale, shape, exponent = values["scale_um_pp"], values["shape"], values["force_exponent"]
        power = np.power(self.amplitude / (scale * np.power(self.force_ratio, exponent)), shape)
        return values, shape, power, np.exp(-power)

    def prediction(self, x) -> np.ndarray:
        values, _, _, falling = self._parts(x)
        floor = values.get("residual_ratio", 0.0)
        return falling if floor == 0.0 else floor + (1.0 - floor) * falling

    def residual(self, x) -> np.ndarray:
        return self.measured - self.prediction(x)

    def jacobian(self, x) -> np.ndarray:
        """d residual / d free parameter, one column per free parameter (residual = measured - law)."""
        values, shape, power, falling = self._parts(x)
        floor = values.get("residual_ratio", 0.0)
        by_power = (1.0 - floor) * falling  # -d law / d power
        columns = []
        for key in self.keys:
            if key == "residual_ratio":
                columns.append(falling - 1.0)
            elif key in ("scale_um_pp", "tau_um_zp"):  # power ∝ s0^-beta
                columns.append(-by_power * shape * power / values[key])
            elif key == "shape":  # d power / d beta = power ln(a / s)
                log_ratio = self.log_amplitude - np.log(values["scale_um_pp"]) \
                    - values["force_exponent"] * self.log_force_ratio
                columns.append(by_power * power * log_ratio)
            else:  # force_exponent: d power / d p = -beta power ln(F / 0.5 N)
                columns.append(-by_power * shape * power * self.log_force_ratio)
        return np.column_stack(columns)


def fit_range(data: Measurements) -> FitRange:
    """The forces a fit to ``data`` rests on, and its number of points.

    Parameters
    ----------
    data : Measurements

    Returns
    -------
    FitRange
        The distinct forces (N) and the point count.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> data = Measurements(amplitude, np.exp(-(amplitude / 2.5) ** 2), np.repeat([0.3, 0.9], 13), source="example")
    >>> fit_range(data)
    FitRange(forces_n=(0.3, 0.9), points=26)
    """
    return FitRange(tuple(float(f) for f in np.unique(_forces(data))), len(data))


def _starts(kind, x0, low, high, free):
    """Starting points: the defaults, and for the stretched law also a shallow and a sharp shape."""
    yield x0
    keys = [s.key for s in free]
    if kind == "stretched":
        for shape in (1.0, 3.0):
            start = x0.copy()
            start[keys.index("shape")] = shape
            yield start
    if "residual_ratio" in keys:  # a floor: start from one that is there
        start = x0.copy()
        start[keys.index("residual_ratio")] = 0.15
        yield start
    if kind == "squeeze-film":
        for gap, fraction in ((5.0, 0.2), (20.0, 0.8)):
            start = x0.copy()
            start[keys.index("gap_um")], start[keys.index("film_fraction")] = gap, fraction
            yield start


def _standard_errors(jacobian: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """sqrt(diag(s² (JᵀJ)⁻¹)), s² = SSR / (points − parameters); NaN where undetermined."""
    points, count = jacobian.shape
    if points <= count:
        return np.full(count, math.nan)
    variance = float(residuals @ residuals) / (points - count)
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * variance
    return np.sqrt(np.maximum(np.diag(covariance), 0.0))


def _held_out_rms(data: Measurements, kind: str, groups: np.ndarray, hold: dict[str, float] | None = None,
                  near: _Optimum | None = None) -> float:
    """RMS over all points of the residual each gets from a fit to the other groups (each fit starting
    from ``near``, the full fit's optimum, when given)."""
    residuals = np.empty(len(data))
    for group in np.unique(groups):
        held = groups == group
        train = data.subset(~held)
        fit = fit_model(train, kind) if kind == "table" else _least_squares_fit(train, kind, hold, near)[0]
        fit.model._range_said = True  # held-out forces lie outside the training range by design
        test = data.subset(held)
        amplitude = np.minimum(test.amplitude_um_pp, fit.model.max_amplitude_um_pp)
        residuals[held] = test.relative_friction - fit.model.relative_friction(amplitude, _forces(test))
    return float(np.sqrt(np.mean(residuals**2)))


def k_fold_groups(data: Measurements, folds: int = K_FOLDS) -> np.ndarray:
    """The fold of each point, drawn within each force, so every fold holds points of every force.

    5 folds, or leave-one-out below 10 points; the same seed every time.

    Parameters
    ----------
    data : Measurements
    folds : int
        The number of folds.

    Returns
    -------
    numpy.ndarray of int
        The fold of each point.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> force = np.repeat([0.3, 0.9], 13)
    >>> groups = k_fold_groups(Measurements(amplitude, np.exp(-(amplitude / 2.5) ** 2), force, source="example"))
    >>> [sorted(set(groups[force == f].tolist())) for f in (0.3, 0.9)]
    [[0, 1, 2, 3, 4], [0, 1, 2, 3, 4]]
    >>> k_fold_groups(Measurements(amplitude[:4], np.ones(4), None, source="four points")).tolist()
    [0, 1, 2, 3]
    """
    if len(data) < 10:
        return np.arange(len(data))
    return folds_within(_forces(data), folds)


def folds_within(conditions: np.ndarray, folds: int = K_FOLDS) -> np.ndarray:
    """Each point's fold, drawn within each condition (a force, a speed), so every fold holds points of every
    condition; the same seed every time.

    Parameters
    ----------
    conditions : numpy.ndarray
        Each point's condition.
    folds : int
        The number of folds.

    Returns
    -------
    numpy.ndarray of int

    Examples
    --------
    >>> import numpy as np
    >>> groups = folds_within(np.repeat([25.0, 100.0], 10), 5)
    >>> sorted(groups[:10].tolist()), sorted(groups[10:].tolist())
    ([0, 0, 1, 1, 2, 2, 3, 3, 4, 4], [0, 0, 1, 1, 2, 2, 3, 3, 4, 4])
    """
    groups = np.empty(len(conditions), dtype=int)
    rng = np.random.default_rng(0)
    offset = 0
    for condition in np.unique(conditions):
        where = np.flatnonzero(conditions == condition)
        groups[where[rng.permutation(len(where))]] = (offset + np.arange(len(where))) % folds
        offset += len(where)
    return groups


def cross_validation_errors(data: Measurements, kind: str, hold: dict[str, float] | None = None) -> dict[str, float]:
    """Out-of-sample RMS errors in relative friction, by the schemes the data allow.

    ``k_fold`` (5 folds drawn within each force, or leave-one-out for fewer than 10 points),
    ``leave_one_force_out`` with three forces or more (with two, predicting one force from the other tests
    the two fingers' difference more than any law), and ``leave_one_participant_out`` with several
    participants. A scheme whose training sets are too small for the model is left out.

    Parameters
    ----------
    data : Measurements
    kind : str
        The model: ``stretched``, ``exponential``, ``paper``, ``table`` ...
    hold : dict of str to float, optional
        Parameters held at these values instead of fitted.

    Returns
    -------
    dict of str to float
        The RMS error of each scheme, in relative friction.

    Examples
    --------
    Points on a Gaussian law at two forces are predicted out of sample by the stretched law:

    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> data = Measurements(amplitude, np.exp(-(amplitude / 2.5) ** 2), np.repeat([0.3, 0.9], 13), source="example")
    >>> errors = cross_validation_errors(data, "stretched", hold={"force_exponent": 0.0})
    >>> list(errors), errors["k_fold"] < 1e-6
    (['k_fold'], True)
    """
    return _cross_validation_errors(data, kind, hold, _full_optimum(data, kind, hold))


def _full_optimum(data: Measurements, kind: str, hold: dict[str, float] | None) -> _Optimum | None:
    """The optimum of the fit to all of ``data``, where the refits of its parts start (None: no fit)."""
    if kind == "table":
        return None
    try:
        return _solve(data, kind, hold)[-1]
    except ModelError:
        return None


def _cross_validation_errors(data: Measurements, kind: str, hold: dict[str, float] | None,
                             near: _Optimum | None) -> dict[str, float]:
    errors = {}
    schemes = [("k_fold", k_fold_groups(data))]
    if _distinct_forces(data) >= 3:
        schemes.append(("leave_one_force_out", _forces(data)))
    if data.participant is not None and len(np.unique(data.participant)) >= 2:
        schemes.append(("leave_one_participant_out", data.participant))
    for name, grouping in schemes:
        try:
            errors[name] = _held_out_rms(data, kind, grouping, hold, near)
        except ModelError:  # a training set too small for this model
            continue
    return errors


def selection_note(data: Measurements) -> str:
    """What the data can and cannot test about force laws, and how models are therefore ranked.

    Parameters
    ----------
    data : Measurements

    Returns
    -------
    str
        One sentence.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> selection_note(Measurements(amplitude, np.ones(26), np.repeat([0.3, 0.9], 13), source="example"))
    '2 forces: the force law could not be tested (two forces fix an exponent, they do not test it);
    ranked by k-fold error within each force'
    """
    count = _distinct_forces(data)
    if count >= 3:
        return (f"{count} forces: force laws ranked by leave-one-force-out error (each force predicted from the "
                "others)")
    if count == 2:
        return ("2 forces: the force law could not be tested (two forces fix an exponent, they do not test it); "
                "ranked by k-fold error within each force")
    return ("1 force: the force law could not be tested (force exponents held at their assumed values); ranked by "
            "k-fold error")


FORCE_LAW_PARAMETER = {"stretched": "force_exponent"}  # models whose force law can be set to none (p = 0)


@dataclass(frozen=True)
class ForceLawChoice:
    """Whether the data support a force law, judged by predicting each force from the others.

    Attributes
    ----------
    kind : str
        The model the choice is for (``stretched``).
    forces : int
        The distinct normal forces in the data.
    held_out_with_law : float
        RMS error in relative friction predicting each force from the others with the force law (its
        exponent fitted from the other forces where there are two or more of them, else at its assumed
        value); NaN with one force.
    held_out_force_free : float
        The same with the exponent held at 0 (the law that ignores force); NaN with one force.
    keeps_law : bool
        True only when the law predicts the held-out forces better than ignoring force does.
    hold : dict
        What to hold in the fit that is kept (``{"force_exponent": 0.0}`` for the force-free law).
    note : str
        The choice in words.

    Examples
    --------
    Points with no force dependence at two forces: the force-free law predicts each force from the other better:

    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> ratio = 0.1 + 0.9 * np.exp(-0.5 * (amplitude / 2.5) ** 2)
    >>> choice = choose_force_law(Measurements(amplitude, ratio, np.repeat([0.3, 0.9], 13), source="example"))
    >>> isinstance(choice, ForceLawChoice), choice.kind, choice.forces, choice.keeps_law
    (True, 'stretched', 2, False)
    """

    kind: str
    forces: int
    held_out_with_law: float
    held_out_force_free: float
    keeps_law: bool
    hold: dict
    note: str


def choose_force_law(data: Measurements, kind: str = "stretched") -> ForceLawChoice:
    """Keep a force law only where data at several forces support it out of sample.

    Each force is predicted by a fit to the other forces, once with the model's force law and once with
    its exponent held at 0; the law is kept only if its held-out error is the smaller. With one force
    the question cannot be asked, and the force-free law is kept: a person's data at one force cannot
    tell how their friction depends on force.

    Parameters
    ----------
    data : Measurements
        The points (:func:`read_measurements`), with ``force_n`` where several forces were used.
    kind : str
        A model with a force exponent (``stretched``).

    Returns
    -------
    ForceLawChoice
        The two held-out errors, the choice and the words for it.

    Raises
    ------
    ModelError
        A model without a force law to choose, or data it cannot be fitted to.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> force = np.repeat([0.3, 0.9], 13)
    >>> ratio = 0.1 + 0.9 * np.exp(-0.5 * (amplitude / 2.5) ** 2)  # no force dependence
    >>> choice = choose_force_law(Measurements(amplitude, ratio, force, source="example"))
    >>> choice.keeps_law, choice.held_out_force_free < choice.held_out_with_law
    (False, True)
    """
    if kind not in FORCE_LAW_PARAMETER:
        raise ModelError(f"the {kind} model has no force exponent to choose: choose a force law for "
                         f"{', '.join(FORCE_LAW_PARAMETER)}")
    parameter = FORCE_LAW_PARAMETER[kind]
    free = {parameter: 0.0}
    count = _distinct_forces(data)
    if count < 2:
        return ForceLawChoice(kind, count, math.nan, math.nan, False, free,
                              "1 force: how friction depends on force cannot be told from these data; the force-free "
                              f"law is kept ({parameter} 0)")
    groups = _forces(data)
    with_law = _held_out_rms(data, kind, groups)
    force_free = _held_out_rms(data, kind, groups, free)
    how = "fitted from the others" if count >= 3 else "at its assumed value"
    errors = (f"each force predicted from the other{'s' if count >= 3 else ''}: {with_law:.3f} rms with the law "
              f"(exponent {how}), {force_free:.3f} without")
    if with_law < force_free:
        return ForceLawChoice(kind, count, with_law, force_free, True, {},
                              f"{count} forces: the force law is kept, as it predicts forces it did not see better "
                              f"({errors})")
    return ForceLawChoice(kind, count, with_law, force_free, False, free,
                          f"{count} forces: the force law predicts forces it did not see no better than ignoring "
                          f"force, so the force cannot be told from these data and the force-free law is kept "
                          f"({errors})")


def compare_models(data: Measurements, kinds: tuple[str, ...] = COMPARED_MODELS) -> list[Fit]:
    """Every model fitted and cross-validated, best first.

    By leave-one-force-out RMS when the data hold three forces or more, else by k-fold RMS (within each
    force); :func:`selection_note` says which and why. Models that cannot be fitted to these data are
    left out.

    Parameters
    ----------
    data : Measurements
        The points (:func:`read_measurements`).
    kinds : tuple of str
        The models to compare (by default all).

    Returns
    -------
    list of Fit
        Best first.

    Raises
    ------
    ModelError
        When no model can be fitted to the data.

    Examples
    --------
    >>> from importlib.resources import files
    >>> from ultraglide import read_measurements
    >>> data = read_measurements(files("ultraglide.apps.data") / "monnoyer2018-fit.csv")
    >>> [fit.kind for fit in compare_models(data, ("exponential", "table"))][0]
    'exponential'
    """
    fits = []
    for kind in kinds:
        try:
            fits.append(fit_model(data, kind, cross_validate=True))
        except ModelError:
            continue
    return rank_fits(fits, data)


def rank_fits(fits: list[Fit], data: Measurements) -> list[Fit]:
    """Fits of ``data`` best first, as :func:`compare_models` ranks them: by leave-one-force-out RMS with three
    forces or more, else by k-fold RMS; a fit without that error last.

    Parameters
    ----------
    fits : list of Fit
        Fits of ``data``, cross-validated (``fit_model(..., cross_validate=True)``).
    data : Measurements
        The points they were fitted to (their forces decide the error ranked by).

    Returns
    -------
    list of Fit
        The same fits, best first.

    Examples
    --------
    Monnoyer et al.'s fitted curve: their law ranks before a table of its points:

    >>> from importlib.resources import files
    >>> from ultraglide import read_measurements
    >>> data = read_measurements(files("ultraglide.apps.data") / "monnoyer2018-fit.csv")
    >>> fits = [fit_model(data, kind, cross_validate=True) for kind in ("table", "exponential")]
    >>> [fit.kind for fit in rank_fits(fits, data)]
    ['exponential', 'table']
    """
    ranked_by = "leave_one_force_out" if _distinct_forces(data) >= 3 else "k_fold"

    def score(fit: Fit) -> float:
        value = fit.cross_validation.get(ranked_by, math.nan)
        return math.inf if math.isnan(value) else value
    return sorted(fits, key=score)


def bootstrap_errors(data: Measurements, kind: str, samples: int = BOOTSTRAP_SAMPLES, seed: int = 0,
                     hold: dict[str, float] | None = None) -> dict[str, dict[str, float]]:
    """Bootstrap standard errors of each fitted parameter.

    ``points`` (points resampled with replacement) and, with three groups or more, ``force`` and
    ``participant`` (whole groups resampled, which keeps what the points of one finger or one force share).
    A resample the model cannot be fitted to is skipped; a parameter free in fewer than half the resamples
    gets no value.

    Parameters
    ----------
    data : Measurements
    kind : str
        The model (``table`` has no parameters: {}).
    samples : int
        Resamples per scheme.
    seed : int
        The random generator's seed.
    hold : dict of str to float, optional
        Parameters held at these values instead of fitted.

    Returns
    -------
    dict of str to dict of str to float
        Per scheme, each parameter's standard error in its own unit (µm peak-to-peak for a scale).

    Examples
    --------
    A Gaussian law with a 2.5 µm scale, 0.01 of noise: the scale's error is a fraction of a µm:

    >>> import numpy as np
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> noise = np.random.default_rng(1).normal(0.0, 0.01, 26)
    >>> data = Measurements(amplitude, np.exp(-(amplitude / 2.5) ** 2) + noise, np.repeat([0.3, 0.9], 13), "example")
    >>> errors = bootstrap_errors(data, "stretched", samples=10, hold={"force_exponent": 0.0})
    >>> list(errors), 0.0 < errors["points"]["scale_um_pp"] < 0.2
    (['points'], True)
    """
    if kind == "table" or samples < 2:
        return {}
    return _bootstrap_errors(data, kind, samples, seed, hold, _full_optimum(data, kind, hold))


def _bootstrap_errors(data: Measurements, kind: str, samples: int, seed: int, hold: dict[str, float] | None,
                      near: _Optimum | None) -> dict[str, dict[str, float]]:
    """:func:`bootstrap_errors`, each refit starting from ``near`` (the full fit's optimum, about which
    the resamples' estimates spread)."""
    if kind == "table" or samples < 2:
        return {}
    rng = np.random.default_rng(seed)
    schemes: list[tuple[str, np.ndarray]] = [("points", np.arange(len(data)))]
    if _distinct_forces(data) >= MIN_BOOTSTRAP_GROUPS:
        schemes.append(("force", _forces(data)))
    if data.participant is not None and len(np.unique(data.participant)) >= MIN_BOOTSTRAP_GROUPS:
        schemes.append(("participant", data.participant))
    result = {}
    for scheme, groups in schemes:
        names = np.unique(groups)
        members = [np.flatnonzero(groups == name) for name in names]
        values: dict[str, list[float]] = {}
        for _ in range(samples):
            drawn = rng.integers(0, len(names), len(names))
            pick = np.concatenate([members[k] for k in drawn])
            try:
                fitted = _fitted_values(data.subset(pick), kind, hold, near)
            except ModelError:
                continue
            for key, value in fitted.items():
                values.setdefault(key, []).append(value)
        result[scheme] = {key: float(np.std(found, ddof=1)) for key, found in values.items()
                          if len(found) >= max(2, samples // 2)}
    return result


def fit_summary(fit: Fit) -> dict:
    """A fit as plain values (JSON and the calibration file's [fit] table).

    Parameters
    ----------
    fit : Fit

    Returns
    -------
    dict
        The model, its description, source, points, forces (N), force law, the selection note, the noise, the
        parameters with their standard errors and allowed ranges, residuals and cross-validation errors.

    Examples
    --------
    >>> import json
    >>> import numpy as np
    >>> from ultraglide.render.physics.fitting import fit_model
    >>> from ultraglide.render.physics.measurements import Measurements
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
    >>> data = Measurements(amplitude, np.exp(-(amplitude / 2.5) ** 2), np.repeat([0.3, 0.9], 13), source="example")
    >>> summary = fit_summary(fit_model(data, "stretched"))
    >>> scale = summary["parameters"]["scale_um_pp"]["value"]
    >>> summary["model"], summary["points"], summary["forces_n"], round(scale, 6)
    ('stretched', 26, [0.3, 0.9], 2.5)
    >>> json.loads(json.dumps(summary)) == summary
    True
    """
    forces = [float(f) for f in np.unique(_forces(fit.data))]
    return {
        "model": fit.kind,
        "description": fit.model.describe(),
        "source": str(fit.data.source),
        "points": len(fit.data),
        "forces_n": forces,
        "force_range_n": [min(forces), max(forces)],
        "force_law": fit.model.force_law(),
        "selection": selection_note(fit.data),
        "noise": fit.data.noise_words(),
        "bootstrap_stderr": fit.bootstrap,
        "parameters": {p.spec.key: {"value": p.value, "stderr": None if math.isnan(p.stderr) else p.stderr,
                                    "fixed": p.fixed, "allowed": [p.spec.low, p.spec.high]}
                       for p in fit.parameters},
        "rms_residual": fit.rms_residual,
        "max_abs_residual": fit.max_abs_residual,
        "cross_validation_rms": dict(fit.cross_validation),
        "warnings": fit.warnings(),
    }
