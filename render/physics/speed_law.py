"""The settled reduction's dependence on sliding speed: an assumed law, exposed as a parameter, none by default.

A static model (:mod:`ultraglide.render.physics.friction_models`) gives the settled friction ratio for an
amplitude and a force, at whatever speed its data were taken. The intermittent-contact reading of friction
reduction says the faster the finger slides relative to the plate's vibration velocity, the less the vibration
reduces friction: that direction is what an intermittent-contact reading predicts (our reading, not a reported
finding), and no source available to this project gives the law with numbers (the bundled paper and data notes have
none), so the law here is **ours, an assumption**:

    the static model is evaluated at an effective amplitude a_eff = a (v_ref / max(v, v_min))^s

with v the sliding speed, v_ref the speed the model holds at (22 mm/s by default: our choice, the static laws'
speeds are not stated) and s >= 0 the exponent (0: no dependence, the default). s = 1 is the reading taken to
its end: amplitude and speed enter only through their ratio, the plate's vibration velocity against the
finger's; beyond 1 nothing we know of would put them, so s is bounded to 0-1. Below v_min = 2 mm/s (the
friction dynamics' slowest speed, :data:`~ultraglide.render.physics.dynamics.SLOWEST_SPEED_MM_S`) the
finger all but sticks and the law is held at v_min; a speed above 2000 mm/s (no finger swipes faster: a
jump of an estimate) is held there.

The law composes with every static model and inverts exactly: with k = (max(v, v_min) / v_ref)^s, the
amplitude for a target ratio at speed v is the static inverse times k, asked within the limit divided by k, so
the floor reachable under the limit rises with speed (:func:`scaled_inverse`). :class:`SpeedLawModel` is a
static model with such a law: every map it has without a speed is the static model's at v_ref; the renderer
asks it at the finger's speed, block by block. ``--model speed:S:NAME`` names one on the command line and a
calibration file's ``[speed]`` table in a file (:mod:`ultraglide.render.physics.calibration`).

Examples
--------
s = 0.5 at four times the reference speed: the vibration's efficacy halves, so the amplitude for a ratio doubles:

>>> law = SpeedLaw(0.5)
>>> law.amplitude_scale(88.0), law.effective_amplitude_um_pp(4.0, 88.0)
(2.0, 2.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.dynamics import (
    REFERENCE_SPEED_MM_S,
    REFERENCE_SPEED_RANGE_MM_S,
    SLOWEST_SPEED_MM_S,
    DynamicFrictionModel,
    checked_in_range,
)
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.model_base import DEFAULT_FORCE_N, FrictionModel, Inversion, ladder_limit

EXPONENT_RANGE = (0.0, 1.0)  # 0: none; 1: amplitude and speed enter only through their ratio (see above)
FASTEST_SPEED_MM_S = 2000.0  # no finger swipes faster: a faster estimate is held here
FITTED = "fitted to "  # how a law fitted by ``calibrate`` (render.physics.speed_fit) begins its source


@dataclass(frozen=True)
class SpeedLaw:
    """How the settled reduction weakens with sliding speed (see the module docstring). Speeds in mm/s.

    Parameters
    ----------
    exponent : float
        s in a_eff = a (v_ref / v)^s: 0 (no dependence, the default) to 1. Assumed, ours: no source gives it.
    reference_speed_mm_s : float
        v_ref, the speed at which the static model holds as it is: 22 mm/s by default (ours), 1-1000 mm/s.
    source : str
        Where the values come from, in words (for :meth:`describe`); "" : assumed. Not compared.

    Raises
    ------
    ModelError
        A value outside its range, with the range.

    Examples
    --------
    >>> SpeedLaw(0.5).amplitude_scale([22.0, 88.0, 1.0]).round(6).tolist()     # 1 mm/s held at 2 mm/s
    [1.0, 2.0, 0.301511]
    >>> round((2.0 / 22.0) ** 0.5, 6)
    0.301511
    >>> SpeedLaw(1.5)
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: the reduction's speed exponent must lie in 0-1, got 1.5
    """

    exponent: float = 0.0
    reference_speed_mm_s: float = REFERENCE_SPEED_MM_S
    source: str = field(default="", compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "exponent", checked_in_range("the reduction's speed exponent", self.exponent,
                                                      EXPONENT_RANGE, ""))
        object.__setattr__(self, "reference_speed_mm_s", checked_in_range(
            "the reduction's reference speed", self.reference_speed_mm_s, REFERENCE_SPEED_RANGE_MM_S, " mm/s"))

    def amplitude_scale(self, speed_mm_s: ArrayLike) -> np.ndarray | float:
        """k = (v / v_ref)^s at the sliding speed v (mm/s, held within 2-2000 mm/s, infinity too; NaN: the
        reference): the amplitude a ratio needs at v over what it needs at v_ref.

        Parameters
        ----------
        speed_mm_s : float or array of float
            Sliding speeds, mm/s.

        Returns
        -------
        float or numpy.ndarray
            k, one a speed (exactly 1 for s = 0).

        Examples
        --------
        >>> SpeedLaw(1.0).amplitude_scale(44.0), SpeedLaw(0.0).amplitude_scale(500.0)
        (2.0, 1.0)
        """
        if np.ndim(speed_mm_s) == 0:
            return self.one_scale(float(speed_mm_s))
        speed = np.asarray(speed_mm_s, dtype=float)
        speed = np.where(np.isnan(speed), self.reference_speed_mm_s, speed)
        speed = np.minimum(np.maximum(speed, SLOWEST_SPEED_MM_S), FASTEST_SPEED_MM_S)
        return (speed / self.reference_speed_mm_s) ** self.exponent

    def one_scale(self, speed_mm_s: float) -> float:
        """:meth:`amplitude_scale` of one speed (mm/s), as a float, without arrays (the renderer's block path).

        Examples
        --------
        >>> SpeedLaw(0.5).one_scale(88.0), SpeedLaw(0.5).one_scale(float("nan"))
        (2.0, 1.0)
        >>> SpeedLaw(1.0).one_scale(float("inf")) == SpeedLaw(1.0).one_scale(2000.0) == 2000.0 / 22.0
        True
        """
        if self.exponent == 0.0 or math.isnan(speed_mm_s):
            return 1.0
        speed = min(max(speed_mm_s, SLOWEST_SPEED_MM_S), FASTEST_SPEED_MM_S)
        return (speed / self.reference_speed_mm_s) ** self.exponent

    def effective_amplitude_um_pp(self, amplitude_um_pp: ArrayLike, speed_mm_s: ArrayLike) -> np.ndarray | float:
        """a_eff = a / k: the amplitude (µm p-p) the static model is evaluated at for this sliding speed (mm/s).

        Examples
        --------
        >>> SpeedLaw(0.5).effective_amplitude_um_pp(4.0, 88.0)           # 4 µm at 4 × 22 mm/s acts as 2 µm
        2.0
        """
        scale = self.amplitude_scale(speed_mm_s)
        result = np.asarray(amplitude_um_pp, dtype=float) / scale
        return float(result) if np.ndim(result) == 0 else result

    def describe(self) -> str:
        """One line: the law and whose it is: assumed, ours, or the source a calibration file gives (its writer's).

        Examples
        --------
        >>> SpeedLaw(0.5).describe()
        'the reduction weakens with sliding speed: a_eff = a (22 mm/s / v)^0.5 (assumed, ours)'
        >>> SpeedLaw(0.5, source="my sweeps").describe()
        'the reduction weakens with sliding speed: a_eff = a (22 mm/s / v)^0.5 (given, not ours: my sweeps)'
        >>> SpeedLaw(0.5, source="fitted to 26 points at 25 and 100 mm/s").describe()[-45:]
        '^0.5 (fitted to 26 points at 25 and 100 mm/s)'
        >>> SpeedLaw().describe()
        'no dependence on sliding speed (s = 0)'
        """
        if self.exponent == 0.0:
            return "no dependence on sliding speed (s = 0)"
        whose = (self.source if self.source.startswith(FITTED) else f"given, not ours: {self.source}" if self.source
                 else "assumed, ours")  # calibrate's fit says so itself; another source is its writer's
        return (f"the reduction weakens with sliding speed: a_eff = a ({self.reference_speed_mm_s:g} mm/s / v)"
                f"^{self.exponent:g} ({whose})")

    def parameters(self) -> dict[str, float]:
        """``reduction_speed_exponent`` and ``reduction_reference_speed_mm_s`` (mm/s): for files, JSON.

        Examples
        --------
        >>> SpeedLaw(0.5).parameters()
        {'reduction_speed_exponent': 0.5, 'reduction_reference_speed_mm_s': 22.0}
        """
        return {"reduction_speed_exponent": self.exponent,
                "reduction_reference_speed_mm_s": self.reference_speed_mm_s}


def scaled_inverse(model: FrictionModel, ratio: ArrayLike, force_n: ArrayLike, limit_um_pp: float, scale: float,
                   out: np.ndarray | None = None) -> Inversion:
    """The amplitude for each target ratio at a speed whose amplitude scale is ``scale`` (:meth:`SpeedLaw.one_scale`):
    ``model``'s inverse within ``ladder_limit(limit_um_pp / scale)``
    (:func:`~ultraglide.render.physics.model_base.ladder_limit`: under 0.1 % inside ``limit_um_pp / scale``, on a
    rung, so the floor there is computed once a rung, not once a speed), times ``scale``. What it clamps is
    what is out of reach at that speed, or within 0.1 % of it (its amplitude is the limit); no amplitude exceeds
    ``limit_um_pp``. With ``out`` (float64, the ratios' length) and a compiled model, nothing is allocated: the
    scaling is in place.

    Parameters
    ----------
    model : FrictionModel
        Any model (or the closed loop standing in for one): its inverse at the reference speed.
    ratio : array_like
        Target friction ratios.
    force_n : array_like
        Normal forces, N.
    limit_um_pp : float
        The amplitude limit, µm p-p.
    scale : float
        k > 0 at the finger's speed.
    out : numpy.ndarray, optional
        Where to write the amplitudes.

    Returns
    -------
    Inversion
        Amplitudes (µm p-p) and the count clamped.

    Examples
    --------
    At k = 2 the exponential law's amplitude for a half doubles; within a 5 µm limit it is out of reach:

    >>> from ultraglide.render.physics.friction_models import ExponentialModel
    >>> model = ExponentialModel()
    >>> at_reference = model.amplitude_um_pp(np.array([0.5]), 0.5, 5.0).amplitude_um_pp[0]
    >>> fast = scaled_inverse(model, np.array([0.5]), 0.5, 5.0, 2.0)
    >>> round(float(at_reference), 4), fast.amplitude_um_pp.tolist(), fast.clamped
    (3.1084, [5.0], 1)
    """
    if scale == 1.0:
        return model.amplitude_um_pp(ratio, force_n, limit_um_pp, out)
    reached = reach_limit(limit_um_pp, scale)
    inversion = model.amplitude_um_pp(ratio, force_n, reached, out)
    amplitude = inversion.amplitude_um_pp
    if isinstance(amplitude, np.ndarray) and amplitude.ndim == 1 and amplitude.dtype == np.float64:
        most = float(min(reached, model.max_amplitude_um_pp))
        kernels.scale_within(amplitude, float(scale), most, float(limit_um_pp))
    else:
        clamped = amplitude >= min(reached, model.max_amplitude_um_pp)
        amplitude *= scale
        amplitude[clamped] = limit_um_pp
        np.minimum(amplitude, limit_um_pp, out=amplitude)
    return inversion


def reach_limit(limit_um_pp: float, scale: float) -> float:
    """The limit (µm p-p) a static inverse is asked within at amplitude scale ``scale``: ``limit_um_pp / scale`` on
    the ladder's rung at or below it (:func:`~ultraglide.render.physics.model_base.ladder_limit`), so the reachable
    limit only shrinks, by under 0.1 %; ``limit_um_pp`` itself at ``scale`` 1.

    Examples
    --------
    >>> reach_limit(6.0, 1.0), 3.0 / 1.001 < reach_limit(6.0, 2.0) <= 3.0
    (6.0, True)
    """
    return limit_um_pp if scale == 1.0 else ladder_limit(limit_um_pp / scale)


class SpeedLawModel(FrictionModel):
    """A static friction model whose settled reduction weakens with sliding speed by a :class:`SpeedLaw`.

    Every method without a speed is the static model's (the model at the law's reference speed); the ``*_at``
    methods take the speed. The renderer asks :func:`scaled_inverse` at the finger's speed, block by block.

    Parameters
    ----------
    static : FrictionModel
        The law at the reference speed (not dynamic, not itself with a speed law: a dynamic model wraps this one).
    law : SpeedLaw
        The speed dependence.

    Raises
    ------
    ModelError
        ``static`` is a dynamic model or has a speed law already.

    Examples
    --------
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> static = StretchedExponentialModel()
    >>> model = SpeedLawModel(static, SpeedLaw(0.5))
    >>> bool(model.relative_friction_at(4.0, 0.5, 88.0) == static.relative_friction(2.0, 0.5))
    True
    >>> bool(model.relative_friction(4.0, 0.5) == static.relative_friction(4.0, 0.5))    # at 22 mm/s
    True
    """

    def __init__(self, static: FrictionModel, law: SpeedLaw):
        if isinstance(static, DynamicFrictionModel):
            raise ModelError("a speed law wraps a static model; a dynamic model wraps that one "
                             "(DynamicFrictionModel(SpeedLawModel(static)))")
        if isinstance(static, SpeedLawModel):
            raise ModelError("this model has a speed law already")
        self.static = static
        self.speed_law = law
        self.name = static.name
        self.max_amplitude_um_pp = static.max_amplitude_um_pp
        self.fitted = static.fitted
        self.default_floor = static.default_floor

    def warm_up(self) -> None:
        """The static model's compiled inverse, loaded, and its slots for the floors on the limit ladder made (the
        law asks its floors there: :meth:`FrictionModel._floor`).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> SpeedLawModel(ExponentialModel(), SpeedLaw(0.5)).warm_up()
        """
        self.static.warm_up()
        self.static._ladder_slots()
        kernels.scale_within(np.zeros(1), 2.0, 1.0, 2.0)  # compiled (or loaded) here, not in the first block

    def force_law(self) -> str:
        """The static model's force law.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> SpeedLawModel(ExponentialModel(), SpeedLaw(0.5)).force_law() == ExponentialModel().force_law()
        True
        """
        return self.static.force_law()

    def valid_force_range_n(self) -> tuple[float, float]:
        """The static model's force range (N).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> SpeedLawModel(ExponentialModel(), SpeedLaw(0.5)).valid_force_range_n()
        (0.01, 10.0)
        """
        return self.static.valid_force_range_n()

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """The settled ratio at the reference speed: the static model's.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> float(SpeedLawModel(ExponentialModel(), SpeedLaw(0.5)).relative_friction(0.0))
        1.0
        """
        return self.static.relative_friction(amplitude_um_pp, force_n)

    def relative_friction_at(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike, speed_mm_s: ArrayLike) -> np.ndarray:
        """The settled ratio at a sliding speed: the static model at a_eff = a / k(v).

        Parameters
        ----------
        amplitude_um_pp : array_like
            µm p-p.
        force_n : array_like
            N.
        speed_mm_s : array_like
            mm/s, one or one an amplitude.

        Returns
        -------
        numpy.ndarray

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = SpeedLawModel(ExponentialModel(), SpeedLaw(1.0))
        >>> bool(model.relative_friction_at(3.0, 0.5, 44.0) == ExponentialModel().relative_friction(1.5, 0.5))
        True
        """
        return self.static.relative_friction(self.speed_law.effective_amplitude_um_pp(amplitude_um_pp, speed_mm_s),
                                             force_n)

    def _amplitude_in_reach(self, ratio, force_n):
        return self.static._amplitude_in_reach(ratio, force_n)

    def amplitude_um_pp(self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf,
                        out: np.ndarray | None = None) -> Inversion:
        """The static model's inverse (at the reference speed).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = SpeedLawModel(ExponentialModel(), SpeedLaw(0.5))
        >>> round(float(model.amplitude_um_pp(0.5, 0.5).amplitude_um_pp), 2)
        3.11
        """
        return self.static.amplitude_um_pp(ratio, force_n, limit_um_pp, out)

    def amplitude_at(self, ratio: ArrayLike, force_n: ArrayLike, speed_mm_s: float, limit_um_pp: float = np.inf,
                     out: np.ndarray | None = None) -> Inversion:
        """The amplitude (µm p-p) for each target ratio at one sliding speed (mm/s): the static inverse times
        k(v), within the limit (:func:`scaled_inverse`).

        Parameters
        ----------
        ratio : array_like
        force_n : array_like
            N.
        speed_mm_s : float
            mm/s.
        limit_um_pp : float
            µm p-p.
        out : numpy.ndarray, optional

        Returns
        -------
        Inversion

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = SpeedLawModel(ExponentialModel(), SpeedLaw(0.5))
        >>> round(float(model.amplitude_at(np.array([0.5]), 0.5, 88.0).amplitude_um_pp[0]), 4)   # 2 × 3.1084
        6.2167
        """
        return scaled_inverse(self.static, ratio, force_n, limit_um_pp, self.speed_law.one_scale(float(speed_mm_s)),
                              out)

    def floor_ratio(self, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf) -> np.ndarray | float:
        """The static model's floor (at the reference speed) within the limit (µm p-p).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = SpeedLawModel(ExponentialModel(), SpeedLaw(0.5))
        >>> bool(model.floor_ratio(0.5, 6.0) == ExponentialModel().floor_ratio(0.5, 6.0))
        True
        """
        return self.static.floor_ratio(force_n, limit_um_pp)

    def floor_at(self, force_n: ArrayLike, speed_mm_s: float, limit_um_pp: float = np.inf) -> np.ndarray | float:
        """The lowest settled ratio reachable within the limit (µm p-p) at a sliding speed (mm/s): the static
        floor within ``limit / k(v)``; it rises with speed.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = SpeedLawModel(ExponentialModel(), SpeedLaw(0.5))
        >>> bool(model.floor_at(0.5, 88.0, 6.0) == ExponentialModel().floor_ratio(0.5, 3.0))
        True
        """
        return self.static.floor_ratio(force_n, limit_um_pp / self.speed_law.one_scale(float(speed_mm_s)))

    def _floor(self, force_n, limit: float):
        return self.static._floor(force_n, limit)

    def describe(self) -> str:
        """One line: the static model, then the speed law (assumed).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = SpeedLawModel(ExponentialModel(), SpeedLaw(0.5))
        >>> model.describe().endswith("; the reduction weakens with sliding speed: a_eff = a (22 mm/s / v)^0.5 "
        ...                           "(assumed, ours)")
        True
        """
        return f"{self.static.describe()}; {self.speed_law.describe()}"

    def parameters(self) -> dict[str, float | str]:
        """The static model's parameters and the speed law's (``reduction_speed_exponent``,
        ``reduction_reference_speed_mm_s`` in mm/s).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> SpeedLawModel(ExponentialModel(), SpeedLaw(0.5)).parameters()["reduction_speed_exponent"]
        0.5
        """
        return {**self.static.parameters(), **self.speed_law.parameters()}

    def __repr__(self) -> str:
        return f"SpeedLawModel({self.static!r}, {self.speed_law!r})"


def floor_at_speed(model, force_n: float, speed_mm_s: float, limit_um_pp: float) -> float:
    """The lowest settled ratio ``model`` reaches within the limit (µm p-p) at a force (N) and sliding speed (mm/s):
    under its speed law (:func:`speed_law_of`) the floor within limit / k(v), which rises with speed; without one,
    the floor within the limit.

    Examples
    --------
    >>> from ultraglide.render.physics.friction_models import ExponentialModel
    >>> static = ExponentialModel()
    >>> bool(floor_at_speed(SpeedLawModel(static, SpeedLaw(1.0)), 0.5, 44.0, 6.0) == static.floor_ratio(0.5, 3.0))
    True
    >>> bool(floor_at_speed(static, 0.5, 44.0, 6.0) == static.floor_ratio(0.5, 6.0))
    True
    """
    law = speed_law_of(model)
    within = limit_um_pp / law.one_scale(float(speed_mm_s)) if law is not None else limit_um_pp
    return float(model.floor_ratio(force_n, within))


def speed_law_of(model) -> SpeedLaw | None:
    """The speed law a model (a dynamic one, the closed loop standing in for one) carries, or None (no
    dependence). A law with s = 0 counts as none.

    Examples
    --------
    >>> from ultraglide.render.physics.friction_models import ExponentialModel
    >>> speed_law_of(ExponentialModel()) is None, speed_law_of(SpeedLawModel(ExponentialModel(), SpeedLaw(0.5)))
    (True, SpeedLaw(exponent=0.5, reference_speed_mm_s=22.0))
    """
    law = getattr(model, "speed_law", None)
    return law if law is not None and law.exponent > 0.0 else None
