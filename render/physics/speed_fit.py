"""The reduction's speed law fitted from points measured at several sliding speeds, kept only where it predicts
points it did not see better than ignoring speed.

The law is :class:`~ultraglide.render.physics.speed_law.SpeedLaw`'s: a static model evaluated at the effective
amplitude a (v_ref / v)^s. Given points with their speeds (a measurement CSV's ``speed_mm_s`` column: sessions of
``calibrate --device`` at several ``--slide-speed-mm-s``, joined), the exponent s is the one in 0-1 whose
effective amplitudes the static model fits best (the model's own parameters refitted at each s), with a 95 %
interval from the residual sum of squares' profile (n ln(RSS(s) / RSS(ŝ)) within 3.84, the likelihood-ratio
bound for Gaussian errors). Whether the law is kept is judged out of sample, as the force law is
(:func:`~ultraglide.render.physics.fitting.choose_force_law`): with three speeds or more each speed is predicted
from the others (s and the model fitted on them); with two, points are held out in folds drawn within each
speed; the law is kept only where its held-out error is the smaller.

Examples
--------
Points of a stretched law whose reduction weakens with speed as s = 0.5, at 25 and 100 mm/s:

>>> import numpy as np
>>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
>>> from ultraglide.render.physics.measurements import Measurements
>>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 2)
>>> speed = np.repeat([25.0, 100.0], 13)
>>> ratio = StretchedExponentialModel().relative_friction(amplitude * (22.0 / speed) ** 0.5, 0.5)
>>> fitted = fit_speed_law(Measurements(amplitude, ratio, np.full(26, 0.5), "by hand", speed_mm_s=speed))
>>> round(fitted.exponent, 2), fitted.kept
(0.5, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fitting import K_FOLDS, folds_within
from ultraglide.render.physics.measurements import Measurements
from ultraglide.render.physics.speed_law import EXPONENT_RANGE, FITTED, SpeedLaw

LIKELIHOOD_95 = 3.84  # chi-squared with one degree of freedom, 95 %
EXPONENT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class SpeedLawFit:
    """The speed law fitted to points at several speeds, and whether it is kept.

    Attributes
    ----------
    kind : str
        The static model it was fitted with.
    speeds_mm_s : tuple of float
        The distinct sliding speeds of the points, mm/s.
    exponent : float
        The fitted s (0-1); NaN with one speed.
    interval : tuple of float
        Its 95 % interval (profile likelihood), within 0-1.
    reference_speed_mm_s : float
        v_ref, mm/s.
    held_out_with_law, held_out_without : float
        RMS error in relative friction predicting points held out (by speed, or in folds within each speed), with
        s fitted on the rest and with s held at 0.
    kept : bool
        True only when the law's held-out error is the smaller.
    points : int
        How many points.
    note : str
        The choice in words.

    Examples
    --------
    >>> fit = SpeedLawFit("stretched", (25.0,), math.nan, (math.nan, math.nan), 22.0, math.nan, math.nan, False, 13,
    ...                   "1 speed")
    >>> fit.law() is None
    True
    """

    kind: str
    speeds_mm_s: tuple[float, ...]
    exponent: float
    interval: tuple[float, float]
    reference_speed_mm_s: float
    held_out_with_law: float
    held_out_without: float
    kept: bool
    points: int
    note: str

    def law(self) -> SpeedLaw | None:
        """The kept law, with its source in words (a calibration file's ``[speed]`` table); None when not kept.

        Examples
        --------
        >>> fit = SpeedLawFit("stretched", (25.0, 100.0), 0.5, (0.45, 0.55), 22.0, 0.01, 0.05, True, 26, "kept")
        >>> fit.law().exponent, fit.law().source
        (0.5, 'fitted to 26 points at 25 and 100 mm/s, 95 % interval 0.45-0.55')
        """
        if not self.kept:
            return None
        low, high = self.interval
        return SpeedLaw(round(self.exponent, 3), self.reference_speed_mm_s,
                        f"{FITTED}{self.points} points at {_speeds_words(self.speeds_mm_s)}, 95 % interval "
                        f"{low:.2g}-{high:.2g}")

    def summary(self) -> dict:
        """JSON-ready (NaN as None).

        Examples
        --------
        >>> SpeedLawFit("stretched", (25.0,), math.nan, (math.nan, math.nan), 22.0, math.nan, math.nan, False, 13,
        ...             "1 speed").summary()["exponent"] is None
        True
        """
        def number(value):
            return None if not math.isfinite(value) else round(float(value), 6)
        return {"model": self.kind, "speeds_mm_s": list(self.speeds_mm_s), "exponent": number(self.exponent),
                "interval": [number(v) for v in self.interval], "reference_speed_mm_s": self.reference_speed_mm_s,
                "held_out_rms_with_law": number(self.held_out_with_law),
                "held_out_rms_without": number(self.held_out_without), "kept": self.kept, "note": self.note}


def _speeds_words(speeds) -> str:
    words = [f"{v:g}" for v in speeds]
    return (", ".join(words[:-1]) + " and " + words[-1] if len(words) > 1 else words[0]) + " mm/s"


def at_exponent(data: Measurements, exponent: float, reference_speed_mm_s: float) -> Measurements:
    """The points with each amplitude made effective for its speed, a (v_ref / v)^s (µm p-p): what a static model
    fitted to them sees. They are then points at v_ref, so they carry no speeds.

    Parameters
    ----------
    data : Measurements
        Points with ``speed_mm_s``.
    exponent, reference_speed_mm_s : float
        s, and v_ref (mm/s).

    Returns
    -------
    Measurements

    Examples
    --------
    >>> import numpy as np
    >>> data = Measurements(np.array([0.0, 4.0]), np.array([1.0, 0.5]), None, "m", speed_mm_s=np.array([88.0, 88.0]))
    >>> at_exponent(data, 0.5, 22.0).amplitude_um_pp.tolist()          # (22 / 88)^0.5 = 1/2
    [0.0, 2.0]
    """
    law = SpeedLaw(exponent, reference_speed_mm_s)
    amplitude = law.effective_amplitude_um_pp(data.amplitude_um_pp, data.speed_mm_s)
    return Measurements(np.asarray(amplitude, dtype=float), data.relative_friction, data.force_n, data.source,
                        data.participant)


def _rss(data: Measurements, kind: str, exponent: float, reference: float) -> float:
    from ultraglide.render.physics.fitting import fit_model

    fit = fit_model(at_exponent(data, exponent, reference), kind)
    return float(np.sum(fit.residuals ** 2))


def _best_exponent(data: Measurements, kind: str, reference: float) -> tuple[float, float]:
    """(s, RSS at s): the bounded minimum of the RSS over 0-1, the ends compared too (a law flat at an end)."""
    from scipy.optimize import minimize_scalar

    found = minimize_scalar(lambda s: _rss(data, kind, s, reference), bounds=EXPONENT_RANGE, method="bounded",
                            options={"xatol": EXPONENT_TOLERANCE})
    candidates = [(float(found.x), float(found.fun))]
    candidates += [(end, _rss(data, kind, end, reference)) for end in EXPONENT_RANGE]
    return min(candidates, key=lambda pair: pair[1])


def _interval(data: Measurements, kind: str, reference: float, exponent: float, least: float) -> tuple[float, float]:
    """The 95 % profile-likelihood interval of s: where n ln(RSS(s) / RSS(ŝ)) stays within 3.84, each edge found
    by root-finding between ŝ and that end of 0-1 (the end itself where the bound is not crossed)."""
    from scipy.optimize import brentq

    def excess(s: float) -> float:
        return len(data) * math.log(max(_rss(data, kind, s, reference), 1e-300) / max(least, 1e-300)) - LIKELIHOOD_95

    edges = []
    for end in EXPONENT_RANGE:
        if end == exponent or excess(end) <= 0.0:
            edges.append(end)
        else:
            edges.append(float(brentq(excess, min(exponent, end), max(exponent, end), xtol=EXPONENT_TOLERANCE)))
    return edges[0], edges[1]


def _held_out(data: Measurements, kind: str, groups: np.ndarray, reference: float, with_law: bool) -> float:
    """RMS over all points of the residual each gets from a fit to the other groups."""
    from ultraglide.render.physics.fitting import fit_model

    residuals = np.empty(len(data))
    for group in np.unique(groups):
        held = groups == group
        train, test = data.subset(~held), data.subset(held)
        exponent = _best_exponent(train, kind, reference)[0] if with_law else 0.0
        model = fit_model(at_exponent(train, exponent, reference), kind).model
        model._range_said = True  # held-out points may lie outside the training range by design
        effective = at_exponent(test, exponent, reference)
        forces = test.force_n if test.force_n is not None else np.full(len(test), 0.5)
        amplitude = np.minimum(effective.amplitude_um_pp, model.max_amplitude_um_pp)
        residuals[held] = test.relative_friction - model.relative_friction(amplitude, forces)
    return float(np.sqrt(np.mean(residuals ** 2)))


def fit_speed_law(data: Measurements, kind: str = "stretched", reference_speed_mm_s: float = 22.0) -> SpeedLawFit:
    """Fit the reduction's speed exponent to points at several sliding speeds and judge it out of sample (see the
    module docstring).

    Parameters
    ----------
    data : Measurements
        Points with ``speed_mm_s`` (:func:`~ultraglide.render.physics.measurements.read_measurements`).
    kind : str
        The static model fitted at each exponent: ``stretched``, ``exponential``, ``paper`` ... (not ``table``).
    reference_speed_mm_s : float
        v_ref, mm/s: the speed the fitted static model holds at.

    Returns
    -------
    SpeedLawFit

    Raises
    ------
    ModelError
        Points without speeds, a table model, or data the model cannot be fitted to, in one line.

    Examples
    --------
    Points that do not depend on speed: the law is not kept.

    >>> import numpy as np
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> amplitude = np.tile(np.linspace(0.0, 6.0, 13), 3)
    >>> noise = np.random.default_rng(1).normal(0.0, 0.01, 39)
    >>> ratio = StretchedExponentialModel().relative_friction(amplitude, 0.5) + noise
    >>> speed = np.repeat([20.0, 50.0, 120.0], 13)
    >>> data = Measurements(amplitude, ratio, np.full(39, 0.5), "by hand", speed_mm_s=speed)
    >>> fitted = fit_speed_law(data)
    >>> fitted.kept, fitted.interval[0] == 0.0
    (False, True)
    """
    if data.speed_mm_s is None:
        raise ModelError(f"{data.source}: no speed_mm_s column: the speed law is fitted to points measured at "
                         "several sliding speeds")
    if kind == "table":
        raise ModelError("a table model has no parameters to refit at each speed exponent: fit stretched, "
                         "exponential or paper")
    SpeedLaw(0.0, reference_speed_mm_s)  # the reference speed checked
    speeds = tuple(float(v) for v in np.unique(data.speed_mm_s))
    if len(speeds) < 2:
        return SpeedLawFit(kind, speeds, math.nan, (math.nan, math.nan), reference_speed_mm_s, math.nan, math.nan,
                           False, len(data), f"1 speed ({speeds[0]:g} mm/s): how the reduction depends on sliding "
                           "speed cannot be told from these data; no speed law")
    exponent, least = _best_exponent(data, kind, reference_speed_mm_s)
    low, high = _interval(data, kind, reference_speed_mm_s, exponent, least)
    if len(speeds) >= 3:
        groups, how = data.speed_mm_s, "each speed predicted from the others"
    else:
        groups, how = folds_within(data.speed_mm_s, K_FOLDS), f"points held out in {K_FOLDS} folds within each speed"
    with_law = _held_out(data, kind, groups, reference_speed_mm_s, True)
    without = _held_out(data, kind, groups, reference_speed_mm_s, False)
    errors = f"{how}: {with_law:.3f} rms with the law, {without:.3f} without"
    at = f"{len(speeds)} speeds ({_speeds_words(speeds)})"
    if with_law < without:
        note = (f"{at}: the speed law is kept, s = {exponent:.2f} (95 % interval {low:.2f}-{high:.2f}), as it "
                f"predicts points it did not see better ({errors})")
    else:
        note = (f"{at}: a speed law predicts points it did not see no better than ignoring speed, so the speed "
                f"dependence cannot be told from these data and none is kept (s would be {exponent:.2f}, 95 % "
                f"interval {low:.2f}-{high:.2f}; {errors})")
    return SpeedLawFit(kind, speeds, exponent, (low, high), reference_speed_mm_s, with_law, without,
                       with_law < without, len(data), note)
