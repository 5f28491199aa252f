"""Calibration files that act as models, and the one place that turns a ``--model`` value into a model.
A fitted model remembers the forces it was fitted on (:class:`FitRange`, also in the calibration
file), and says so once when it is used outside them.

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
    forces_n = [0.5]
    force_range_n = [0.5, 0.5]
    force_law = "s ∝ F^0.333, assumed from the paper's detachment law ..."
    ...

Every command that takes ``--model`` accepts such a file (see :func:`load_model`). Reading one is
typed: each model's parameters are listed in :data:`PARAMETERS` with their allowed ranges, and a
missing, unknown, non-numeric or out-of-range parameter is refused with a line naming the key.

The fitting itself is :mod:`ultraglide.render.physics.fitting`; this module re-exports its names.
"""

from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path
from typing import TYPE_CHECKING

import tomli_w
from ultraglide.render.physics.default_model import DEFAULT_MODEL
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import FingerParams
from ultraglide.render.physics.fitting import (
    BOOTSTRAP_SAMPLES,
    COMPARED_MODELS,
    FORCE_LAW_PARAMETER,
    K_FOLDS,
    MIN_BOOTSTRAP_GROUPS,
    ForceLawChoice,
    bootstrap_errors,
    choose_force_law,
    compare_models,
    cross_validation_errors,
    fit_model,
    fit_range,
    fit_summary,
    k_fold_groups,
    rank_fits,
    selection_note,
)
from ultraglide.render.physics.friction_models import (
    ExponentialModel,
    FitRange,
    FrictionModel,
    PaperModel,
    StretchedExponentialModel,
    TableModel,
)
from ultraglide.render.physics.measurements import read_measurements
from ultraglide.render.physics.model_parameters import (
    MODEL_NAMES,
    OPTIONAL_KEYS,
    PARAMETERS,
    Fit,
    Parameter,
    ParameterSpec,
    build_model,
    model_kind,
)
from ultraglide.render.physics.squeeze_film import (
    SqueezeFilmModel,
)

from ultraglide.inputs import parse_toml, read_input, shown

if TYPE_CHECKING:
    from ultraglide.render.physics.dynamics_fit import DynamicsFit
    from ultraglide.render.physics.speed_law import SpeedLaw

CALIBRATION_VERSION = 1


def calibration_toml(fit: Fit, participant: str | None = None, procedure: str | None = None,
                     dynamics: DynamicsFit | None = None, recording: str | None = None,
                     speed_law: SpeedLaw | None = None) -> str:
    """The calibration file's text for a fit (``ultraglide calibrate`` writes it atomically).

    Parameters
    ----------
    fit : Fit
        A fit (:func:`fit_model`).
    participant : str, optional
        Whose finger it is (an on-plate calibration's id).
    procedure : str, optional
        How the points were measured, in words.
    dynamics : DynamicsFit, optional
        The friction's dynamics fitted from the same session's recording
        (:func:`~ultraglide.render.physics.dynamics_fit.fit_dynamics`): written as ``[dynamics]``; where they
        resolve a time constant, the file reads back as a :class:`DynamicFrictionModel` with them.
    recording : str, optional
        The recording's file name (beside the calibration), for ``calibrate --compare`` in time.
    speed_law : SpeedLaw, optional
        The reduction's speed law fitted with it (:func:`~ultraglide.render.physics.speed_fit.fit_speed_law`; the
        fit's parameters are then those at its reference speed): written as ``[speed]``.

    Returns
    -------
    str
        TOML that :func:`read_calibration` reads back into the fitted model.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from importlib.resources import files
    >>> fit = fit_model(read_measurements(files("ultraglide.apps.data") / "monnoyer2018-fit.csv"), "exponential")
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "finger.toml"
    >>> _ = path.write_text(calibration_toml(fit, participant="P01"))
    >>> type(read_calibration(path)).__name__
    'ExponentialModel'
    """
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
            "force_range_n": summary["force_range_n"],
            "force_law": summary["force_law"],
            "rms_residual": fit.rms_residual,
            "max_abs_residual": fit.max_abs_residual,
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        },
    }
    if fit.parameters:
        document["fit"]["stderr"] = {p.spec.key: p.stderr for p in fit.parameters if not p.fixed}
    if fit.bootstrap:
        document["fit"]["bootstrap_stderr"] = {scheme: dict(values) for scheme, values in fit.bootstrap.items()
                                               if values}
    if summary["noise"]:
        document["fit"]["noise"] = summary["noise"]
    if fit.cross_validation:
        document["fit"]["cross_validation_rms"] = dict(fit.cross_validation)
    if fit.warnings():
        document["fit"]["warnings"] = fit.warnings()
    if participant is not None:
        document["fit"]["participant"] = str(participant)  # an id (P01), text as experiments keep it
    if procedure:
        document["fit"]["procedure"] = procedure
    if dynamics is not None:
        document["dynamics"] = dynamics_table(dynamics, recording)
    if speed_law is not None and speed_law.exponent > 0.0:
        document["speed"] = {"exponent": speed_law.exponent, "reference_speed_mm_s": speed_law.reference_speed_mm_s,
                             "source": speed_law.source}
    return tomli_w.dumps(document)


def dynamics_table(fit: DynamicsFit, recording: str | None = None) -> dict:
    """The ``[dynamics]`` table of a calibration file.

    Parameters
    ----------
    fit : DynamicsFit
        The dynamics fitted from a recording (:func:`~ultraglide.render.physics.dynamics_fit.fit_dynamics`).
    recording : str, optional
        The recording's file name.

    Returns
    -------
    dict
        ``fitted`` (whether the file's model has dynamics), the four parameters where it has (times s, speed
        mm/s), ``source``, and for ``onset`` and ``recovery`` the fitted value, its standard error and 95 %
        ``range_s``, the edges and a note; the speed law's note, the sensors assumed, the resolution (s) and the
        recording.

    Examples
    --------
    >>> from ultraglide.render.physics.dynamics_fit import example_recording, find_steps, fit_dynamics
    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> recording = example_recording()
    >>> table = dynamics_table(fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20))
    >>> table["fitted"], table["source"], table["onset"]["edges"], table["speed_exponent"]
    (True, 'fitted on the plate, 12 edges (6 onsets, 6 recoveries)', 6, 0.5)
    """
    table = {"fitted": fit.dynamics is not None}
    if fit.dynamics is not None:
        table.update(fit.dynamics.parameters())
        table["source"] = f"{fit.dynamics.source} ({fit.onset.edges} onsets, {fit.recovery.edges} recoveries)"
    else:
        table["source"] = "not fitted: the finger's friction cannot be told apart from instantaneous at this sampling"
    for tc in (fit.onset, fit.recovery):
        entry = {"edges": tc.edges, "resolved": tc.resolved, "note": tc.note}
        for key, value in (("fitted_s", tc.fitted_s), ("stderr_s", tc.stderr_s)):
            if math.isfinite(value):
                entry[key] = value
        if math.isfinite(tc.low_s) and math.isfinite(tc.high_s):
            entry["range_s"] = [tc.low_s, tc.high_s]
        if math.isfinite(tc.speed_mm_s):
            entry["speed_mm_s"] = tc.speed_mm_s
        table[tc.kind] = entry
    table["speed_law"] = fit.speed_exponent_note
    table["sensors"] = fit.lag.words()
    table["resolution_s"] = fit.lag.resolution_s
    if fit.notes:
        table["notes"] = list(fit.notes)
    if recording:
        table["recording"] = recording
    return table


def read_calibration(path: str | Path) -> FrictionModel:
    """A model from a calibration file (``ultraglide calibrate``, :func:`calibration_toml`).

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.toml`` calibration file.

    Returns
    -------
    FrictionModel
        The model with the fitted parameters.

    Raises
    ------
    ModelError
        What is wrong with the file, in one line.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from importlib.resources import files
    >>> fit = fit_model(read_measurements(files("ultraglide.apps.data") / "monnoyer2018-fit.csv"), "stretched")
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "finger.toml"
    >>> _ = path.write_text(calibration_toml(fit))
    >>> type(read_calibration(path)).__name__
    'StretchedExponentialModel'
    """
    path = Path(path)
    data = read_input(path, "calibration file", ModelError)
    document = parse_toml(data, str(path), ModelError, what="calibration file")
    return calibration_from_document(document, str(path))


def calibration_from_document(document: dict, where: str) -> FrictionModel:
    """The typed reading of a calibration file's parsed TOML (see :func:`read_calibration`).

    Parameters
    ----------
    document : dict
        The parsed TOML.
    where : str
        What to name in a refusal (the file).

    Returns
    -------
    FrictionModel
        With its fitted force range (:attr:`FrictionModel.fitted`) where the file gives one.

    Raises
    ------
    ModelError
        Not a calibration file of this version, an unknown model, or a parameter missing or out of range.

    Examples
    --------
    >>> calibration_from_document({"ultraglide_calibration": 1, "model": "exponential",
    ...                             "parameters": {"tau_um_zp": 1.0}}, "cal.toml")
    ExponentialModel(tau_um_zp=1.0)
    >>> calibration_from_document({}, "cal.toml")                     # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: cal.toml: not an ultraglide calibration file of version 1 ...
    """
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
        raise ModelError(f"{where}: unknown parameter {shown(unknown[0])} for the {kind} model; "
                         f"expected {', '.join(specs)}")
    values = {}
    for key, spec in specs.items():
        if key not in parameters:
            if spec.optional:
                values[key] = spec.default
                continue
            raise ModelError(f"{where}: parameter {key} is missing (allowed range [{spec.low:g}, {spec.high:g}]"
                             f"{spec.unit})")
        values[key] = spec.check(parameters[key], where)
    fitted = _fitted_forces(document.get("fit"), where)
    dynamics = _fitted_dynamics(document.get("dynamics"), where)
    speed_law = _speed_law(document.get("speed"), where)
    try:
        model = build_model(kind, values)
    except ValueError as error:  # FingerParams: a combination it refuses
        raise ModelError(f"{where}: {str(error).splitlines()[0]}") from None
    model.fitted = fitted
    if speed_law is not None:
        from ultraglide.render.physics.speed_law import SpeedLawModel

        model = SpeedLawModel(model, speed_law)
    if dynamics is not None:
        from ultraglide.render.physics.dynamics import DynamicFrictionModel

        model = DynamicFrictionModel(model, dynamics)
    return model


DYNAMICS_KEYS = ("onset_s", "recovery_s", "reference_speed_mm_s", "speed_exponent")


def _fitted_dynamics(table, where: str):
    """The :class:`FrictionDynamics` a calibration file's ``[dynamics]`` holds where ``fitted = true``, checked;
    None when it has none (files written before dynamics were fitted, or dynamics not resolved)."""
    if table is None:
        return None
    if not isinstance(table, dict) or not isinstance(table.get("fitted"), bool):
        raise ModelError(f"{where}: [dynamics] must be a table with fitted = true or false")
    if not table["fitted"]:
        return None
    from ultraglide.render.physics.dynamics import FrictionDynamics

    values = {}
    for key in DYNAMICS_KEYS:
        value = table.get(key)
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise ModelError(f"{where}: [dynamics] {key} must be a number (fitted = true)")
        values[key] = float(value)
    source = table.get("source")
    try:
        return FrictionDynamics(**values, source=source[:200] if isinstance(source, str) else "")
    except ModelError as error:
        raise ModelError(f"{where}: [dynamics] {error}") from None


SPEED_KEYS = ("exponent", "reference_speed_mm_s", "source")


def _speed_law(table, where: str):
    """The :class:`SpeedLaw` a calibration file's ``[speed]`` table gives (``exponent`` 0-1; optional
    ``reference_speed_mm_s``, 22 mm/s by default, and ``source`` in words), checked; None when it has none or its
    exponent is 0. ``calibrate`` writes it where points at several speeds support a law
    (:mod:`~ultraglide.render.physics.speed_fit`); it may also be written by hand."""
    if table is None:
        return None
    from ultraglide.render.physics.dynamics import REFERENCE_SPEED_MM_S
    from ultraglide.render.physics.speed_law import SpeedLaw

    if not isinstance(table, dict):
        raise ModelError(f"{where}: [speed] must be a table: exponent = S (0-1), optionally reference_speed_mm_s")
    unknown = sorted(set(table) - set(SPEED_KEYS))
    if unknown:
        raise ModelError(f"{where}: unknown key {shown(unknown[0])} in [speed]; expected {', '.join(SPEED_KEYS)}")
    if "exponent" not in table:
        raise ModelError(f"{where}: [speed] needs exponent = S (0-1, the reduction's speed exponent)")
    source = table.get("source", "")
    if not isinstance(source, str):
        raise ModelError(f"{where}: [speed] source must be text")
    try:
        law = SpeedLaw(table["exponent"], table.get("reference_speed_mm_s", REFERENCE_SPEED_MM_S), source[:200])
    except ModelError as error:
        raise ModelError(f"{where}: [speed] {error}") from None
    return law if law.exponent > 0.0 else None


MAX_FITTED_FORCES = 10_000  # a calibration's data hold at most 100 000 points


def _fitted_forces(fit, where: str) -> FitRange | None:
    """The forces a calibration file says its model was fitted on ([fit] forces_n), checked; None when
    the file does not say (files written before the range was kept)."""
    if not isinstance(fit, dict) or "forces_n" not in fit:
        return None
    forces = fit["forces_n"]
    if (not isinstance(forces, list) or not 1 <= len(forces) <= MAX_FITTED_FORCES
            or not all(isinstance(f, (int, float)) and not isinstance(f, bool) and math.isfinite(f) and 0 < f <= 50
                       for f in forces)):
        raise ModelError(f"{where}: [fit] forces_n must be a list of the forces fitted on, each in (0, 50] N")
    points = fit.get("points", 0)
    points = int(points) if isinstance(points, int) and not isinstance(points, bool) and points >= 0 else 0
    return FitRange(tuple(sorted(float(f) for f in set(forces))), points)


def load_model(spec: str) -> FrictionModel:
    """A friction model by name or file.

    Parameters
    ----------
    spec : str
        ``stretched`` (force-aware, floor 0.10), ``squeeze-film``, ``exponential``,
        ``paper``, ``paper-uniform``, ``table:FILE.csv`` (measured points) or a calibration file
        ``CAL.toml`` (``ultraglide calibrate``: a :class:`DynamicFrictionModel` where its ``[dynamics]`` were fitted
        on the plate; with its ``[speed]`` table, a speed law); ``dynamic`` (``stretched`` with the published
        friction dynamics: :data:`DEFAULT_MODEL`, the default for rendering) or ``dynamic:NAME`` (any of these with
        them); ``speed:S:NAME`` (any of these whose
        settled reduction weakens with sliding speed, exponent S in 0-1, assumed:
        :mod:`~ultraglide.render.physics.speed_law`).

    Returns
    -------
    FrictionModel

    Raises
    ------
    ModelError
        An unknown name, or a file that cannot be used, in one line.

    Examples
    --------
    >>> model = load_model("exponential")
    >>> round(float(model.amplitude_um_pp(0.5, 0.5).amplitude_um_pp), 2)   # µm p-p to halve the friction
    3.11
    """
    if spec.startswith("speed:"):
        return _with_speed_law(spec)
    if spec == "dynamic" or spec.startswith("dynamic:"):
        from ultraglide.render.physics.dynamics import DynamicFrictionModel

        inner = spec.removeprefix("dynamic").removeprefix(":") or "stretched"
        if inner == "dynamic" or inner.startswith("dynamic:"):
            raise ModelError(f"a dynamic model wraps a static one: {spec!r} wraps another dynamic model")
        static = load_model(inner)
        if isinstance(static, DynamicFrictionModel):
            whose = "its own, fitted on the plate" if static.dynamics.source else "the published ones"
            raise ModelError(f"{inner} has friction dynamics already ({whose}): give --model {inner} (dynamic: "
                             "adds the published ones to a static model)")
        return DynamicFrictionModel(static)
    if spec == "paper":
        return PaperModel()
    if spec == "paper-uniform":
        return PaperModel(FingerParams(contact="uniform"))
    if spec == "exponential":
        return ExponentialModel()
    if spec == "stretched":
        return StretchedExponentialModel()
    if spec == "squeeze-film":
        return SqueezeFilmModel()
    if spec.startswith("table:"):
        return TableModel(read_measurements(spec.removeprefix("table:")))
    if spec.endswith(".toml"):
        return read_calibration(spec)
    raise ModelError(
        f"unknown model {spec!r}; use stretched, squeeze-film, exponential, paper, paper-uniform, table:FILE.csv, "
        "CAL.toml, dynamic[:NAME] (one of these with the finger's friction dynamics) or speed:S:NAME (with the "
        "reduction weakening with sliding speed)"
    )


SPEED_SPEC = "speed:S:NAME, S the reduction's speed exponent in 0-1 (0: none), NAME any model"


def _with_speed_law(spec: str) -> FrictionModel:
    """``speed:S:NAME``: the model NAME with the settled speed law of exponent S (a dynamic NAME keeps its
    dynamics around the static model with the law)."""
    from ultraglide.render.physics.dynamics import DynamicFrictionModel
    from ultraglide.render.physics.speed_law import SpeedLaw, SpeedLawModel

    _, _, rest = spec.partition(":")
    exponent, colon, inner = rest.partition(":")
    if not colon or not inner:
        raise ModelError(f"{spec!r}: give {SPEED_SPEC} (e.g. speed:0.5:stretched)")
    try:
        value = float(exponent)
    except ValueError:
        raise ModelError(f"{spec!r}: {exponent!r} is not a number; give {SPEED_SPEC}") from None
    try:
        law = SpeedLaw(value)
    except ModelError as error:
        raise ModelError(f"{spec!r}: {error}") from None
    model = load_model(inner)
    if getattr(model, "speed_law", None) is not None:
        raise ModelError(f"{spec!r}: {inner} has a speed law already (give it once)")
    if isinstance(model, DynamicFrictionModel):
        return DynamicFrictionModel(SpeedLawModel(model.static, law), model.dynamics)
    return SpeedLawModel(model, law)


__all__ = [  # the calibration's names, the fitting's and the parameters' (one import for the commands)
    "BOOTSTRAP_SAMPLES", "CALIBRATION_VERSION", "COMPARED_MODELS", "DEFAULT_MODEL", "K_FOLDS", "MAX_FITTED_FORCES",
    "MIN_BOOTSTRAP_GROUPS", "MODEL_NAMES", "OPTIONAL_KEYS", "PARAMETERS", "Fit", "Parameter", "ParameterSpec",
    "FORCE_LAW_PARAMETER", "ForceLawChoice", "bootstrap_errors", "build_model", "choose_force_law",
    "calibration_from_document", "calibration_toml", "compare_models", "dynamics_table",
    "cross_validation_errors", "fit_model", "fit_range", "fit_summary", "k_fold_groups", "load_model", "model_kind",
    "rank_fits", "read_calibration", "selection_note",
]
