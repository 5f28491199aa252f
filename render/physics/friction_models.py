"""Friction models: amplitude and force → friction ratio, and back.

Every model maps a vibration amplitude (µm peak-to-peak) and a normal force (N) to the friction
ratio mu/mu0 (1 = plate at rest), and inverts that: which amplitude gives a target ratio. All
functions are vectorised over numpy arrays; the inverse is the real-time hot path.

Example::

    >>> from ultraglide.render.physics.friction_models import ExponentialModel
    >>> model = ExponentialModel()
    >>> result = model.amplitude_um_pp([1.0, 0.5, 0.01], force_n=0.5, limit_um_pp=5.0)
    >>> result.amplitude_um_pp.round(2).tolist(), result.clamped
    ([0.0, 3.11, 5.0], 1)

Ratios the plate cannot reach (below the ratio at the amplitude limit) are clamped to the limit
and counted in ``clamped``; ratios above 1 mean rest (0 µm). No amplitude ever exceeds
``limit_um_pp`` or the model's own validity range ``max_amplitude_um_pp``. Forces may be one
number or one per sample (a pressure-sensing panel); forces below 10 mN count as 10 mN (the
finger is lifting), forces above 10 N (a fingertip's touch range) as 10 N.
NaN, infinite or negative forces, ratios or amplitudes raise :class:`ModelError` with one line.

Every model states its force law and where it holds (:meth:`FrictionModel.force_law`,
:meth:`FrictionModel.valid_force_range_n`): assumed from the paper's detachment law, fitted by a
calibration on a range of forces, or absent. Asked about a force outside that range (10 mN and
lighter excepted: the finger is lifting), a model says so once, as a :class:`ForceRangeWarning`.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.errors import ForceRangeWarning, ModelError
from ultraglide.render.physics.fingerprint import (
    MM2_TO_M2,
    FingerParams,
    area_saturation_force_n,
    detach_amplitude_um_pp,
)
from ultraglide.render.physics.measurements import Measurements, check_describes_reduction
from ultraglide.render.physics.normal_contact import relative_friction_of_u

DEFAULT_FORCE_N = 0.5
MIN_FORCE_N = 0.01  # lighter touches are treated as 10 mN: the finger is lifting off
MAX_FORCE_N = 10.0  # a fingertip's touch range ends here (a hard press); commands refuse more
TOUCH_FORCE_RANGE_N = (0.0, MAX_FORCE_N)  # what a command accepts as a finger's normal force
CEILING_UM_PP = 20.0  # no model is evaluated beyond this: far above any plate's safe amplitude
RATIO_GRID_POINTS = 4097  # resolution of the uniform inverse tables


@dataclass(frozen=True)
class FitRange:
    """Where a calibrated model was fitted: the distinct forces of its data (N) and its point count."""

    forces_n: tuple[float, ...]
    points: int = 0

    @property
    def force_range_n(self) -> tuple[float, float]:
        return (min(self.forces_n), max(self.forces_n))

    def words(self) -> str:
        """"0.2-1 N (3 forces)" or "0.5 N only"."""
        low, high = self.force_range_n
        if len(self.forces_n) == 1:
            return f"{low:g} N only"
        return f"{low:g}-{high:g} N ({len(self.forces_n)} forces)"


@dataclass(frozen=True)
class Inversion:
    """Amplitudes for target ratios, and how many ratios were out of reach."""

    amplitude_um_pp: np.ndarray
    clamped: int


class UniformTable:
    """Piecewise-linear lookup on a uniform grid: cheap enough for tens of millions of calls a second."""

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


def _clip_force(force_n):
    return np.clip(np.asarray(force_n, dtype=float), MIN_FORCE_N, MAX_FORCE_N)


def _is_scalar(value) -> bool:
    return not isinstance(value, np.ndarray) or value.ndim == 0


def check_force(force_n) -> None:
    """Raise :class:`ModelError` unless every force is a finite number >= 0 N."""
    if _is_scalar(force_n) and not isinstance(force_n, (list, tuple)):
        value = float(force_n)
        if not (0.0 <= value < np.inf):
            raise ModelError(f"normal force must be a finite number >= 0 N, got {value}")
        return
    force = np.asarray(force_n, dtype=float)
    bad = ~((force >= 0.0) & (force < np.inf))
    if bad.any():
        raise ModelError(f"normal force must be a finite number >= 0 N, got {force[bad].flat[0]}")


def check_ratio(ratio: np.ndarray) -> None:
    """Raise :class:`ModelError` unless every friction ratio is a finite number >= 0."""
    bad = ~((ratio >= 0.0) & (ratio < np.inf))
    if bad.any():
        raise ModelError(f"friction ratio must be a finite number >= 0 (1 = plate at rest), got {ratio[bad].flat[0]}")


def check_amplitude(amplitude: np.ndarray) -> None:
    """Raise :class:`ModelError` unless every amplitude is a finite number >= 0 µm."""
    bad = ~((amplitude >= 0.0) & (amplitude < np.inf))
    if bad.any():
        raise ModelError(f"amplitude must be a finite number >= 0 µm p-p, got {amplitude[bad].flat[0]}")


def _kernel_result(code: int, ratio: np.ndarray, force) -> int:
    """A kernel's return value: a count of clamped ratios, or -1 - i for a bad sample i."""
    if code >= 0:
        return code
    i = -1 - code
    force = np.atleast_1d(force)
    check_force(force[min(i, len(force) - 1)])
    check_ratio(ratio[i:i + 1])
    raise AssertionError("a kernel reported a bad sample that passes the checks")  # pragma: no cover


class FrictionModel(ABC):
    """The interface every friction model offers; see the module docstring."""

    name: str = "model"
    max_amplitude_um_pp: float = CEILING_UM_PP
    fitted: FitRange | None = None  # set by a calibration: the forces the parameters were fitted on
    _range_said = False  # the force-range warning is given once per model

    def force_law(self) -> str:
        """How this model's friction depends on the normal force, and where that comes from, in words."""
        return "no force term"

    def _own_force_range_n(self) -> tuple[float, float]:
        """The forces (N) over which the model's force law holds, before any calibration."""
        return (MIN_FORCE_N, MAX_FORCE_N)

    def _range_reason(self) -> str:
        """Why the model's own range ends where it does (for the warning)."""
        return ""

    def valid_force_range_n(self) -> tuple[float, float]:
        """The forces (N) the model may be trusted on: those it was fitted on, or where its law holds."""
        return self.fitted.force_range_n if self.fitted is not None else self._own_force_range_n()

    def _checked_force(self, force_n) -> None:
        """Refuse a bad force (:func:`check_force`) and, once per model, say when a force leaves the
        range the model holds on (forces of 10 mN and less excepted: the finger is lifting)."""
        check_force(force_n)
        self._note_force_range(force_n)

    def _note_force_range(self, force_n) -> None:
        """The once-per-model warning of :meth:`_checked_force`, for forces already checked (no array
        is made: the live path calls it)."""
        if self._range_said:
            return
        low, high = self.valid_force_range_n()
        if _is_scalar(force_n) and not isinstance(force_n, (list, tuple)):
            value = float(force_n)
            outside = value if (MIN_FORCE_N < value < low or value > high) else None
        else:
            force = np.asarray(force_n, dtype=float)
            if not force.size:
                return
            smallest, largest = float(force.min()), float(force.max())
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
        """Forward model: friction ratio at each amplitude (µm p-p) and force (N)."""

    @abstractmethod
    def _amplitude_in_reach(self, ratio: np.ndarray, force_n) -> np.ndarray:
        """Inverse for ratios already inside the reachable range."""

    @abstractmethod
    def describe(self) -> str:
        """One line naming the model and its parameters."""

    def parameters(self) -> dict[str, float | str]:
        """The model's parameters as plain values, for calibration files and JSON."""
        return {}

    def __repr__(self) -> str:
        """The constructor call with the model's parameters: ``ExponentialModel(tau_um_zp=1.32)`` (a floor of 0,
        the default, left out)."""
        shown = {k: v for k, v in self.parameters().items() if not (k == "residual_ratio" and v == 0.0)}
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in shown.items())})"

    def _floor(self, force_n, limit: float):
        """The floor ratio, remembered for the last scalar force and limit (the live case)."""
        if isinstance(force_n, np.ndarray) and force_n.ndim:
            return self.relative_friction(limit, force_n)
        key = (float(force_n), limit)
        cached = getattr(self, "_floor_cache", None)
        if cached is None or cached[0] != key:
            cached = (key, float(self.relative_friction(limit, force_n)))
            self._floor_cache = cached
        return cached[1]

    def floor_ratio(self, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf) -> np.ndarray | float:
        """Lowest ratio reachable at this force within the amplitude limit."""
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        return self.relative_friction(limit, force_n)

    def _fast_path(self, ratio, force_n, limit_um_pp, out=None) -> bool:
        """True when the compiled kernel can take the call: a 1-d float ratio array (and ``out`` a float64
        array of its length)."""
        return (isinstance(ratio, np.ndarray) and ratio.ndim == 1 and ratio.dtype.kind == "f"
                and (_is_scalar(force_n) or (force_n.ndim == 1 and len(force_n) == len(ratio)))
                and limit_um_pp >= 0
                and (out is None or (out.dtype == np.float64 and out.shape == ratio.shape)))

    @staticmethod
    def _result(amplitude: np.ndarray, clamped: int, out: np.ndarray | None) -> Inversion:
        if out is not None and amplitude is not out:
            out[...] = amplitude
            amplitude = out
        return Inversion(amplitude, clamped)

    def amplitude_um_pp(
        self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N, limit_um_pp: float = np.inf,
        out: np.ndarray | None = None,
    ) -> Inversion:
        """Inverse model: the smallest amplitude (µm p-p) that gives each ratio at each force.
        ``out``: a float64 array of the result's shape to write the amplitudes into; with a 1-d float ratio
        (a live block) the compiled models then allocate no array."""
        if not limit_um_pp >= 0:
            raise ModelError(f"the amplitude limit must be >= 0 µm, got {limit_um_pp}")
        self._checked_force(force_n)
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        shape = np.shape(ratio) if _is_scalar(force_n) else np.broadcast_shapes(np.shape(ratio), np.shape(force_n))
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


class PaperModel(FrictionModel):
    """The seed paper's non-Coulombic bed-of-springs model (section IV), tabulated.

    The ratio depends on amplitude and force only through u = a_pp / detach_amplitude_um_pp(F)
    (see :mod:`render.physics.normal_contact`), so one table over u serves every force. The detachment
    amplitude scales as F^(1 - area_exponent) (F^(1/3) with the paper's A = k F^(2/3)). It predicts
    a modest reduction (to about 0.72 at 10 µm and 0.5 N) and never full levitation.
    """

    name = "paper"
    U_NODES = 384

    def __init__(self, params: FingerParams = FingerParams()):
        self.params = params
        self._detach_exponent = 1.0 - params.area_exponent
        # eq. (6) without the area's cap: 2 F / k_n at 1 N, k_n = E k (1 N)^(2/3) / h
        self._detach_at_1n = 2.0e6 * params.ridge_height_m / (
            params.youngs_modulus_pa * params.area_coefficient_mm2 * MM2_TO_M2)
        self._saturation_n = area_saturation_force_n(params)
        # the table covers every amplitude up to the ceiling at every force in range
        smallest_detach = float(np.min(self._detach_um_pp(np.array([MIN_FORCE_N, MAX_FORCE_N]))))
        u_max = max(CEILING_UM_PP / smallest_detach, 4.0)
        self.u_nodes = u_max * np.linspace(0.0, 1.0, self.U_NODES) ** 2
        ratio = relative_friction_of_u(self.u_nodes, params, phase_points=192, ring_nodes=32)
        self.ratio_nodes = np.minimum.accumulate(ratio)  # guard monotonicity against rounding
        ratio_grid = np.linspace(self.ratio_nodes[-1], 1.0, RATIO_GRID_POINTS)
        # the inverse of a flat stretch is its smallest amplitude: interp on reversed nodes
        u_of_ratio = np.interp(ratio_grid, self.ratio_nodes[::-1], self.u_nodes[::-1])
        self._u_table = UniformTable(ratio_grid[0], 1.0, u_of_ratio)

    def _detach_um_pp(self, force_n, clip: bool = True):
        """W_c (µm p-p) at each force: ∝ F^(1 - area exponent) until the area reaches a fingertip's, then ∝ F.
        Forces are clipped to the models' range unless ``clip`` is False."""
        force = _clip_force(force_n) if clip else np.asarray(force_n, dtype=float)
        return (self._detach_at_1n * np.power(np.minimum(force, self._saturation_n), self._detach_exponent)
                * np.maximum(force / self._saturation_n, 1.0))

    def force_law(self) -> str:
        return (f"W_c ∝ F^{self._detach_exponent:.3g} from eqs. (1), (3), (6), ∝ F above "
                f"{self._saturation_n:.3g} N where the area is a fingertip's")

    def _own_force_range_n(self) -> tuple[float, float]:
        return (MIN_FORCE_N, min(self._saturation_n, MAX_FORCE_N))

    def _range_reason(self) -> str:
        return (f"above {self._saturation_n:.3g} N eq. (3)'s contact area would exceed a fingertip's pad, "
                f"{self.params.max_contact_area_mm2:g} mm², and is held there")

    @staticmethod
    def detach_um_pp_for(params: FingerParams, force_n):
        """Detachment amplitude (µm p-p) at each force, forces clipped to the models' range."""
        return detach_amplitude_um_pp(_clip_force(force_n), params)

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        self._checked_force(force_n)
        amplitude = np.asarray(amplitude_um_pp, dtype=float)
        check_amplitude(amplitude)
        return np.interp(amplitude / self._detach_um_pp(force_n), self.u_nodes, self.ratio_nodes)

    def _amplitude_in_reach(self, ratio, force_n):
        return self._u_table(ratio) * self._detach_um_pp(force_n)

    def _detach_at(self, force_n) -> float:
        """The detachment amplitude at one force, remembered for the last force (the live case)."""
        force = float(force_n)
        cached = getattr(self, "_detach_cache", None)
        if cached is None or cached[0] != force:
            cached = self._detach_cache = (force, float(self._detach_um_pp(force)))
        return cached[1]

    def amplitude_um_pp(self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N,
                        limit_um_pp: float = np.inf, out: np.ndarray | None = None) -> Inversion:
        if not self._fast_path(ratio, force_n, limit_um_pp, out):
            return super().amplitude_um_pp(ratio, force_n, limit_um_pp, out)
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        table = self._u_table
        if out is None:
            out = np.empty(len(ratio))
        if _is_scalar(force_n):
            self._checked_force(force_n)
            code = kernels.inverse_uniform(ratio, self._floor(force_n, limit), limit, table.start, table.scale,
                                           table.values, table.slopes, self._detach_at(force_n), out)
            return Inversion(out, _kernel_result(code, ratio, force_n))
        ratio = ratio.astype(np.float64, copy=False)
        force = force_n.astype(np.float64, copy=False)
        code = kernels.inverse_uniform_forces(ratio, force, limit, table.start, table.scale, table.values,
                                              table.slopes, self._detach_at_1n, self._detach_exponent,
                                              self._saturation_n, MIN_FORCE_N, MAX_FORCE_N, out)
        result = Inversion(out, _kernel_result(code, ratio, force))
        self._note_force_range(force)
        return result

    def describe(self) -> str:
        p = self.params
        return (
            f"paper: ridge springs with non-Coulombic friction (E = {p.youngs_modulus_pa / 1e6:g} MPa, "
            f"n = {p.friction_exponent:.3g}, A ∝ F^{p.area_exponent:.3g}, {p.contact} contact)"
        )

    def parameters(self) -> dict[str, float | str]:
        p = self.params
        return {
            "youngs_modulus_pa": p.youngs_modulus_pa,
            "friction_exponent": p.friction_exponent,
            "area_exponent": p.area_exponent,
        }

    def __repr__(self) -> str:
        """``PaperModel()`` with the paper's parameters, else ``PaperModel(FingerParams(...))`` with those that
        differ."""
        changed = {k: v for k, v in vars(self.params).items() if v != getattr(FingerParams(), k)}
        inner = f"FingerParams({', '.join(f'{k}={v!r}' for k, v in changed.items())})" if changed else ""
        return f"PaperModel({inner})"


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
ASSUMED_FORCE_EXPONENT = 1.0 / 3.0  # W_c ∝ F^(1/3): eq. (6) with eq. (3)'s A ∝ F^(2/3)


class StretchedExponentialModel(FrictionModel):
    """A force-aware empirical law with a floor: mu/mu0 = d + (1 - d) exp(-(a_pp / s(F))^beta),
    s(F) = s0 (F / 0.5 N)^p.

    ``scale_um_pp`` s0 is the amplitude (µm p-p) at which the reducible part of friction falls to
    1/e at 0.5 N; ``shape`` beta sets how sudden the fall is (2 is Gaussian, Monnoyer's law; below 1
    it starts steeply); ``force_exponent`` p makes harder presses need more vibration;
    ``residual_ratio`` d is the friction vibration does not remove (Huloux et al. 2018's floor,
    f = f0 exp(-a² tau) + d, over friction at rest; 0 by default). The defaults are Monnoyer et al.'s
    published curve at 0.5 N (s0 = 2 sqrt 2 x 1.32 µm = 3.73 µm p-p, beta = 2, no floor) with
    p = 1/3, **assumed**: the force law of the paper's detachment amplitude (W_c = 2 F / k_n with
    A ∝ F^(2/3), eqs. 1, 3, 6), since the bundled curve has a single force. It holds where eq. (3)
    does, up to the force at which the contact area is a fingertip's (2.4 N). A calibration at two
    forces or more fits p and replaces that range by the forces it was fitted on (:attr:`fitted`).
    Any s0 > 0, beta > 0 gives a strictly decreasing curve; values outside the allowed ranges are
    refused.
    """

    name = "stretched"

    def __init__(self, scale_um_pp: float = MONNOYER_SCALE_UM_PP, shape: float = 2.0,
                 force_exponent: float = ASSUMED_FORCE_EXPONENT, residual_ratio: float = 0.0):
        self.scale_um_pp = _in_range("scale_um_pp", scale_um_pp, SCALE_RANGE_UM_PP, " µm p-p")
        self.shape = _in_range("shape", shape, SHAPE_RANGE)
        self.force_exponent = _in_range("force_exponent", force_exponent, FORCE_EXPONENT_RANGE)
        self.residual_ratio = _in_range("residual_ratio", residual_ratio, RESIDUAL_RANGE)

    def force_law(self) -> str:
        law = f"s ∝ F^{self.force_exponent:.3g}"
        fitted = self.fitted
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
        """s(F), µm p-p: the amplitude that brings the reducible friction to 1/e at this force."""
        return self.scale_um_pp * np.power(_clip_force(force_n) / REFERENCE_FORCE_N, self.force_exponent)

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
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
        """s(F) at one force as a float, remembered for the last force (the live case)."""
        force = float(force_n)
        cached = getattr(self, "_scale_cache", None)
        if cached is None or cached[0] != force:
            cached = self._scale_cache = (force, float(self.scale_at_um_pp(force)))
        return cached[1]

    def amplitude_um_pp(self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N,
                        limit_um_pp: float = np.inf, out: np.ndarray | None = None) -> Inversion:
        if not self._fast_path(ratio, force_n, limit_um_pp, out):
            return super().amplitude_um_pp(ratio, force_n, limit_um_pp, out)
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        if out is None:
            out = np.empty(len(ratio))
        if _is_scalar(force_n):
            self._checked_force(force_n)
            code = kernels.inverse_stretched(ratio, self._floor(force_n, limit), limit, self._scale_at(force_n),
                                             1.0 / self.shape, self.residual_ratio, out)
            return Inversion(out, _kernel_result(code, ratio, force_n))
        ratio = ratio.astype(np.float64, copy=False)
        force = force_n.astype(np.float64, copy=False)
        code = kernels.inverse_stretched_forces(ratio, force, limit, self.scale_um_pp, 1.0 / self.shape,
                                                self.force_exponent, REFERENCE_FORCE_N, MIN_FORCE_N, MAX_FORCE_N,
                                                self.residual_ratio, out)
        result = Inversion(out, _kernel_result(code, ratio, force))
        self._note_force_range(force)
        return result

    def _floor_words(self) -> str:
        return f", floor d = {self.residual_ratio:.3g}" if self.residual_ratio else ""

    def describe(self) -> str:
        return (f"stretched: mu/mu0 = exp(-(a/s)^beta), s = {self.scale_um_pp:.4g} µm p-p x (F/0.5 N)^"
                f"{self.force_exponent:.3g}, beta = {self.shape:.3g}{self._floor_words()}; force law: "
                f"{self.force_law()}")

    def parameters(self) -> dict[str, float | str]:
        return {"scale_um_pp": self.scale_um_pp, "shape": self.shape, "force_exponent": self.force_exponent,
                "residual_ratio": self.residual_ratio}


TAU_RANGE_UM_ZP = (0.02, 35.0)  # within the scale range once converted: s0 = 2 sqrt 2 tau


class ExponentialModel(StretchedExponentialModel):
    """Empirical law of Monnoyer et al. (IEEE Trans. Haptics 2018): mu/mu0 = exp(-a²/(2 tau²)), with
    Huloux et al. (2018)'s floor d when ``residual_ratio`` is given: d + (1 - d) exp(-a²/(2 tau²)).

    The published a and tau are zero-to-peak (tau = 1.32 µm); here a = a_pp / 2. The law has no
    force term (Monnoyer et al. did not state the force), so the force is checked and otherwise
    ignored: the stretched model with beta = 2, p = 0 and s0 = 2 sqrt 2 tau.
    """

    name = "exponential"

    def __init__(self, tau_um_zp: float = MONNOYER_TAU_UM_ZP, residual_ratio: float = 0.0):
        self.tau_um_zp = _in_range("tau_um_zp", tau_um_zp, TAU_RANGE_UM_ZP, " µm zero-to-peak")
        super().__init__(2.0 * np.sqrt(2.0) * self.tau_um_zp, 2.0, 0.0, residual_ratio)

    def force_law(self) -> str:
        return "none: the same curve at every force (Monnoyer et al. did not state theirs)"

    def _own_force_range_n(self) -> tuple[float, float]:
        return (MIN_FORCE_N, MAX_FORCE_N)

    def describe(self) -> str:
        return (f"exponential: mu/mu0 = exp(-a²/2tau²), tau = {self.tau_um_zp:.4g} µm zero-to-peak"
                f"{self._floor_words()}; force law: {self.force_law()}")

    def parameters(self) -> dict[str, float | str]:
        return {"tau_um_zp": self.tau_um_zp, "residual_ratio": self.residual_ratio}


class TableModel(FrictionModel):
    """Measured points, interpolated monotonically (PCHIP) in amplitude and linearly in force.

    Points that rise with amplitude (measurement noise) are first made non-increasing by isotonic
    regression, per force. With several forces, amplitudes for a ratio are interpolated linearly
    between the neighbouring forces and held beyond the ends; the forward model is the exact
    inverse of that, found by bisection. The reachable range ends at the largest measured amplitude.
    """

    name = "table"

    def __init__(self, data: Measurements):
        from scipy.interpolate import PchipInterpolator  # imported here: scipy.interpolate takes 0.3-0.8 s to load
        from scipy.optimize import isotonic_regression  # imported here: it loads all of scipy.optimize

        check_describes_reduction(data, data.source)
        forces = data.force_n if data.force_n is not None else np.full(len(data), DEFAULT_FORCE_N)
        self.source = data.source
        self.forces = np.unique(forces)
        self.max_amplitude_um_pp = float(min(
            data.amplitude_um_pp[forces == f].max() for f in self.forces
        ))
        rows = []
        self.floors = []
        for force in self.forces:
            pick = forces == force
            amplitude = data.amplitude_um_pp[pick]
            if len(np.unique(amplitude)) < 2:
                raise ModelError(f"{self.source}: at {force:g} N there must be two amplitudes or more")
            order = np.argsort(amplitude)
            amplitude, ratio = amplitude[order], data.relative_friction[pick][order]
            amplitude, first = np.unique(amplitude, return_index=True)
            ratio = np.minimum(isotonic_regression(ratio[first], increasing=False).x, 1.0)
            curve = PchipInterpolator(amplitude, ratio, extrapolate=False)
            fine = np.linspace(0.0, self.max_amplitude_um_pp, 2049)
            fine_ratio = curve(np.clip(fine, amplitude[0], amplitude[-1]))
            fine_ratio = np.minimum.accumulate(np.minimum(fine_ratio, 1.0))
            self.floors.append(fine_ratio[-1])
            rows.append(fine_ratio)
        self.floor = float(max(self.floors))
        grid = np.linspace(min(self.floors), 1.0, RATIO_GRID_POINTS)
        fine = np.linspace(0.0, self.max_amplitude_um_pp, 2049)
        inverse = np.array([np.interp(grid, r[::-1], fine[::-1]) for r in rows])
        self._table = UniformTable(grid[0], 1.0, inverse)

    def _row_weights(self, force_n):
        force = np.clip(np.asarray(force_n, dtype=float), self.forces[0], self.forces[-1])
        upper = np.clip(np.searchsorted(self.forces, force), 1, max(len(self.forces) - 1, 1))
        if len(self.forces) == 1:
            return np.zeros_like(force, dtype=np.intp), np.zeros_like(force)
        lower = upper - 1
        weight = (force - self.forces[lower]) / (self.forces[upper] - self.forces[lower])
        return lower, weight

    def _amplitude_in_reach(self, ratio, force_n):
        if len(self.forces) == 1:
            return self._table(ratio)
        lower, weight = self._row_weights(force_n)
        shape = np.broadcast(ratio, lower).shape
        ratio, lower, weight = (np.broadcast_to(x, shape).ravel() for x in (ratio, lower, weight))
        low = np.empty(len(ratio))
        high = np.empty(len(ratio))
        for row in np.unique(lower):  # a handful of force rows, not samples
            pick = lower == row
            low[pick] = self._table(ratio[pick], int(row))
            high[pick] = self._table(ratio[pick], int(row) + 1)
        return ((1.0 - weight) * low + weight * high).reshape(shape)

    def amplitude_um_pp(self, ratio: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N,
                        limit_um_pp: float = np.inf, out: np.ndarray | None = None) -> Inversion:
        if not self._fast_path(ratio, force_n, limit_um_pp, out):
            return super().amplitude_um_pp(ratio, force_n, limit_um_pp, out)
        limit = min(float(limit_um_pp), self.max_amplitude_um_pp)
        table = self._table
        if out is None:
            out = np.empty(len(ratio))
        if _is_scalar(force_n):
            self._checked_force(force_n)
            code = kernels.inverse_table_force(ratio, float(force_n), limit, table.start, table.scale, table.values,
                                               table.slopes, self.forces, out)
            return Inversion(out, _kernel_result(code, ratio, force_n))
        ratio = ratio.astype(np.float64, copy=False)
        force = force_n.astype(np.float64, copy=False)
        code = kernels.inverse_table_forces(ratio, force, limit, table.start, table.scale, table.values,
                                            table.slopes, self.forces, out)
        result = Inversion(out, _kernel_result(code, ratio, force))
        self._note_force_range(force)
        return result

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        self._checked_force(force_n)
        amplitude = np.asarray(amplitude_um_pp, dtype=float)
        check_amplitude(amplitude)
        shape = np.broadcast(amplitude, np.asarray(force_n)).shape
        low = np.full(shape, float(self._table.start))
        high = np.ones(shape)
        target = np.broadcast_to(np.minimum(amplitude, self.max_amplitude_um_pp), shape)
        # bisection for the largest ratio whose amplitude reaches the target: where a force's curve
        # ends above the lowest floor, its inverse holds the end amplitude, and the answer is its floor
        for _ in range(48):
            middle = 0.5 * (low + high)
            above = self._amplitude_in_reach(middle, force_n) >= target
            low = np.where(above, middle, low)
            high = np.where(above, high, middle)
        return 0.5 * (low + high)

    def force_law(self) -> str:
        if len(self.forces) == 1:
            return f"none: measured at {self.forces[0]:g} N only, the same curve at every force"
        return f"measured at {len(self.forces)} forces, amplitudes linear in force between them"

    def _own_force_range_n(self) -> tuple[float, float]:
        if len(self.forces) == 1:
            return (MIN_FORCE_N, MAX_FORCE_N)
        return (float(self.forces[0]), float(self.forces[-1]))

    def _range_reason(self) -> str:
        return "the forces measured; beyond them the nearest force's curve is held"

    def describe(self) -> str:
        forces = ", ".join(f"{f:g}" for f in self.forces)
        return f"table: {self.source} ({forces} N, up to {self.max_amplitude_um_pp:g} µm p-p)"

    def parameters(self) -> dict[str, float | str]:
        return {"source": self.source}

    def __repr__(self) -> str:
        """``TableModel('finger.csv', forces 0.2–1 N)``: where its points came from."""
        forces = (f"force {self.forces[0]:g} N" if len(self.forces) == 1
                  else f"forces {self.forces[0]:g}–{self.forces[-1]:g} N")
        return f"TableModel({self.source!r}, {forces})"
