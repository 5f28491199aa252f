"""The friction models' common ground: the base class, its checks, force range and inverse tables.

See :mod:`ultraglide.render.physics.friction_models` for what every model promises.
"""

from __future__ import annotations

import math
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.errors import ForceRangeWarning, ModelError

DEFAULT_FORCE_N = 0.5
MIN_FORCE_N = 0.01  # lighter touches are treated as 10 mN: the finger is lifting off
MAX_FORCE_N = 10.0  # a fingertip's touch range ends here (a hard press); commands refuse more
CEILING_UM_PP = 20.0  # no model is evaluated beyond this: far above any plate's safe amplitude
RATIO_GRID_POINTS = 4097  # resolution of the uniform inverse tables
SCALAR_CACHE = 16  # values remembered per model for scalar forces (a closed loop's few, at once)
LADDER_STEP = math.log(1.001)  # the rungs of the amplitude-limit ladder, 0.1 % apart (see ladder_limit)
LADDER_RUNGS = (-6910, 6910)  # 0.001-1000 µm p-p: any limit a plate and a speed law's k can make
FORCE_RUNG_STEP = math.log(1.01)  # a floor on the ladder is asked at the force's rung: 1 % apart, one at 0.5 N
LADDER_FLOOR_SLOTS = 4096  # the floors on the ladder a model keeps: (force rung, limit rung) -> ratio, 64 kB
LADDER_PROBES = 8  # slots looked at for a pair before the first is overwritten
EMPTY_SLOT = -(2**62)  # no pair's key


def ladder_limit(limit_um_pp: float) -> float:
    """The rung of a fixed ladder (steps 0.1 % apart, 0.001-1000 µm p-p) at or just below an amplitude limit: a
    limit that moves by a fraction (a speed law's limit / k, new whenever the speed changes) is asked on a rung, so
    the floor there is computed once a rung and kept in a table made once a force (:meth:`FrictionModel._floor`).

    Parameters
    ----------
    limit_um_pp : float
        µm p-p, > 0.

    Returns
    -------
    float
        The rung (µm p-p), within 0.1 % below the limit, the same float for every limit on it; the limit itself
        outside the ladder's range.

    Examples
    --------
    >>> rung = ladder_limit(3.0)
    >>> ladder_limit(rung * 1.0005) == ladder_limit(rung) == rung, 3.0 / 1.001 < rung <= 3.0
    (True, True)
    """
    if not (limit_um_pp > 0.0 and math.isfinite(limit_um_pp)):
        return limit_um_pp
    rung = math.floor(math.log(limit_um_pp) / LADDER_STEP)
    if not LADDER_RUNGS[0] <= rung < LADDER_RUNGS[1]:
        return limit_um_pp
    value = math.exp(rung * LADDER_STEP)
    return value if value <= limit_um_pp else math.exp((rung - 1) * LADDER_STEP)


def _ladder_rung(limit: float) -> int | None:
    """The rung index of a limit on the ladder (exactly), else None."""
    if not (limit > 0.0 and math.isfinite(limit)):
        return None
    rung = round(math.log(limit) / LADDER_STEP)
    if LADDER_RUNGS[0] <= rung < LADDER_RUNGS[1] and math.exp(rung * LADDER_STEP) == limit:
        return rung
    return None


def remembered(owner, memo: str, key, compute, size: int = SCALAR_CACHE):
    """``compute()``, remembered in ``owner``'s dict named ``memo`` for the last ``size`` keys.

    Parameters
    ----------
    owner : object
        Whose ``__dict__`` keeps the values.
    memo : str
        The name they are kept under.
    key : hashable
        What the value is for.
    compute : callable
        Makes the value when it is not kept.
    size : int
        How many keys are kept (:data:`SCALAR_CACHE` by default).

    Returns
    -------
    object

    Examples
    --------
    >>> class Model: pass
    >>> model, calls = Model(), []
    >>> [remembered(model, "_memo", 0.5, lambda: calls.append(1) or 2.0) for _ in range(3)], len(calls)
    ([2.0, 2.0, 2.0], 1)
    """
    values = owner.__dict__.get(memo)
    if values is None:
        values = owner.__dict__[memo] = {}
    value = values.get(key)
    if value is None:
        if len(values) >= size:  # the oldest goes: the dict's size stays put once full (a floor asked at a
            del values[next(iter(values))]  # new limit each block, under a speed law, keeps nothing more per block)
        value = values[key] = compute()
    return value


@dataclass(frozen=True)
class FitRange:
    """Where a calibrated model was fitted: the distinct forces of its data (N) and its point count.

    Examples
    --------
    >>> FitRange((0.2, 0.5, 1.0), points=30).words(), FitRange((0.5,)).words()
    ('0.2-1 N (3 forces)', '0.5 N only')
    """

    forces_n: tuple[float, ...]
    points: int = 0

    @property
    def force_range_n(self) -> tuple[float, float]:
        """The smallest and largest force fitted on (N).

        Examples
        --------
        >>> FitRange((0.5, 0.2, 1.0)).force_range_n
        (0.2, 1.0)
        """
        return (min(self.forces_n), max(self.forces_n))

    def words(self) -> str:
        """The forces fitted on in words: "0.2-1 N (3 forces)" or "0.5 N only".

        Returns
        -------
        str

        Examples
        --------
        >>> FitRange((1.0, 0.2, 0.5)).words()
        '0.2-1 N (3 forces)'
        """
        low, high = self.force_range_n
        if len(self.forces_n) == 1:
            return f"{low:g} N only"
        return f"{low:g}-{high:g} N ({len(self.forces_n)} forces)"


@dataclass(frozen=True)
class Inversion:
    """Amplitudes for target ratios, and how many ratios were out of reach.

    Examples
    --------
    The stretched law's inverse at its reference force, without a floor: a ratio of 1/2 needs scale × sqrt(ln 2):

    >>> import math
    >>> import numpy as np
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> model = StretchedExponentialModel(residual_ratio=0.0)
    >>> inversion = model.amplitude_um_pp(np.array([1.0, 0.5]), 0.5)
    >>> expected = [0.0, model.scale_um_pp * math.sqrt(math.log(2.0))]
    >>> bool(np.allclose(inversion.amplitude_um_pp, expected)), inversion.clamped
    (True, 0)
    """

    amplitude_um_pp: np.ndarray
    clamped: int


class UniformTable:
    """Piecewise-linear lookup on a uniform grid: cheap enough for tens of millions of calls a second.

    Parameters
    ----------
    start, stop : float
        The grid's first and last x.
    values : numpy.ndarray
        The values at the grid's points (a row per table when 2-D).

    Examples
    --------
    >>> import numpy as np
    >>> table = UniformTable(0.0, 1.0, np.array([0.0, 10.0, 30.0]))       # points at 0, 0.5 and 1
    >>> table(np.array([0.25, 0.75, 2.0])).tolist()                         # linear between, held beyond
    [5.0, 20.0, 30.0]
    """

    def __init__(self, start: float, stop: float, values: np.ndarray):
        values = np.asarray(values, dtype=float)
        self.start = float(start)
        self.intervals = values.shape[-1] - 1
        self.scale = self.intervals / (float(stop) - self.start)
        self.values = values
        self.slopes = np.diff(values, axis=-1)

    def __call__(self, x, row: int = 0) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        position = (x.reshape(-1) - self.start) * self.scale
        np.clip(position, 0.0, self.intervals, out=position)
        index = position.astype(np.intp)
        np.minimum(index, self.intervals - 1, out=index)
        position -= index
        values = self.values if self.values.ndim == 1 else self.values[row]
        slopes = self.slopes if self.slopes.ndim == 1 else self.slopes[row]
        position *= slopes.take(index)
        position += values.take(index)
        return position.reshape(x.shape)


def clip_force(force_n):
    # minimum(maximum()): np.clip's values (NaN kept), without its Python wrapper (a few µs a call)
    """Forces (N) held within the models' range, 10 mN to 10 N (a NaN stays NaN for the checks to name).

    Parameters
    ----------
    force_n : array_like
        Forces (N).

    Returns
    -------
    numpy.ndarray
        The forces, clipped.

    Examples
    --------
    >>> clip_force([0.0, 0.5, 20.0]).tolist()
    [0.01, 0.5, 10.0]
    """
    return np.minimum(np.maximum(np.asarray(force_n, dtype=float), MIN_FORCE_N), MAX_FORCE_N)


def is_scalar(value) -> bool:
    """True for one value (a number or a 0-d array), False for an array of values.

    Examples
    --------
    >>> is_scalar(0.5), is_scalar(np.float64(0.5)), is_scalar(np.array([0.5]))
    (True, True, False)
    """
    return not isinstance(value, np.ndarray) or value.ndim == 0


def check_force(force_n) -> None:
    """Raise :class:`ModelError` unless every force is a finite number >= 0 N.

    Parameters
    ----------
    force_n : array_like
        Forces (N).

    Raises
    ------
    ModelError
        A force that is negative, infinite or NaN (the first is named).

    Examples
    --------
    >>> check_force([0.0, 0.5])
    >>> check_force(-1.0)
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: normal force must be a finite number >= 0 N, got -1.0
    """
    if is_scalar(force_n) and not isinstance(force_n, (list, tuple)):
        value = float(force_n)
        if not (0.0 <= value < np.inf):
            raise ModelError(f"normal force must be a finite number >= 0 N, got {value}")
        return
    force = np.asarray(force_n, dtype=float)
    bad = ~((force >= 0.0) & (force < np.inf))
    if bad.any():
        raise ModelError(f"normal force must be a finite number >= 0 N, got {force[bad].flat[0]}")


def _smallest(values: np.ndarray):
    """The smallest of all the values (NaN if any is: a NaN fails every comparison), without ``min``'s wrapper."""
    return np.minimum.reduce(values, axis=None)


def _largest(values: np.ndarray):
    return np.maximum.reduce(values, axis=None)


def check_ratio(ratio: np.ndarray) -> None:
    """Raise :class:`ModelError` unless every friction ratio is a finite number >= 0.

    Parameters
    ----------
    ratio : numpy.ndarray
        Friction ratios.

    Raises
    ------
    ModelError
        A ratio that is negative, infinite or NaN.

    Examples
    --------
    >>> check_ratio(np.array([np.nan]))                               # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: friction ratio must be a finite number >= 0 ..., got nan
    """
    bad = ~((ratio >= 0.0) & (ratio < np.inf))
    if bad.any():
        raise ModelError(f"friction ratio must be a finite number >= 0 (1 = plate at rest), got {ratio[bad].flat[0]}")


def check_amplitude(amplitude: np.ndarray) -> None:
    """Raise :class:`ModelError` unless every amplitude is a finite number >= 0 µm.

    Parameters
    ----------
    amplitude : numpy.ndarray
        Amplitudes (µm p-p).

    Raises
    ------
    ModelError
        An amplitude that is negative, infinite or NaN.

    Examples
    --------
    >>> check_amplitude(np.array([-1.0]))
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: amplitude must be a finite number >= 0 µm p-p, got -1.0
    """
    if not amplitude.size or (_smallest(amplitude) >= 0.0 and _largest(amplitude) < np.inf):  # NaN fails both
        return
    bad = ~((amplitude >= 0.0) & (amplitude < np.inf))
    if bad.any():
        raise ModelError(f"amplitude must be a finite number >= 0 µm p-p, got {amplitude[bad].flat[0]}")


def kernel_result(code: int, ratio: np.ndarray, force) -> int:
    """A kernel's return value: a count of clamped ratios, or -1 - i for a bad sample i.

    Parameters
    ----------
    code : int
        What the kernel returned.
    ratio : numpy.ndarray
        The ratios it was given.
    force : float or numpy.ndarray
        The forces (N) it was given.

    Returns
    -------
    int
        The count of clamped ratios.

    Raises
    ------
    ModelError
        The bad sample, named as the checks name it.

    Examples
    --------
    >>> kernel_result(3, np.zeros(3), 0.5)
    3
    >>> kernel_result(-2, np.array([0.5, np.nan]), 0.5)                  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: friction ratio must be a finite number >= 0 ..., got nan
    """
    if code >= 0:
        return code
    i = -1 - code
    force = np.atleast_1d(force)
    check_force(force[min(i, len(force) - 1)])
    check_ratio(ratio[i:i + 1])
    raise AssertionError("a kernel reported a bad sample that passes the checks")  # pragma: no cover


class FrictionModel(ABC):
    """The interface every friction model offers (see :mod:`render.physics.friction_models`).

    A model maps a vibration amplitude (µm peak-to-peak) and a normal force (N) to the friction ratio mu/mu0
    (1 = the plate at rest) with :meth:`relative_friction`, and back with :meth:`amplitude_um_pp`, vectorised over
    numpy arrays. Build one by name with :func:`~render.physics.calibration.load_model`, or from a subclass.

    Attributes
    ----------
    name : str
        The model's name as the command takes it (``"paper"``, ``"exponential"``, ``"stretched"``, ``"table"``,
        ``"squeeze-film"``).
    max_amplitude_um_pp : float
        The largest amplitude (µm p-p) the model answers for; the inverse never exceeds it.
    fitted : FitRange or None
        Set by a calibration: the forces (N) its parameters were fitted on; None for the published defaults.

    Raises
    ------
    ModelError
        From every method: a NaN, infinite or negative amplitude, ratio or force, in one line.

    Examples
    --------
    >>> from ultraglide.render.physics.calibration import load_model
    >>> model = load_model("exponential")
    >>> isinstance(model, FrictionModel), model.name
    (True, 'exponential')
    >>> round(float(model.relative_friction(2.64, force_n=0.5)), 4)   # 1.32 µm zero-to-peak = tau: exp(-1/2)
    0.6065
    >>> result = model.amplitude_um_pp([1.0, 0.6065306597126334, 0.01], force_n=0.5, limit_um_pp=5.0)
    >>> result.amplitude_um_pp.round(2).tolist(), result.clamped   # 0.01 is out of reach: held at 5 µm
    ([0.0, 2.64, 5.0], 1)
    """

    name: str = "model"
    max_amplitude_um_pp: float = CEILING_UM_PP
    fitted: FitRange | None = None  # set by a calibration: the forces the parameters were fitted on
    _range_said = False  # the force-range warning is given once per model

    def warm_up(self) -> None:
        """Load this model's compiled inverse (from numba's cache, or compile it once per machine) before a
        real-time block needs it. Models override it with their own kernels; this loads every one.

        Examples
        --------
        Afterwards the inverse runs without compiling (its first call as fast as the next):

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> model = ExponentialModel()
        >>> model.warm_up()
        >>> model.amplitude_um_pp(np.array([1.0]), 0.5).amplitude_um_pp.tolist()     # at rest: no vibration
        [0.0]
        """
        kernels.warm_up()

    def force_law(self) -> str:
        """How this model's friction depends on the normal force, and where that comes from, in words.

        Returns
        -------
        str

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> load_model("exponential").force_law()
        'none: the same curve at every force (Monnoyer et al. did not state theirs)'
        """
        return "no force term"

    def _own_force_range_n(self) -> tuple[float, float]:
        """The forces (N) over which the model's force law holds, before any calibration."""
        return (MIN_FORCE_N, MAX_FORCE_N)

    def _range_reason(self) -> str:
        """Why the model's own range ends where it does (for the warning)."""
        return ""

    def valid_force_range_n(self) -> tuple[float, float]:
        """The forces (N) the model may be trusted on: those it was fitted on, or where its law holds.

        Returns
        -------
        (float, float)
            Low and high (N).

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> low, high = load_model("stretched").valid_force_range_n()   # eq. (3) holds up to a whole pad
        >>> low, round(high, 3)
        (0.01, 2.436)
        """
        return self.fitted.force_range_n if self.fitted is not None else self._own_force_range_n()

    def _checked_force(self, force_n) -> None:
        """Refuse a bad force (:func:`check_force`) and, once per model, say when a force leaves the
        range the model holds on (forces of 10 mN and less excepted: the finger is lifting)."""
        if is_scalar(force_n) and not isinstance(force_n, (list, tuple)):
            check_force(force_n)
            self._note_force_range(force_n)
            return
        force = np.asarray(force_n, dtype=float)
        extremes = (float(_smallest(force)), float(_largest(force))) if force.size else None
        if extremes is not None and not (extremes[0] >= 0.0 and extremes[1] < np.inf):  # NaN fails both
            check_force(force)  # names the first bad force
        self._note_force_range(force, extremes)

    def _note_force_range(self, force_n, extremes: tuple[float, float] | None = None) -> None:
        """The once-per-model warning of :meth:`_checked_force`, for forces already checked (no array
        is made: the live path calls it); ``extremes``: the forces' smallest and largest, if known."""
        if self._range_said:
            return
        range_for = self.__dict__.get("_range_for")  # (the fitted range it was computed for, low, high)
        if range_for is None or range_for[0] is not self.fitted:
            range_for = self._range_for = (self.fitted, *self.valid_force_range_n())
        _, low, high = range_for
        if is_scalar(force_n) and not isinstance(force_n, (list, tuple)):
            value = float(force_n)
            outside = value if (MIN_FORCE_N < value < low or value > high) else None
        else:
            force = np.asarray(force_n, dtype=float)
            if not force.size:
                return
            smallest, largest = extremes or (float(_smallest(force)), float(_largest(force)))
            outside = largest if largest > high else None
            if outside is None and smallest < low:
                lifted = force[force > MIN_FORCE_N]
                outside = float(lifted.min()) if lifted.size and lifted.min() < low else None
        if outside is not None:
            self._range_said = True
            warnings.warn(self._range_message(outside), ForceRangeWarning, stacklevel=3)

    def _range_message(self, force_n: float) -> str:
        low, high = self.valid_force_range_n()
        if force_n > MAX_FORCE_N:
            return (f"{force_n:g} N is above {MAX_FORCE_N:g} N, the end of a fingertip's touch range: the {self.name} "
                    f"model takes it as {MAX_FORCE_N:g} N")
        if self.fitted is not None:
            return (f"{force_n:g} N is outside the forces this {self.name} calibration was fitted on "
                    f"({self.fitted.words()}): its force law ({self.force_law()}) is extrapolated there")
        reason = self._range_reason()
        return (f"{force_n:g} N is outside {low:.3g}-{high:.3g} N, where the {self.name} model's force law holds"
                + (f" ({reason})" if reason else "") + ": it is extrapolated there")

    @abstractmethod
    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """Forward model: the friction ratio at each amplitude and force.

        Parameters
        ----------
        amplitude_um_pp : array_like
            Vibration amplitudes (µm peak-to-peak), >= 0.
        force_n : array_like
            Normal forces (N), one or one per amplitude; 0.5 N by default.

        Returns
        -------
        numpy.ndarray
            mu/mu0 at each amplitude, in [0, 1]; 1 at rest.

        Raises
        ------
        ModelError
            A NaN, infinite or negative amplitude or force.

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> load_model("stretched").relative_friction([0.0, 3.7335238], 0.5).round(3)  # at its scale: d + (1-d)/e
        array([1.   , 0.431])
        """

    @abstractmethod
    def _amplitude_in_reach(self, ratio: np.ndarray, force_n) -> np.ndarray:
        """Inverse for ratios already inside the reachable range."""

    @abstractmethod
    def describe(self) -> str:
        """One line naming the model and its parameters.

        Returns
        -------
        str

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> load_model("exponential").describe().split(",")[:2]
        ['exponential: mu/mu0 = exp(-a²/2tau²)', ' tau = 1.32 µm zero-to-peak']
        """

    def parameters(self) -> dict[str, float | str]:
        """The model's parameters as plain values, for calibration files and JSON.

        Returns
        -------
        dict
            Names with units in them (``tau_um_zp``) to numbers or strings.

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> load_model("exponential").parameters()
        {'tau_um_zp': 1.32, 'residual_ratio': 0.0}
        """
        return {}

    def __repr__(self) -> str:
        """The constructor call with the model's parameters: ``ExponentialModel(tau_um_zp=1.32)`` (a floor at the
        class's default, left out)."""
        shown = {k: v for k, v in self.parameters().items()
                 if not (k == "residual_ratio" and v == self.default_floor)}
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in shown.items())})"

    def _floor(self, force_n, limit: float):
        """The floor ratio, remembered for the last few scalar forces and limits (the live case: a closed loop
        asks at its measured force and at ±5 % of it, its limit moving with its scale); a limit on the ladder
        (:func:`ladder_limit`) at the force's rung (1 % apart), kept in fixed slots: nothing allocated or kept per
        call, a model evaluated once a new pair of rungs (a pressure panel's force and a speed law's limit both move
        block by block)."""
        if isinstance(force_n, np.ndarray) and force_n.ndim:
            return self.relative_friction(limit, force_n)
        rung = _ladder_rung(limit)
        force = float(force_n)
        if rung is not None and force > 0.0 and math.isfinite(force):  # a limit on the ladder (a speed law's)
            return self._ladder_floor(force, rung, limit)
        return remembered(self, "_floors", (float(force_n), limit),
                          lambda: float(self.relative_friction(limit, force_n)))

    def _ladder_floor(self, force_n: float, rung: int, limit: float) -> float:
        """The floor at a limit on the ladder (its ``rung``) and the force's rung: kept in one of
        :data:`LADDER_FLOOR_SLOTS` slots (open addressing over :data:`LADDER_PROBES` slots; when they are all
        taken, the first is overwritten), made when first asked (the slots are made before a block asks:
        :meth:`SpeedLawModel.warm_up <ultraglide.render.physics.speed_law.SpeedLawModel.warm_up>`)."""
        force_rung = round(math.log(force_n / DEFAULT_FORCE_N) / FORCE_RUNG_STEP)
        key = force_rung * (LADDER_RUNGS[1] - LADDER_RUNGS[0]) + (rung - LADDER_RUNGS[0])
        keys, values = self._ladder_slots()
        first = (key * 2654435761) % LADDER_FLOOR_SLOTS  # Knuth's multiplicative mixing: neighbours spread
        slot = first
        for probe in range(LADDER_PROBES):
            slot = (first + probe) % LADDER_FLOOR_SLOTS
            if keys[slot] == key:
                return float(values[slot])
            if keys[slot] == EMPTY_SLOT:
                break
        else:
            slot = first
        force = DEFAULT_FORCE_N * math.exp(force_rung * FORCE_RUNG_STEP)
        values[slot] = float(self.relative_friction(limit, force))
        keys[slot] = key
        return float(values[slot])

    def _ladder_slots(self) -> tuple[np.ndarray, np.ndarray]:
        slots = self.__dict__.get("_ladder_floor_slots")
        if slots is None:
            slots = self.__dict__["_ladder_floor_slots"] = (np.full(LADDER_FLOOR_SLOTS, EMPTY_SLOT, dtype=np.int64),
                                                             np.zeros(LADDER_FLOOR_SLOTS))
        return slots

    def floor_ratio(self, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf) -> np.ndarray | float:
        """The lowest ratio reachable at this force within the amplitude limit.

        Parameters
        ----------
        force_n : array_like
            Normal force (N), one or an array; 0.5 N by default.
        limit_um_pp : float
            The amplitude limit (µm p-p); the model's own :attr:`max_amplitude_um_pp` by default.

        Returns
        -------
        numpy.ndarray or float
            The ratio at the limit, for each force.

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> round(float(load_model("paper").floor_ratio(0.5, limit_um_pp=6.0)), 3)
        0.773
        """
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        return self.relative_friction(limit, force_n)

    def _fast_path(self, ratio, force_n, limit_um_pp, out=None) -> bool:
        """True when the compiled kernel can take the call: a 1-d float ratio array (and ``out`` a float64
        array of its length)."""
        return (isinstance(ratio, np.ndarray) and ratio.ndim == 1 and ratio.dtype.kind == "f"
                and (is_scalar(force_n) or (force_n.ndim == 1 and len(force_n) == len(ratio)))
                and limit_um_pp >= 0
                and (out is None or (out.dtype == np.float64 and out.shape == ratio.shape)))

    @staticmethod
    def _result(amplitude: np.ndarray, clamped: int, out: np.ndarray | None) -> Inversion:
        if out is not None and amplitude is not out:
            out[...] = amplitude
            amplitude = out
        return Inversion(amplitude, clamped)

    default_floor = 0.0  # the residual_ratio a model of this class has unless told otherwise
    compiled = False  # True when the model has compiled inverses (_inverse_one_force, _inverse_forces)

    def _inverse_one_force(self, ratio: np.ndarray, force_n: float, limit: float, out: np.ndarray) -> int:
        """The compiled inverse at one force into ``out``: the number clamped, or -1 - the first bad index."""
        raise NotImplementedError

    def _inverse_forces(self, ratio: np.ndarray, force_n: np.ndarray, limit: float, out: np.ndarray) -> int:
        """The compiled inverse at a force per sample (float64 arrays) into ``out``, coded as above."""
        raise NotImplementedError

    def _compiled_inverse(self, ratio, force_n, limit_um_pp, out) -> Inversion:
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        if out is None:
            out = np.empty(len(ratio))
        if is_scalar(force_n):
            self._checked_force(force_n)
            return Inversion(out, kernel_result(self._inverse_one_force(ratio, float(force_n), limit, out),
                                                ratio, force_n))
        ratio = ratio.astype(np.float64, copy=False)
        force = force_n.astype(np.float64, copy=False)
        result = Inversion(out, kernel_result(self._inverse_forces(ratio, force, limit, out), ratio, force))
        self._note_force_range(force)
        return result

    def one_amplitude_um_pp(self, ratio: float, force_n: float, limit_um_pp: float = np.inf,
                            work: np.ndarray | None = None) -> float:
        """The inverse of one ratio at one force, as a float (µm p-p): what :meth:`amplitude_um_pp` gives for it.
        ``work``: two floats to compute in (no allocation).

        Parameters
        ----------
        ratio : float
            The target ratio.
        force_n : float
            Normal force (N).
        limit_um_pp : float
            The amplitude limit (µm p-p).
        work : numpy.ndarray, optional
            Two floats to compute in.

        Returns
        -------
        float
            µm p-p.

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> round(load_model("exponential").one_amplitude_um_pp(0.5, 0.5), 4)   # 2 sqrt(2 ln 2) × 1.32 µm
        3.1084
        """
        work = np.empty(2) if work is None else work
        work[0] = ratio
        return float(self.amplitude_um_pp(work[0:1], force_n, limit_um_pp, work[1:2]).amplitude_um_pp[0])

    def amplitude_um_pp(
        self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf,
        out: np.ndarray | None = None,
    ) -> Inversion:
        """Inverse model: the smallest amplitude (µm p-p) that gives each ratio at each force.

        Parameters
        ----------
        ratio : array_like
            Target friction ratios mu/mu0; above 1 means rest (0 µm).
        force_n : array_like
            Normal forces (N), one or one per ratio; 0.5 N by default.
        limit_um_pp : float
            The amplitude limit (µm p-p), >= 0; ratios below the one at the limit are clamped to it.
        out : numpy.ndarray, optional
            A float64 array of the result's shape to write the amplitudes into; with a 1-d float ratio (a live
            block) the compiled models then allocate no array.

        Returns
        -------
        Inversion
            ``amplitude_um_pp`` (µm p-p, never above the limit nor :attr:`max_amplitude_um_pp`) and ``clamped``,
            how many ratios were out of reach.

        Raises
        ------
        ModelError
            A NaN, infinite or negative ratio or force, or a negative limit.

        Examples
        --------
        >>> from ultraglide.render.physics.calibration import load_model
        >>> result = load_model("exponential").amplitude_um_pp([1.2, 0.5, 0.01], force_n=0.5, limit_um_pp=5.0)
        >>> result.amplitude_um_pp.round(2).tolist(), result.clamped
        ([0.0, 3.11, 5.0], 1)
        """
        if self.compiled and self._fast_path(ratio, force_n, limit_um_pp, out):
            return self._compiled_inverse(ratio, force_n, limit_um_pp, out)
        if not limit_um_pp >= 0:
            raise ModelError(f"the amplitude limit must be >= 0 µm, got {limit_um_pp}")
        self._checked_force(force_n)
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        shape = np.shape(ratio) if is_scalar(force_n) else np.broadcast_shapes(np.shape(ratio), np.shape(force_n))
        ratio = np.asarray(ratio, dtype=float)
        check_ratio(ratio)
        ratio = np.minimum(ratio, 1.0)
        if ratio.ndim == 0:
            ratio = ratio.reshape(1)
        floor = self._floor(force_n, limit)
        out_of_reach = ratio < floor
        clamped = int(np.count_nonzero(out_of_reach))
        np.maximum(ratio, floor, out=ratio)
        amplitude = np.asarray(self._amplitude_in_reach(ratio, force_n), dtype=float)
        if amplitude.ndim == 0:
            amplitude = amplitude.reshape(1)
        np.minimum(amplitude, limit, out=amplitude)
        np.maximum(amplitude, 0.0, out=amplitude)
        if clamped:
            amplitude[np.broadcast_to(out_of_reach, amplitude.shape)] = limit
        return self._result(amplitude.reshape(shape), clamped, out)
