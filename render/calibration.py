"""Fitting friction models to measured points, and calibration files that act as models.

A calibration file is TOML::

    ultraglide_calibration = 1
    model = "exponential"
    [parameters]
    tau_um_zp = 1.32
    [fit]
    source = "monnoyer2018-fit.csv"
    points = 11
    rms_residual = 0.0003

Every command that takes ``--model`` accepts such a file (see :func:`load_model`).
"""

from __future__ import annotations

import datetime as _dt
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w
from ultraglide.render.errors import ModelError
from ultraglide.render.fingerprint import FingerParams
from ultraglide.render.friction_models import DEFAULT_FORCE_N, ExponentialModel, FrictionModel, PaperModel, TableModel
from ultraglide.render.measurements import Measurements, read_measurements

CALIBRATION_VERSION = 1
MODEL_NAMES = ("paper", "paper-uniform", "exponential")


@dataclass(frozen=True)
class Fit:
    """A fitted model with its residuals (measured minus modelled ratio) at each point."""

    model: FrictionModel
    residuals: np.ndarray
    data: Measurements

    @property
    def rms_residual(self) -> float:
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def max_abs_residual(self) -> float:
        return float(np.max(np.abs(self.residuals)))


def _forces(data: Measurements) -> np.ndarray:
    return data.force_n if data.force_n is not None else np.full(len(data), DEFAULT_FORCE_N)


def fit_model(data: Measurements, kind: str) -> Fit:
    """Least-squares fit of a model's free parameters to measured points.

    ``exponential`` fits tau (zero-to-peak µm). ``paper`` fits the ridge modulus E_e (which sets
    the detachment amplitude) and the friction exponent n, the two quantities the paper takes
    from other work.
    """
    from scipy.optimize import least_squares  # only fitting needs it; keep model loading light

    forces = _forces(data)
    if kind == "exponential":
        def residual(x):
            return data.relative_friction - ExponentialModel(x[0]).relative_friction(data.amplitude_um_pp)
        result = least_squares(residual, x0=[1.32], bounds=([0.05], [50.0]))
        model: FrictionModel = ExponentialModel(float(result.x[0]))
    elif kind in ("paper", "paper-uniform"):
        contact = "uniform" if kind == "paper-uniform" else "hertz"

        def make(x):
            return PaperModel(FingerParams(youngs_modulus_pa=x[0] * 1e6, friction_exponent=x[1],
                                           contact=contact))

        def residual(x):
            return data.relative_friction - make(x).relative_friction(data.amplitude_um_pp, forces)
        result = least_squares(residual, x0=[1.0, 2.0 / 3.0], bounds=([0.01, 0.0], [100.0, 0.99]),
                               diff_step=1e-3)
        model = make(result.x)
    else:
        raise ModelError(f"cannot fit model {kind!r}; choose one of: {', '.join(MODEL_NAMES)}")
    return Fit(model, residual(result.x), data)


def calibration_toml(fit: Fit) -> str:
    """The calibration file's text for a fit (``ultraglide calibrate`` writes it atomically)."""
    document = {
        "ultraglide_calibration": CALIBRATION_VERSION,
        "model": fit.model.name if fit.model.name != "paper" else
        ("paper-uniform" if fit.model.params.contact == "uniform" else "paper"),
        "parameters": fit.model.parameters(),
        "fit": {
            "source": str(fit.data.source),
            "points": len(fit.data),
            "rms_residual": fit.rms_residual,
            "max_abs_residual": fit.max_abs_residual,
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        },
    }
    return tomli_w.dumps(document)


def read_calibration(path: str | Path) -> FrictionModel:
    """A model from a calibration file; :class:`ModelError` says what is wrong with it."""
    path = Path(path)
    try:
        with path.open("rb") as stream:
            document = tomllib.load(stream)
    except FileNotFoundError:
        raise ModelError(f"{path}: no such calibration file") from None
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ModelError(f"{path}: not a readable calibration file ({error})") from None
    version = document.get("ultraglide_calibration")
    if version != CALIBRATION_VERSION:
        raise ModelError(f"{path}: not an ultraglide calibration file of version {CALIBRATION_VERSION}"
                         " (make one with `ultraglide calibrate`)")
    kind = document.get("model")
    parameters = document.get("parameters", {})
    try:
        if kind == "exponential":
            return ExponentialModel(float(parameters["tau_um_zp"]))
        if kind in ("paper", "paper-uniform"):
            return PaperModel(FingerParams(
                youngs_modulus_pa=float(parameters["youngs_modulus_pa"]),
                friction_exponent=float(parameters["friction_exponent"]),
                contact="uniform" if kind == "paper-uniform" else "hertz",
            ))
    except KeyError as error:
        raise ModelError(f"{path}: parameter {error.args[0]} is missing") from None
    except (TypeError, ValueError) as error:
        raise ModelError(f"{path}: bad parameter ({error})") from None
    raise ModelError(f"{path}: unknown model {kind!r}; expected one of {', '.join(MODEL_NAMES)}")


def load_model(spec: str) -> FrictionModel:
    """A model by name or file: ``paper``, ``paper-uniform``, ``exponential``,
    ``table:FILE.csv`` or a calibration file ``CAL.toml``."""
    if spec == "paper":
        return PaperModel()
    if spec == "paper-uniform":
        return PaperModel(FingerParams(contact="uniform"))
    if spec == "exponential":
        return ExponentialModel()
    if spec.startswith("table:"):
        return TableModel(read_measurements(spec.removeprefix("table:")))
    if spec.endswith(".toml"):
        return read_calibration(spec)
    raise ModelError(
        f"unknown model {spec!r}; use paper, paper-uniform, exponential, table:FILE.csv or CAL.toml"
    )
