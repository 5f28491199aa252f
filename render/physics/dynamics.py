"""Friction in time: the finger's felt friction follows the static model's ratio through asymmetric dynamics.

A static model (:mod:`ultraglide.render.physics.friction_models`) says what friction ratio an amplitude gives
once the finger has settled. Measured fingers do not settle at once, and not at the same pace both ways:

* **onset** (vibration starts, friction falls): within a few milliseconds, 5 ms in Meyer, Wiertlewski,
  Peshkin and Colgate (IEEE Haptics Symposium 2014);
* **recovery** (vibration stops, friction comes back): tens of milliseconds, 70 ms at a sliding speed of
  22 mm/s in the same paper, slower when sliding slower. Huloux et al. (2018) saw friction settle in
  32-37 ms. Monnoyer, Willemet and Wiertlewski (2023) saw the skin release its elastic strain over 20 ms
  after the reduction was switched on, a finger pressing rather than sliding.

:class:`FrictionDynamics` models both as first-order lags, with the 5 ms and 70 ms as their time constants (our
reading: whether the paper's figures are time constants or settling times was not checked here), chosen by the
direction of the change: ``onset_s`` where the static ratio lies below the felt one, the recovery's where it
lies above. The recovery's dependence on the sliding speed v is
``recovery_s (reference_speed_mm_s / v)^speed_exponent``: the source gives one point (70 ms at 22 mm/s) and the
direction (slower when slower), not the law, so the exponent is **an assumption, exposed as a parameter**: 0.5
by default (our choice: it puts the recovery at 100 mm/s at 33 ms, inside the 32-37 ms above, whose speed we do
not know); 1 would be a fixed sliding distance (1.5 mm) to renew the contact, 0 no dependence. Each sample's
static value is held for one period, so the response to a step is exact: 1 - exp(-t / tau), 63 % at t = tau.

:class:`DynamicFrictionModel` is a static model with dynamics: every command and the API take it where they
take a model (``dynamic`` is the default static model with the published dynamics; ``dynamic:NAME`` any
other). Its amplitude ↔ ratio maps are the static model's (the steady state); :meth:`felt` runs the
dynamics.

Examples
--------
>>> import numpy as np
>>> dynamics = FrictionDynamics()
>>> step = np.full(120, 0.0)                         # 10 ms at 12 kHz of a step from 1 down to 0
>>> felt = dynamics.respond(step, 12000.0, speed_mm_s=22.0, felt=1.0)
>>> round(float(felt[59]), 3)                          # 5 ms: one onset time constant, 1/e left
0.368
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.model_base import DEFAULT_FORCE_N, FrictionModel, Inversion

ONSET_S = 0.005  # Meyer et al. 2014 (sources.FIGURES "onset_s")
RECOVERY_S = 0.070  # at 22 mm/s, Meyer et al. 2014 ("recovery_s")
REFERENCE_SPEED_MM_S = 22.0  # the speed of that recovery ("recovery_speed")
ASSUMED_SPEED_EXPONENT = 0.5  # assumed (see the module docstring): no source gives the law
SLOWEST_SPEED_MM_S = 2.0  # slower than this the finger all but sticks: the recovery is held at this speed's
LONGEST_S = 1.0  # no time constant is longer than this
ONSET_RANGE_S = (0.0005, 0.05)  # 0.5-50 ms: from below the 2.3 ms people discriminate to beyond a 20 ms release
RECOVERY_RANGE_S = (0.002, 0.5)
SPEED_EXPONENT_RANGE = (0.0, 1.5)
REFERENCE_SPEED_RANGE_MM_S = (1.0, 1000.0)


def checked_in_range(name: str, value, allowed: tuple[float, float], unit: str) -> float:
    """``value`` as a float if it is a finite number within ``allowed`` (ends included), else a one-line
    :class:`ModelError` naming ``name``, the range and its ``unit``.

    Examples
    --------
    >>> checked_in_range("the onset time constant", 0.005, (0.0005, 0.05), " s")
    0.005
    >>> checked_in_range("the onset time constant", "fast", (0.0005, 0.05), " s")
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: the onset time constant must be a number in 0.0005-0.05 s, got 'fast'
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ModelError(f"{name} must be a number in {allowed[0]:g}-{allowed[1]:g}{unit}, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and allowed[0] <= value <= allowed[1]):
        raise ModelError(f"{name} must lie in {allowed[0]:g}-{allowed[1]:g}{unit}, got {value:g}")
    return value


@dataclass(frozen=True)
class FrictionDynamics:
    """Asymmetric first-order friction dynamics (see the module docstring). Times in s, speeds in mm/s.

    Parameters
    ----------
    onset_s : float
        Time constant where friction falls (the vibration starts): 5 ms (Meyer et al. 2014). Our allowed
        range: 0.5-50 ms.
    recovery_s : float
        Time constant where friction rises, at ``reference_speed_mm_s``: 70 ms at 22 mm/s (Meyer et al.
        2014). Our allowed range: 2-500 ms.
    reference_speed_mm_s : float
        The sliding speed of ``recovery_s``, 1-1000 mm/s.
    speed_exponent : float
        The recovery scales as (reference / v)^exponent: 0.5, assumed (no source gives the law), 0-1.5.
    source : str
        Where these values come from, in words, for :meth:`describe` (e.g. "fitted on the plate, 28 edges"); ""
        (the default): the published figures where they are the published ones. Not compared, not in the repr.

    Raises
    ------
    ModelError
        A parameter outside its range, with the range.

    Examples
    --------
    The recovery time constant falls as (22 / v)^0.5: 35 ms at 88 mm/s; a held fall follows its onset time
    constant, at 1 kHz e^(-1/5) of the way left after one sample:

    >>> import numpy as np
    >>> dynamics = FrictionDynamics()
    >>> round(float(dynamics.recovery_at_s(88.0)), 9)
    0.035
    >>> felt = dynamics.respond(np.array([0.5, 0.5]), 1000.0)
    >>> bool(np.allclose(felt, 0.5 + 0.5 * np.exp(-np.array([1.0, 2.0]) / 5.0)))
    True
    """

    onset_s: float = ONSET_S
    recovery_s: float = RECOVERY_S
    reference_speed_mm_s: float = REFERENCE_SPEED_MM_S
    speed_exponent: float = ASSUMED_SPEED_EXPONENT
    source: str = field(default="", compare=False, repr=False)

    def __post_init__(self) -> None:
        checked_in_range("the onset time constant", self.onset_s, ONSET_RANGE_S, " s")
        checked_in_range("the recovery time constant", self.recovery_s, RECOVERY_RANGE_S, " s")
        checked_in_range("the recovery's reference speed", self.reference_speed_mm_s, REFERENCE_SPEED_RANGE_MM_S,
                         " mm/s")
        checked_in_range("the recovery's speed exponent", self.speed_exponent, SPEED_EXPONENT_RANGE, "")

    @property
    def published(self) -> bool:
        """Whether these are the published time constants (Meyer et al. 2014's onset, recovery and its speed), not
        fitted or given ones; the speed exponent, an assumption either way, does not decide it.

        Examples
        --------
        >>> FrictionDynamics().published, FrictionDynamics(speed_exponent=1.0).published
        (True, True)
        >>> FrictionDynamics(onset_s=0.004).published
        False
        """
        return (self.onset_s, self.recovery_s, self.reference_speed_mm_s) == (ONSET_S, RECOVERY_S,
                                                                               REFERENCE_SPEED_MM_S)

    def recovery_at_s(self, speed_mm_s: ArrayLike) -> np.ndarray | float:
        """The recovery's time constant (s) at a sliding speed (mm/s; below 2 mm/s as at 2 mm/s), at most 1 s.

        Examples
        --------
        70 ms at the reference 22 mm/s; at 88 mm/s, 70 ms × (22 / 88)^0.5 = 35 ms; 1 mm/s is taken as 2 mm/s:

        >>> dynamics = FrictionDynamics()
        >>> [round(float(t), 6) for t in dynamics.recovery_at_s([22.0, 88.0, 1.0])]
        [0.07, 0.035, 0.232164]
        >>> round(0.07 * (22 / 2) ** 0.5, 6)
        0.232164
        """
        speed = np.maximum(np.asarray(speed_mm_s, dtype=float), SLOWEST_SPEED_MM_S)
        tau = np.minimum(self.recovery_s * (self.reference_speed_mm_s / speed) ** self.speed_exponent, LONGEST_S)
        return float(tau) if tau.ndim == 0 else tau

    def respond(self, static_ratio: ArrayLike, rate_hz: float, speed_mm_s: ArrayLike = REFERENCE_SPEED_MM_S,
                felt: float = 1.0, out: np.ndarray | None = None) -> np.ndarray:
        """The felt ratio at the end of each sample, for the static ratio of each sample held for one period.

        Parameters
        ----------
        static_ratio : array of float
            What the static model gives at each sample (1 at rest).
        rate_hz : float
            The samples' rate, Hz.
        speed_mm_s : float or array of float
            The finger's sliding speed, mm/s (one, or one a sample).
        felt : float
            The felt ratio before the first sample (1: the finger has been on a plate at rest).
        out : float64 array, optional
            Where to write the result (no allocation then).

        Returns
        -------
        numpy.ndarray
            The felt ratio, one a sample.

        Examples
        --------
        Back from 0.2 to 1 at 22 mm/s, sampled at 1 kHz: after one 70 ms recovery time constant, 1 - 0.8 e^-1:

        >>> import math
        >>> felt = FrictionDynamics().respond(np.ones(70), 1000.0, 22.0, felt=0.2)
        >>> round(float(felt[-1]), 9) == round(1 - 0.8 * math.exp(-1.0), 9)
        True
        """
        static = np.ascontiguousarray(static_ratio, dtype=float).reshape(-1)
        if not rate_hz > 0:
            raise ModelError(f"the sample rate must be positive, got {rate_hz}")
        if not np.all(np.isfinite(static)):
            raise ModelError("the static friction ratio must be finite")
        out = np.empty(len(static)) if out is None else out
        speed = np.asarray(speed_mm_s, dtype=float)
        if speed.ndim == 0:
            one, speeds = max(float(speed), 0.0), _NO_SPEEDS
        else:
            one, speeds = -1.0, np.ascontiguousarray(np.maximum(speed.reshape(-1), 0.0))
            if len(speeds) != len(static):
                raise ModelError(f"one speed a sample: {len(speeds)} speeds for {len(static)} samples")
        kernels.friction_response(static, speeds, one, float(rate_hz), self.onset_s, self.recovery_s,
                                  self.reference_speed_mm_s, self.speed_exponent, SLOWEST_SPEED_MM_S, LONGEST_S,
                                  float(felt), out)
        return out

    def describe(self) -> str:
        """One line: the time constants and where they come from.

        Examples
        --------
        Given time constants (not the published ones, so no source is named), the recovery at 100 mm/s is
        50 ms × (22 / 100)^0.5:

        >>> FrictionDynamics(onset_s=0.004, recovery_s=0.05).describe()
        'onset 4 ms, recovery 50 ms at 22 mm/s, x (v_ref/v)^0.5 (assumed): 23.5 ms at 100 mm/s'
        >>> round(50 * (22 / 100) ** 0.5, 1)
        23.5
        """
        law = ("assumed" if self.speed_exponent == ASSUMED_SPEED_EXPONENT else "as given")
        source = f" ({self.source})" if self.source else " (Meyer et al. 2014)" if self.published else ""
        return (f"onset {1000 * self.onset_s:.3g} ms, recovery {1000 * self.recovery_s:.3g} ms at "
                f"{self.reference_speed_mm_s:g} mm/s{source}, x (v_ref/v)^{self.speed_exponent:g} ({law}): "
                f"{1000 * self.recovery_at_s(100.0):.3g} ms at 100 mm/s")

    def parameters(self) -> dict[str, float]:
        """``onset_s``, ``recovery_s`` (s), ``reference_speed_mm_s`` (mm/s), ``speed_exponent``: for files, JSON.

        Examples
        --------
        >>> FrictionDynamics(onset_s=0.004).parameters()
        {'onset_s': 0.004, 'recovery_s': 0.07, 'reference_speed_mm_s': 22.0, 'speed_exponent': 0.5}
        """
        return {"onset_s": self.onset_s, "recovery_s": self.recovery_s,
                "reference_speed_mm_s": self.reference_speed_mm_s, "speed_exponent": self.speed_exponent}


_NO_SPEEDS = np.zeros(0)


class DynamicFrictionModel(FrictionModel):
    """A static friction model (the steady state) with :class:`FrictionDynamics` (how the finger gets there).

    Every amplitude ↔ ratio map is the static model's; :meth:`felt` gives the friction felt over time for an
    amplitude over time. The renderer plans against :attr:`dynamics` (:mod:`ultraglide.render.planning`).

    Parameters
    ----------
    static : FrictionModel
        The steady state (not itself dynamic).
    dynamics : FrictionDynamics, optional
        How the finger gets there (the default: :class:`FrictionDynamics`'s).

    Raises
    ------
    ModelError
        ``static`` is a dynamic model.

    Examples
    --------
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> model = DynamicFrictionModel(StretchedExponentialModel())
    >>> felt = model.felt(np.r_[np.zeros(12), np.full(1200, 6.0)], 12000.0)
    >>> round(float(felt[-1]), 3) == round(float(model.relative_friction(6.0)), 3)   # settled after 100 ms
    True
    """

    name = "dynamic"

    def __init__(self, static: FrictionModel, dynamics: FrictionDynamics | None = None):
        if isinstance(static, DynamicFrictionModel):
            raise ModelError("a dynamic model wraps a static one, not another dynamic model")
        self.static = static
        self.dynamics = dynamics or FrictionDynamics()
        self.max_amplitude_um_pp = static.max_amplitude_um_pp
        self.fitted = static.fitted
        self.default_floor = static.default_floor

    @property
    def speed_law(self):
        """The static model's settled speed law (:mod:`~ultraglide.render.physics.speed_law`), None without one.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> print(DynamicFrictionModel(StretchedExponentialModel()).speed_law)
        None
        """
        return getattr(self.static, "speed_law", None)

    def warm_up(self) -> None:
        """Load the static model's compiled inverse and the dynamics' kernel before a real-time block needs them.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> model.warm_up()                      # loads, returns nothing
        """
        self.static.warm_up()
        kernels.warm_up_dynamics()

    def force_law(self) -> str:
        """The static model's force law (the dynamics add none).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> model.force_law() == model.static.force_law()
        True
        """
        return self.static.force_law()

    def valid_force_range_n(self) -> tuple[float, float]:
        """The static model's force range (N).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> model.valid_force_range_n() == model.static.valid_force_range_n()
        True
        """
        return self.static.valid_force_range_n()

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """The steady state: the static model's ratio.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> float(model.relative_friction(0.0)), bool(model.relative_friction(3.0) < 1.0)
        (1.0, True)
        """
        return self.static.relative_friction(amplitude_um_pp, force_n)

    def _amplitude_in_reach(self, ratio, force_n):
        return self.static._amplitude_in_reach(ratio, force_n)

    def amplitude_um_pp(self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf,
                        out: np.ndarray | None = None) -> Inversion:
        """The static model's inverse (the amplitude whose settled ratio is the one asked).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> amplitude = model.amplitude_um_pp(np.array([0.6]), 0.5).amplitude_um_pp
        >>> round(float(model.relative_friction(amplitude, 0.5)[0]), 6)    # settled there: the ratio asked
        0.6
        """
        return self.static.amplitude_um_pp(ratio, force_n, limit_um_pp, out)

    def floor_ratio(self, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf) -> np.ndarray | float:
        """The static model's floor: the lowest steady ratio at this force within the limit (µm p-p).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> float(model.floor_ratio(0.5, 6.0)) == float(model.relative_friction(6.0, 0.5))
        True
        """
        return self.static.floor_ratio(force_n, limit_um_pp)

    def felt(self, amplitude_um_pp: ArrayLike, rate_hz: float, force_n: ArrayLike = DEFAULT_FORCE_N,
             speed_mm_s: ArrayLike = REFERENCE_SPEED_MM_S, felt: float = 1.0) -> np.ndarray:
        """The friction ratio the finger feels for the plate's amplitude over time (µm p-p, one a sample at
        ``rate_hz``), at a force (N) and a sliding speed (mm/s), one or one a sample; ``felt``: the ratio
        felt before the first sample.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> import math
        >>> steady = float(model.relative_friction(4.0, 0.5))
        >>> felt = model.felt(np.full(5, 4.0), 1000.0)       # 5 ms at 1 kHz: one onset time constant
        >>> round(float(felt[-1]), 9) == round(steady + (1 - steady) * math.exp(-1.0), 9)
        True
        """
        static = self.static.relative_friction(amplitude_um_pp, force_n)
        return self.dynamics.respond(static, rate_hz, speed_mm_s, felt)

    def describe(self) -> str:
        """One line: the static model, then the dynamics in time.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> model.describe() == f"dynamic: {model.static.describe()}; in time: {model.dynamics.describe()}"
        True
        """
        return f"dynamic: {self.static.describe()}; in time: {self.dynamics.describe()}"

    def parameters(self) -> dict[str, float | str]:
        """The static model's parameters and the dynamics' (times in s, speeds in mm/s).

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = DynamicFrictionModel(StretchedExponentialModel())
        >>> model.parameters()["onset_s"], model.parameters()["shape"] == model.static.parameters()["shape"]
        (0.005, True)
        """
        return {**self.static.parameters(), **self.dynamics.parameters()}

    def __repr__(self) -> str:
        return f"DynamicFrictionModel({self.static!r}, {self.dynamics!r})"
