"""The friction controller: the model's inverse, adapted to the finger, with a fast correction, or open loop.

:class:`ClosedLoopInverse` stands in for the friction model in the renderer (it has the model's
``amplitude_um_pp(ratio, force_n, limit_um_pp, out)``), so the loop acts on the amplitude *target*, before
the envelope, the output stage and its limiter, whose guarantee is untouched. For each block of target
ratios it computes:

* the **open-loop** amplitude: the host model's inverse at the force the renderer gives (the touch panel's
  or the default), as without the loop;
* while the loop **follows**, the **adaptive inverse** ``a = k (1 + g) A(r*, F)``: ``A`` the model's inverse at
  the *measured* normal force ``F``, ``k`` the scale the estimator adapted online
  (:mod:`render.engine.friction_estimator`), and ``g`` the **fast correction**, an integral of the measured
  ratio error (:class:`FastCorrection`). The amplitude stays within the limit (the inverse is asked for
  ``limit / (k (1 + g))``): what the plate cannot reach is held at the limit and counted, never above it.

A scale on the amplitude, not an offset, is what the correction moves: where the texture asks for no
reduction (ratio 1) the amplitude stays 0, whatever the finger.

The loop falls back to open loop whenever the estimate says the finger rests, lifts, or a sensor faults,
or the sensors fall silent (checked here, every block), and its words say so. Falling back switches to
the open-loop amplitude at once, so the amplitude never jumps above the open-loop amplitude; coming back,
it blends from the open-loop amplitude to the closed loop's over ``blend_s``.

The force the inverse is computed at is 15-25 ms old when its amplitude plays (the sensors, a SENSORS frame, the
link, the jitter buffer). While it follows, each block also leaves :attr:`ClosedLoopInverse.force_reference`: that
force and the model's local force exponent d ln a / d ln F there (:func:`force_exponent`), which a device with
the force correction (protocol v3's SETPOINTS_FORCE) uses to rescale the values by the force it measures as they
play (docs/design.md, "Steps and the force's age").

The block path (:meth:`ClosedLoopInverse.amplitude_um_pp`) reads one snapshot (:class:`LoopCommand`,
replaced whole by the thread that takes the sensors) and allocates nothing for blocks up to its capacity.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from ultraglide.render.physics.friction_models import DEFAULT_FORCE_N, FrictionModel, Inversion
from ultraglide.render.physics.speed_law import reach_limit

FORCE_STEP = 0.05  # the central difference's half step in ln F (±5 %)
MAX_FORCE_EXPONENT = 2.0  # what SETPOINTS_FORCE carries (docs/protocol.md)


def force_exponent(model: FrictionModel, ratio: float, force_n: float, work: np.ndarray | None = None) -> float:
    """The model's local force sensitivity of its inverse, d ln a / d ln F, at a target ratio and a force.

    A central difference of the model's own inverse over ±5 % in force (no limit): exact for the laws whose
    amplitude is a power of the force (``stretched``: its ``force_exponent``, 1/3 by default; ``paper``: 1/3
    below the force where the contact area saturates; ``exponential``: 0), the local slope for a ``table``.
    0 where the ratio asks for no vibration (a = 0). Within ±2.

    Parameters
    ----------
    model : FrictionModel
        The host's friction model.
    ratio : float
        The target friction ratio.
    force_n : float
        The normal force, N.
    work : numpy.ndarray, optional
        Three floats to compute in (no allocation).

    Returns
    -------
    float
        d ln(amplitude) / d ln(force), within ±2.

    Examples
    --------
    >>> from ultraglide.render.physics.friction_models import ExponentialModel, StretchedExponentialModel
    >>> round(force_exponent(StretchedExponentialModel(), 0.5, 1.0), 9), force_exponent(ExponentialModel(), 0.5, 1.0)
    (0.333333333, 0.0)
    >>> force_exponent(StretchedExponentialModel(), 1.0, 1.0)   # no vibration asked
    0.0
    """
    if not ratio < 1.0 or not force_n > 0.0:
        return 0.0
    work = np.empty(3) if work is None else work
    up = model.one_amplitude_um_pp(ratio, force_n * math.exp(FORCE_STEP), np.inf, work[0:2])
    down = model.one_amplitude_um_pp(ratio, force_n * math.exp(-FORCE_STEP), np.inf, work[1:3])
    if not (up > 0.0 and down > 0.0):
        return 0.0
    exponent = math.log(up / down) / (2.0 * FORCE_STEP)
    return min(max(exponent, -MAX_FORCE_EXPONENT), MAX_FORCE_EXPONENT)


@dataclass(frozen=True)
class ControllerSettings:
    """The fast correction's integral time (s) and range (a fraction of the amplitude), the blend back into
    closed loop (s), and the sensors' silence that counts as a fault (s).

    Raises
    ------
    ValueError
        An integral time, correction range, blend or silence out of range.

    Examples
    --------
    >>> ControllerSettings().integral_time_s, ControllerSettings(blend_s=0.0).blend_s
    (0.15, 0.0)
    >>> ControllerSettings(integral_time_s=0.0)
    Traceback (most recent call last):
    ...
    ValueError: the correction's integral time must lie in 0.001..100 s, got 0.0
    """

    integral_time_s: float = 0.15
    correction_low: float = -0.5
    correction_high: float = 1.0
    blend_s: float = 0.05
    sensor_silence_s: float = 0.1

    def __post_init__(self) -> None:
        if not 0.001 <= self.integral_time_s <= 100.0:
            raise ValueError(f"the correction's integral time must lie in 0.001..100 s, got {self.integral_time_s}")
        if not -0.9 <= self.correction_low <= 0.0 <= self.correction_high <= 4.0:
            raise ValueError("the correction's range must hold 0, from -0.9 to 4")
        if not 0.0 <= self.blend_s <= 10.0 or not 0.005 <= self.sensor_silence_s <= 10.0:
            raise ValueError("the blend must be 0-10 s and the sensors' silence 0.005-10 s")


@dataclass(frozen=True)
class LoopCommand:
    """What the block path acts on, replaced whole: ``following`` (else open loop), the amplitude scale
    ``k (1 + g)``, the measured normal force (N), since when it follows and when sensors last came
    (perf_counter s), and the loop's state in words.

    Examples
    --------
    A new loop renders open loop until its sensors speak:

    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> command = ClosedLoopInverse(StretchedExponentialModel()).command
    >>> command.following, command.scale, command.words
    (False, 1.0, 'open loop: waiting for the sensors')
    """

    following: bool = False
    scale: float = 1.0
    force_n: float = DEFAULT_FORCE_N
    since_s: float = 0.0
    sensors_s: float = -math.inf
    words: str = "open loop: waiting for the sensors"


class FastCorrection:
    """Integral action on the ratio error through the model's local slope.

    ``g`` scales the amplitude. The error it acts on is the measured ratio minus the ratio the controller
    meant at the amplitude the plate actually reached (``r(a / (k (1 + g)))``): the tracking error less the
    part the plate's own dynamics make (the amplitude loop's job). A sample's sensitivity
    ``s = d(ratio)/d(ln a)`` (the model's local slope times the amplitude, <= 0) turns its error into the change
    of ``g`` that would cancel it: over a batch ``-sum(s e) / (n P)``, taken a fraction ``duration / integral_time_s``
    at a time, where ``P`` is the mean of ``s²`` over the recent batches (the same time constant), or the batch's own
    where larger. With the typical slope that is the batch's least-squares change: an integrator of time constant
    ``integral_time_s`` whatever the local slope, slow beside the sensors' and the link's delay (tens of ms). A batch
    whose slope is small (the tail of a decay toward ratio 1, where the amplitude is nearly zero) moves ``g`` as
    little as it tells about it: its error there is mostly the estimate of friction at rest, not the amplitude's
    scale. (Normalising each batch by its own ``sum(s²)`` divided such errors by a slope near zero: on a plate of
    twice the profile's Q, whose decays are twice as long, each step back to ratio 1 pushed ``g`` up by 0.3-0.5 and
    steps 1 -> 0.5 then settled 5-8 % too slippery.) Measured at the amplitude reached, the error does not grow
    while the amplitude is held at the limit: nothing winds up; ``g`` also stays within its range. With a host
    model that has friction dynamics, the loop (:class:`render.engine.friction_loop.FrictionLoop`) gives it the
    measured ratio less the plan's felt ratio instead, so that what the plate's late delivery of the plan costs is
    corrected too: that error persists where the plate cannot deliver the plan, and ``g`` then rests at the end of
    its range (``correction_high``), not beyond it.

    Examples
    --------
    Measured friction 0.1 below what was meant, through a slope of -0.5 per unit of ln a, for 15 ms (a tenth of
    the 150 ms integral time): g moves by -(s e) / s² × 0.1 = -0.02 (less amplitude, more friction):

    >>> import numpy as np
    >>> correction = FastCorrection(ControllerSettings())
    >>> round(correction.update(np.full(10, -0.1), np.full(10, -0.5), 0.015), 9)
    -0.02
    >>> correction.reset(); correction.value
    0.0
    """

    def __init__(self, settings: ControllerSettings):
        self.settings = settings
        self.value = 0.0
        self.power = math.nan  # the mean of s² over recent batches (NaN: none yet)

    def reset(self) -> None:
        """Forget the correction: ``g`` back to 0, the slope's mean power unknown.

        Examples
        --------
        >>> import numpy as np
        >>> correction = FastCorrection(ControllerSettings())
        >>> _ = correction.update(np.full(10, -0.1), np.full(10, -0.5), 0.015)
        >>> correction.reset()
        >>> correction.value, bool(np.isnan(correction.power))
        (0.0, True)
        """
        self.value = 0.0
        self.power = math.nan

    def update(self, error: np.ndarray, sensitivity: np.ndarray, duration_s: float) -> float:
        """``error`` measured minus intended ratio (NaN: not used), ``sensitivity`` d(ratio)/d(ln a), over one
        batch of ``duration_s``; returns the new ``g``.

        Parameters
        ----------
        error : numpy.ndarray
            Measured minus intended friction ratio per sample (NaN: not used).
        sensitivity : numpy.ndarray
            d(ratio)/d(ln a) per sample.
        duration_s : float
            The batch's duration, s.

        Returns
        -------
        float
            The new ``g``.

        Examples
        --------
        Friction 0.1 above what was meant, slope -0.5, 15 ms of the 150 ms integral time: g rises by 0.02 (more
        amplitude, less friction); samples without a measurement change nothing:

        >>> import numpy as np
        >>> correction = FastCorrection(ControllerSettings())
        >>> correction.update(np.full(3, np.nan), np.full(3, -0.5), 0.015)
        0.0
        >>> round(correction.update(np.full(10, 0.1), np.full(10, -0.5), 0.015), 9)
        0.02
        """
        usable = np.isfinite(error)
        s = sensitivity[usable]
        n = len(s)
        if n == 0:
            return self.value
        batch_power = float(np.dot(s, s)) / n
        fraction = min(1.0, duration_s / self.settings.integral_time_s)
        if math.isnan(self.power):
            if batch_power < 1e-4:  # no slope to act through yet (ratio near 1, amplitude near 0)
                return self.value
            self.power = batch_power
        else:
            self.power += fraction * (batch_power - self.power)
        step = -float(np.dot(s, error[usable])) / (n * max(self.power, batch_power))
        value = self.value + fraction * step
        self.value = min(max(value, self.settings.correction_low), self.settings.correction_high)
        return self.value


class ClosedLoopInverse:
    """The renderer's friction model while the loop runs; see the module docstring. ``model``: the host's
    model, ``capacity``: the longest block computed without allocating.

    Examples
    --------
    Open loop (no sensors yet) it gives the host model's amplitudes:

    >>> import numpy as np
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> model = StretchedExponentialModel()
    >>> inverse = ClosedLoopInverse(model)
    >>> inverse.name, inverse.following_now(0.0)[0]
    ('stretched', False)
    >>> bool(np.array_equal(inverse.amplitude_um_pp(np.array([0.5]), 0.5).amplitude_um_pp,
    ...                     model.amplitude_um_pp(np.array([0.5]), 0.5).amplitude_um_pp))
    True
    """

    def __init__(self, model: FrictionModel, settings: ControllerSettings | None = None, capacity: int = 4096,
                 clock=time.perf_counter):
        self.base = model
        self.clock = clock  # perf_counter s (a simulation may give its own)
        self.settings = settings or ControllerSettings()
        self.command = LoopCommand()
        self.name = model.name
        self.max_amplitude_um_pp = model.max_amplitude_um_pp
        self._open = np.zeros(capacity)
        self._at_reach = np.zeros(capacity, dtype=bool)
        self.open_samples = 0  # rendered open loop (the loop not following)
        self.closed_samples = 0
        self.fallbacks = 0  # times it fell back from following
        self.fallback_reasons: dict[str, int] = {}  # how many times for each reason (the loop's words then)
        self._was_following = False
        self.state_words = self.command.words
        self._reference: tuple | None = None  # (model, lowest target ratio, force N) of the last block, following
        self._reference_value: tuple | None = None  # (that tuple, its force_reference): computed once, when asked
        self._work = np.zeros(3)

    @property
    def force_reference(self) -> tuple[float, float] | None:
        """(force N, d ln a / d ln F) the last block was computed at while the loop follows, else None. The exponent
        is computed when first asked for (once a block): a device without the force correction never pays for it.

        Examples
        --------
        Following, the stretched law's amplitude grows as F^(1/3) (its force exponent): d ln a / d ln F = 1/3:

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> inverse = ClosedLoopInverse(model, clock=lambda: 10.0)                 # its clock: 10 s
        >>> inverse.command = LoopCommand(following=True, scale=1.5, force_n=0.5, since_s=0.0, sensors_s=9.99,
        ...                               words="closed loop: following")
        >>> print(inverse.force_reference)                                       # no block yet
        None
        >>> _ = inverse.amplitude_um_pp(np.array([0.5]), 0.5)
        >>> force_n, exponent = inverse.force_reference
        >>> force_n, round(exponent, 9)
        (0.5, 0.333333333)
        """
        reference = self._reference
        if reference is None:
            return None
        known = self._reference_value
        if known is None or known[0] is not reference:
            model, lowest, force_n = reference
            known = self._reference_value = (reference, (force_n, force_exponent(model, lowest, force_n, self._work)))
        return known[1]

    def __repr__(self) -> str:
        return f"ClosedLoopInverse({self.base!r}, {self.state_words!r})"

    # ---- the model's interface, as the renderer uses it ----
    def describe(self) -> str:
        """The host model's line, and that the loop closes on the plate's force sensors.

        Returns
        -------
        str

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> ClosedLoopInverse(ExponentialModel()).describe().endswith("; closed loop on the plate's force sensors")
        True
        """
        return f"{self.base.describe()}; closed loop on the plate's force sensors"

    def parameters(self) -> dict:
        """The host model's parameters.

        Returns
        -------
        dict

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> ClosedLoopInverse(ExponentialModel()).parameters() == ExponentialModel().parameters()
        True
        """
        return self.base.parameters()

    def warm_up(self) -> None:
        """The host model's compiled inverse loaded before a real-time block needs it.

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> inverse = ClosedLoopInverse(StretchedExponentialModel())
        >>> inverse.warm_up()
        >>> inverse.amplitude_um_pp(np.array([1.0]), 0.5).amplitude_um_pp.tolist()        # at rest: no vibration
        [0.0]
        """
        self.base.warm_up()

    def relative_friction(self, amplitude_um_pp, force_n=DEFAULT_FORCE_N):
        """The host model's forward law (µm p-p and N to the ratio).

        Parameters
        ----------
        amplitude_um_pp : array_like
            µm p-p.
        force_n : array_like
            N.

        Returns
        -------
        numpy.ndarray

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> bool(np.array_equal(ClosedLoopInverse(model).relative_friction([0.0, 3.0], 0.5),
        ...                     model.relative_friction([0.0, 3.0], 0.5)))
        True
        """
        return self.base.relative_friction(amplitude_um_pp, force_n)

    def floor_ratio(self, force_n=DEFAULT_FORCE_N, limit_um_pp: float = np.inf):
        """The host model's lowest ratio at this force (N) within the limit (µm p-p).

        Parameters
        ----------
        force_n : array_like
            N.
        limit_um_pp : float
            µm p-p.

        Returns
        -------
        numpy.ndarray or float

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> bool(ClosedLoopInverse(model).floor_ratio(0.5, 6.0) == model.floor_ratio(0.5, 6.0))
        True
        """
        return self.base.floor_ratio(force_n, limit_um_pp)

    @property
    def dynamics(self):
        """The host model's friction dynamics (None for a static model): the renderer plans against them while
        the loop runs as it does open loop, and the estimator predicts the friction through them.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> print(ClosedLoopInverse(StretchedExponentialModel()).dynamics)            # a static model has none
        None
        """
        return getattr(self.base, "dynamics", None)

    @property
    def speed_law(self):
        """The host model's settled speed law (None without one): the renderer scales the loop's amplitudes by it at
        the finger's speed as it does open loop (:func:`~ultraglide.render.physics.speed_law.scaled_inverse`), and
        the estimator fits the finger through it.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> print(ClosedLoopInverse(StretchedExponentialModel()).speed_law)
        None
        """
        return getattr(self.base, "speed_law", None)

    def _floor(self, force_n, limit: float):
        """The floor ratio for the planner: the host model's at the limit the loop's scale leaves it (µm p-p), on
        the ladder's rung as the inverse asks it (a scale new with every sensors' frame evaluates no model)."""
        following, command, _ = self.following_now()
        if not following:
            return self.base._floor(force_n, limit)
        return self.base._floor(command.force_n, reach_limit(limit, command.scale))

    def following_now(self, now_s: float | None = None) -> tuple[bool, LoopCommand, str]:
        """Whether the block path follows now, the command it acts on, and the state in words.

        Parameters
        ----------
        now_s : float, optional
            perf_counter s (default: the clock's now).

        Returns
        -------
        (bool, LoopCommand, str)

        Examples
        --------
        Following while the sensors speak; 0.1 s of silence and it is open loop again:

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> inverse = ClosedLoopInverse(model, clock=lambda: 10.0)                 # its clock: 10 s
        >>> inverse.command = LoopCommand(following=True, scale=1.5, force_n=0.5, since_s=0.0, sensors_s=9.99,
        ...                               words="closed loop: following")
        >>> inverse.following_now()[0], inverse.following_now(10.2)[2]
        (True, 'open loop: the sensors are silent')
        """
        command = self.command
        now = self.clock() if now_s is None else now_s
        if command.following and now - command.sensors_s > self.settings.sensor_silence_s:
            return False, command, "open loop: the sensors are silent"
        return command.following, command, command.words

    def amplitude_um_pp(self, ratio, force_n=DEFAULT_FORCE_N, limit_um_pp: float = np.inf,
                        out: np.ndarray | None = None) -> Inversion:
        """Amplitudes (µm p-p) for target ratios: closed loop while following, else open loop (see above).

        Parameters
        ----------
        ratio : array_like
            Target friction ratios.
        force_n : array_like
            N.
        limit_um_pp : float
            µm p-p.
        out : numpy.ndarray, optional
            float64, the ratios' length.

        Returns
        -------
        Inversion

        Examples
        --------
        Following with a scale of 1.5 (past the blend): the host model's amplitude × 1.5:

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> inverse = ClosedLoopInverse(model, clock=lambda: 10.0)                 # its clock: 10 s
        >>> inverse.command = LoopCommand(following=True, scale=1.5, force_n=0.5, since_s=0.0, sensors_s=9.99,
        ...                               words="closed loop: following")
        >>> closed = inverse.amplitude_um_pp(np.array([0.5]), 0.5).amplitude_um_pp
        >>> bool(np.allclose(closed, 1.5 * model.amplitude_um_pp(np.array([0.5]), 0.5).amplitude_um_pp))
        True
        >>> inverse.closed_samples, inverse.open_samples
        (1, 0)
        """
        n = len(ratio) if np.ndim(ratio) else 1
        now = self.clock()
        following, command, words = self.following_now(now)
        self.state_words = words
        if not following:
            self._reference = None
            if self._was_following:
                self.fallbacks += 1
                reason = words.removeprefix("open loop: ")
                self.fallback_reasons[reason] = self.fallback_reasons.get(reason, 0) + 1
            self._was_following = False
            self.open_samples += n
            return self.base.amplitude_um_pp(ratio, force_n, limit_um_pp, out)
        self._was_following = True
        self.closed_samples += n
        scale = command.scale
        opened = None
        blend = 1.0 if self.settings.blend_s <= 0 else min(1.0, (now - command.since_s) / self.settings.blend_s)
        if blend < 1.0:
            buffer = self._open[:n] if n <= len(self._open) and np.ndim(ratio) == 1 else None
            opened = self.base.amplitude_um_pp(ratio, force_n, limit_um_pp, buffer).amplitude_um_pp
        reach = reach_limit(limit_um_pp, scale)
        closed = self.base.amplitude_um_pp(ratio, command.force_n, reach, out)
        amplitude = closed.amplitude_um_pp
        # the force this block was computed at, for a device that corrects it as the values play; none while
        # blending with the open-loop amplitude (computed at another force)
        if blend < 1.0:
            self._reference = None
        else:
            lowest = float(np.minimum.reduce(ratio, axis=None))  # np.min's value without its wrapper
            self._reference = (self.base, lowest, command.force_n)
        if closed.clamped:  # held at the rung (0.1 % inside limit / scale): at the limit itself once scaled
            held = self._at_reach[:n] if n <= len(self._at_reach) and amplitude.ndim == 1 else None
            held = np.greater_equal(amplitude, reach, out=held)
        amplitude *= scale
        if closed.clamped:
            np.copyto(amplitude, limit_um_pp, where=held)
        np.minimum(amplitude, limit_um_pp, out=amplitude)  # exactly within the limit, rounding included
        if opened is not None:  # from the open-loop amplitude toward the closed loop's: a - (1 - b)(a - open)
            opened -= amplitude
            opened *= 1.0 - blend
            amplitude += opened
        return Inversion(amplitude, closed.clamped)
