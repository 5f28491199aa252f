"""The renderer's planning stage: friction commanded ahead of time, so the friction *felt* follows the texture.

A finger's friction does not follow the plate at once (:mod:`ultraglide.render.physics.dynamics`): it falls
within milliseconds when the vibration starts and recovers over tens of milliseconds when it stops. A renderer
that asks each instant for the texture's ratio gets a finger that lags the falls a little and the rises a lot:
a fine grating, swept fast, is felt mostly low. The :class:`Planner` chooses the static ratio to command (the
amplitude follows from the model's inverse, as before) by predicting the felt ratio over the next tens of
milliseconds of the texture along the finger's path: it holds friction up before a rise it could not make in
time, lets it fall where the fall is quick, and where a target cannot be reached in time it commands the
reachable friction with the least squared error over the horizon (the compiled
:func:`ultraglide.render.kernels.plan_friction`; no per-sample Python, no allocation in a block).

:func:`contrast_transfer` says how much of a grating's contrast survives, felt, at a speed: the felt
ratio's swing over the target's, with the instantaneous or the planned renderer.

Examples
--------
>>> from ultraglide.render.physics.dynamics import FrictionDynamics
>>> kept = contrast_transfer(FrictionDynamics(), period_mm=1.0, speed_mm_s=100.0, floor=0.1)
>>> 0.0 < kept.planned <= 1.0 and 0.0 < kept.instantaneous <= 1.0
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ultraglide.render import kernels
from ultraglide.render.errors import RenderError
from ultraglide.render.physics.dynamics import FrictionDynamics

DECISION_S = 0.002  # the planner decides every 2 ms (the onset's 5 ms is two and a half decisions)
HORIZON_RECOVERIES = 2.0  # it looks this many recovery time constants ahead
MAX_HORIZON_S = 0.1
MIN_HORIZON_S = 0.01
LEVELS = 9  # commands held, evenly spread over the reachable ratios
MAX_STEPS = int(MAX_HORIZON_S / DECISION_S) + 2  # room for the longest horizon


class Planner:
    """Plans the commanded static ratio block by block, holding the predicted felt ratio between blocks.

    Parameters
    ----------
    dynamics : FrictionDynamics
        The finger's friction dynamics the plan is made against.
    rate_hz : float
        The control rate, Hz.

    Attributes
    ----------
    felt : float
        The felt ratio the dynamics predict at the end of the last block.
    below_floor : int
        Target samples below the reachable floor so far (unreachable targets).

    Raises
    ------
    RenderError
        A rate not positive.

    Examples
    --------
    Asked for 0.5 from rest (1) at 12 kHz, the planner commands the floor first to hasten the fall, and the
    felt ratio is 0.5 by the block's end:

    >>> import numpy as np
    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> planner = Planner(FrictionDynamics(), 12000.0)
    >>> planner.set_speed(100.0)
    >>> ahead = np.full(planner.steps, 0.5, dtype=np.float32)     # as the texture's lookup gives it
    >>> command = planner.plan(np.full(96, 0.5), ahead, 0.1, True, np.empty(96))
    >>> float(command[0]), round(planner.felt, 6), planner.below_floor
    (0.1, 0.5, 0)
    """

    def __init__(self, dynamics: FrictionDynamics, rate_hz: float):
        if not rate_hz > 0:
            raise RenderError(f"the planner's rate must be positive, got {rate_hz}")
        self.dynamics = dynamics
        self.rate_hz = float(rate_hz)
        self.stride = max(1, round(DECISION_S * rate_hz))
        self.k_onset = 1.0 - math.exp(-1.0 / (rate_hz * dynamics.onset_s))
        self.felt = 1.0
        self.phase = 0
        self.command = 1.0
        self.below_floor = 0
        self._speed = None
        self.k_recovery = 0.0
        self.steps = 1
        self._work = np.empty((kernels.PLAN_ROWS, MAX_STEPS + 1))
        self.set_speed(dynamics.reference_speed_mm_s)

    def set_speed(self, speed_mm_s: float) -> None:
        """The finger's sliding speed (mm/s): sets the recovery and the horizon (two recoveries, 10-100 ms).

        Parameters
        ----------
        speed_mm_s : float
            The finger's speed, mm/s.

        Examples
        --------
        The recovery's per-sample step is 1 - exp(-1 / (rate × tau)), tau the dynamics' recovery at that speed:

        >>> import math
        >>> from ultraglide.render.physics.dynamics import FrictionDynamics
        >>> planner = Planner(FrictionDynamics(), 12000.0)
        >>> planner.set_speed(100.0)
        >>> tau = planner.dynamics.recovery_at_s(100.0)
        >>> math.isclose(planner.k_recovery, 1.0 - math.exp(-1.0 / (12000.0 * tau)))
        True
        """
        speed = round(float(speed_mm_s), 1)
        if speed == self._speed:
            return
        self._speed = speed
        tau = self.dynamics.recovery_at_s(speed)
        self.k_recovery = 1.0 - math.exp(-1.0 / (self.rate_hz * tau))
        horizon = min(max(HORIZON_RECOVERIES * tau, MIN_HORIZON_S), MAX_HORIZON_S)
        self.steps = max(1, round(horizon * self.rate_hz / self.stride))

    def ahead_times(self, block_start_s: float, n: int, out: np.ndarray | None = None) -> np.ndarray:
        """The times (s) past a block of ``n`` samples from ``block_start_s`` at which the plan needs the target:
        the ends of its decision steps over the horizon. ``out``: an array of at least :attr:`steps` to fill.

        Parameters
        ----------
        block_start_s : float
            The block's first sample's time, s.
        n : int
            The block's samples.
        out : numpy.ndarray, optional
            At least :attr:`steps` long.

        Returns
        -------
        numpy.ndarray
            :attr:`steps` times, s.

        Examples
        --------
        One decision step (``stride`` samples at 12 kHz) apart, from the first past the block:

        >>> import numpy as np
        >>> from ultraglide.render.physics.dynamics import FrictionDynamics
        >>> planner = Planner(FrictionDynamics(), 12000.0)
        >>> planner.set_speed(100.0)
        >>> times = planner.ahead_times(1.0, 96)
        >>> len(times) == planner.steps, bool(np.allclose(np.diff(times), planner.stride / 12000.0))
        (True, True)
        >>> bool(np.isclose(times[0], 1.0 + planner.first_ahead(96) / 12000.0))
        True
        """
        out = np.empty(self.steps) if out is None else out[:self.steps]
        kernels.spaced_times(float(block_start_s), self.first_ahead(n), self.stride, self.rate_hz, out)
        return out

    def decides_within(self, n: int) -> bool:
        """Whether a decision step begins within the next ``n`` samples (the plan then needs the targets ahead;
        between decisions it holds its command and needs none).

        Parameters
        ----------
        n : int
            The block's samples.

        Returns
        -------
        bool

        Examples
        --------
        Decisions every ``stride`` samples from phase 0: a block of 8 samples holds one, the next two none:

        >>> import numpy as np
        >>> from ultraglide.render.physics.dynamics import FrictionDynamics
        >>> planner = Planner(FrictionDynamics(), 12000.0)
        >>> planner.stride
        24
        >>> ahead = np.ones(planner.steps, dtype=np.float32)
        >>> seen = []
        >>> for _ in range(4):
        ...     seen.append(planner.decides_within(8))
        ...     _ = planner.plan(np.ones(8), ahead, 0.1, True, np.empty(8))
        >>> seen
        [True, False, False, True]
        """
        return (self.stride - self.phase) % self.stride < n

    def first_ahead(self, n: int) -> int:
        """The first sample past a block of ``n`` (counted from its start) where a decision step ends.

        Parameters
        ----------
        n : int
            The block's samples.

        Returns
        -------
        int

        Examples
        --------
        From phase 0 with decision steps of ``stride`` samples, the step that ends past 96 samples:

        >>> from ultraglide.render.physics.dynamics import FrictionDynamics
        >>> planner = Planner(FrictionDynamics(), 12000.0)
        >>> planner.first_ahead(96) == 96 + planner.stride - 1 - 96 % planner.stride
        True
        """
        phase_after = (self.phase + n) % self.stride
        return n + (self.stride - 1 - phase_after)

    def plan(self, target: np.ndarray, ahead: np.ndarray, floor: float, down: bool, out: np.ndarray) -> np.ndarray:
        """The commanded static ratio for the block's ``target`` ratios (into ``out``), given the targets at
        :meth:`ahead_times` (``ahead``), the lowest reachable ratio ``floor``, and whether the finger touches.

        Parameters
        ----------
        target : numpy.ndarray
            The block's target ratios.
        ahead : numpy.ndarray
            float32 targets at :meth:`ahead_times`.
        floor : float
            The lowest ratio the plate reaches.
        down : bool
            Whether the finger touches.
        out : numpy.ndarray
            float64, the block's length.

        Returns
        -------
        numpy.ndarray
            ``out``: the commanded static ratio.

        Examples
        --------
        A target at rest (1) everywhere asks for nothing:

        >>> import numpy as np
        >>> from ultraglide.render.physics.dynamics import FrictionDynamics
        >>> planner = Planner(FrictionDynamics(), 12000.0)
        >>> planner.set_speed(100.0)
        >>> ahead = np.full(planner.steps, 1.0, dtype=np.float32)
        >>> command = planner.plan(np.full(96, 1.0), ahead, 0.1, True, np.empty(96))
        >>> sorted(set(command.tolist())), planner.felt
        ([1.0], 1.0)
        """
        n = len(target)
        self.felt, self.phase, self.command, below = kernels.plan_friction(
            target, ahead, self.first_ahead(n), float(floor), 1.0, self.k_onset, self.k_recovery, self.stride,
            self.steps, LEVELS, self.felt, self.phase, self.command, 1 if down else 0, out, self._work)
        self.below_floor += below
        return out




@dataclass(frozen=True)
class ContrastKept:
    """How much of a grating's contrast is felt (felt swing over target swing, 0-1), and its RMS error.

    Examples
    --------
    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> kept = contrast_transfer(FrictionDynamics(), 1.0, 100.0, 0.1)
    >>> isinstance(kept, ContrastKept), 0.0 <= kept.planned <= 1.0, kept.instantaneous_rms > 0.0
    (True, True, True)
    """

    period_mm: float
    speed_mm_s: float
    instantaneous: float
    planned: float
    instantaneous_rms: float
    planned_rms: float


def felt_over(dynamics: FrictionDynamics, target: np.ndarray, n: int, speed_mm_s: float, floor: float,
              rate_hz: float = 12000.0) -> tuple[np.ndarray, np.ndarray]:
    """The felt ratio over the first ``n`` samples of ``target``, with the instantaneous and the planned renderer.

    ``target`` is known beyond ``n`` by the horizon, as a texture along a path is; the speed is steady. The
    instantaneous renderer asks the target (floored) at once; the planned one runs block by block, as the
    renderer runs it.

    Parameters
    ----------
    dynamics : FrictionDynamics
        The finger's dynamics.
    target : numpy.ndarray
        The friction ratio wanted, one a control sample, at least ``n`` plus the planner's horizon.
    n : int
        How many samples to render.
    speed_mm_s : float
        The finger's speed, mm/s.
    floor : float
        The lowest reachable ratio.
    rate_hz : float
        The control rate, Hz.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray)
        The felt ratio with the instantaneous and with the planned renderer, ``n`` each.

    Examples
    --------
    A step from 1 to 0.5 asked at once is felt as a first-order fall with the 5 ms onset time constant:

    >>> import numpy as np
    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> dynamics = FrictionDynamics()
    >>> instant, planned = felt_over(dynamics, np.full(2400, 0.5), 120, 100.0, 0.1)
    >>> seconds = np.arange(1, 121) / 12000.0
    >>> bool(np.allclose(instant, 0.5 + 0.5 * np.exp(-seconds / dynamics.onset_s)))
    True
    >>> planned.shape, bool(np.all((planned >= 0.1) & (planned <= 1.0)))
    ((120,), True)
    """
    target = np.asarray(target, dtype=float)
    instant = dynamics.respond(np.maximum(target[:n], floor), rate_hz, speed_mm_s, 1.0)
    planner = Planner(dynamics, rate_hz)
    planner.set_speed(speed_mm_s)
    command = np.empty(n)
    block = planner.stride * 8
    # the lookahead as the renderer's band-limited lookup gives it: each step's mean (sample k: the step ending there)
    stepped = np.convolve(target, np.full(planner.stride, 1.0 / planner.stride))[:len(target)]
    for start in range(0, n, block):
        stop = min(start + block, n)
        first = start + planner.first_ahead(stop - start)
        ahead = stepped[np.minimum(first + planner.stride * np.arange(planner.steps), len(target) - 1)]
        planner.plan(target[start:stop], ahead, floor, True, command[start:stop])
    return instant, dynamics.respond(command, rate_hz, speed_mm_s, 1.0)


def grating_felt(dynamics: FrictionDynamics, period_mm: float, speed_mm_s: float, floor: float,
                 rate_hz: float = 12000.0, duration_s: float = 1.0, low: float | None = None,
                 square: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Target, instantaneous felt and planned felt ratios for a grating swept at ``speed_mm_s``.

    A sinusoid (or a square wave) of spatial period ``period_mm`` between 1 and ``low`` (default: the
    reachable ``floor``).

    Parameters
    ----------
    dynamics : FrictionDynamics
        The finger's dynamics.
    period_mm : float
        The grating's spatial period, mm.
    speed_mm_s : float
        The sweep's speed, mm/s.
    floor : float
        The lowest reachable ratio.
    rate_hz : float
        The control rate, Hz.
    duration_s : float
        The sweep's length, s.
    low : float, optional
        The grating's trough (default ``floor``).
    square : bool
        A square wave instead of a sinusoid.

    Returns
    -------
    tuple of numpy.ndarray
        (target, instantaneous felt, planned felt), ``duration_s × rate_hz`` samples each.

    Examples
    --------
    A 2 mm grating at 100 mm/s (50 Hz): the finger's dynamics keep well under half its contrast:

    >>> import numpy as np
    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> target, instant, planned = grating_felt(FrictionDynamics(), 2.0, 100.0, 0.2, duration_s=0.1)
    >>> len(target), float(target.max()), round(float(target.min()), 6)
    (1200, 1.0, 0.2)
    >>> bool(np.ptp(instant[600:]) < 0.5 * np.ptp(target[600:]))
    True
    """
    low = floor if low is None else low
    n = int(round(duration_s * rate_hz))
    phase = 2.0 * math.pi * speed_mm_s / period_mm * np.arange(n + int(MAX_HORIZON_S * rate_hz) + 2) / rate_hz
    wave = np.sign(np.cos(phase)) if square else np.cos(phase)
    target = low + (1.0 - low) * 0.5 * (1.0 + wave)
    instant, planned = felt_over(dynamics, target, n, speed_mm_s, floor, rate_hz)
    return target[:n], instant, planned


def step_felt(dynamics: FrictionDynamics, speed_mm_s: float, floor: float, low: float = 0.3, rate_hz: float = 12000.0,
              down_s: float = 0.1, up_s: float = 0.3, duration_s: float = 0.6):
    """Target, instantaneous and planned felt ratios for a step 1 → ``low`` at ``down_s`` → 1 at ``up_s``.

    Parameters
    ----------
    dynamics : FrictionDynamics
        The finger's dynamics.
    speed_mm_s : float
        The finger's speed, mm/s.
    floor : float
        The lowest reachable ratio.
    low : float
        The step's low ratio.
    rate_hz : float
        The control rate, Hz.
    down_s, up_s, duration_s : float
        When the step falls and rises, and the run's length, s.

    Returns
    -------
    tuple of numpy.ndarray
        (target, instantaneous felt, planned felt), ``duration_s × rate_hz`` samples each.

    Examples
    --------
    Asked at once, the fall has settled (10 onset time constants) when friction rises again at 0.1 s:

    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> target, instant, planned = step_felt(FrictionDynamics(), 100.0, 0.2, down_s=0.05, up_s=0.1, duration_s=0.2)
    >>> len(target), float(target.min()), round(float(instant[1199]), 3)
    (2400, 0.3, 0.3)
    """
    n = int(round(duration_s * rate_hz))
    t = np.arange(n + int(MAX_HORIZON_S * rate_hz) + 2) / rate_hz
    target = np.where((t >= down_s) & (t < up_s), low, 1.0)
    instant, planned = felt_over(dynamics, target, n, speed_mm_s, floor, rate_hz)
    return target[:n], instant, planned


def contrast_transfer(dynamics: FrictionDynamics, period_mm: float, speed_mm_s: float, floor: float,
                      rate_hz: float = 12000.0) -> ContrastKept:
    """How much of a sinusoidal grating's contrast (1 down to ``floor``) the finger feels at ``speed_mm_s``,
    with the instantaneous and the planned renderer: the felt ratio's peak-to-peak over the target's, over the
    second half of a sweep of at least 0.5 s and 20 periods (the start's settling left out), with the RMS error.

    Parameters
    ----------
    dynamics : FrictionDynamics
        The finger's dynamics.
    period_mm : float
        The grating's spatial period, mm.
    speed_mm_s : float
        The sweep's speed, mm/s.
    floor : float
        The lowest reachable ratio (the grating's trough).
    rate_hz : float
        The control rate, Hz.

    Returns
    -------
    ContrastKept

    Raises
    ------
    RenderError
        A period or speed not positive, or a floor outside 0 to below 1.

    Examples
    --------
    A 1 mm grating at 100 mm/s (100 Hz): the finger feels a tenth of its contrast asked at once; the planner,
    which minimises the felt ratio's error, errs less:

    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> kept = contrast_transfer(FrictionDynamics(), 1.0, 100.0, 0.1)
    >>> kept.period_mm, 0.0 < kept.instantaneous < 0.2, kept.planned_rms < kept.instantaneous_rms
    (1.0, True, True)
    """
    if not (period_mm > 0 and speed_mm_s > 0 and 0.0 <= floor < 1.0):
        raise RenderError("a grating needs a positive period and speed, and a floor in 0 to below 1")
    duration = max(0.5, 20.0 * period_mm / speed_mm_s)
    target, instant, planned = grating_felt(dynamics, period_mm, speed_mm_s, floor, rate_hz, duration)
    half = len(target) // 2
    swing = float(np.ptp(target[half:]))

    def kept(felt):
        return float(np.ptp(felt[half:])) / swing, float(np.sqrt(np.mean((felt[half:] - target[half:]) ** 2)))

    (k_i, e_i), (k_p, e_p) = kept(instant), kept(planned)
    return ContrastKept(period_mm, speed_mm_s, k_i, k_p, e_i, e_p)


@dataclass(frozen=True)
class SwipeKept:
    """What a finger with friction dynamics keeps of a texture along a swipe at one speed: the felt friction's
    standard deviation over the texture's (1: all of its contrast), and the RMS error from it, for the
    instantaneous and the planned renderer.

    Examples
    --------
    >>> from ultraglide import grating
    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> kept = swipe_contrast(grating(2.0), FrictionDynamics(), 100.0, 0.2, longest_s=0.2)
    >>> isinstance(kept, SwipeKept), kept.speed_mm_s
    (True, 100.0)
    """

    speed_mm_s: float
    instantaneous: float
    planned: float
    instantaneous_rms: float
    planned_rms: float


def swipe_contrast(texture, dynamics: FrictionDynamics, speed_mm_s: float, floor: float,
                   rate_hz: float = 12000.0, longest_s: float = 1.0) -> SwipeKept:
    """How much of a friction texture's contrast survives, felt, along a left-to-right swipe through its middle at
    ``speed_mm_s`` (at most ``longest_s`` of it, the first 50 ms left out). Both renderers are asked for the
    texture with its targets below ``floor`` held there; what is felt is judged against the texture itself, so
    the contrast the floor removes is lost too (a texture wholly below the floor keeps none).

    Parameters
    ----------
    texture : textures.texture.Texture
        A friction texture.
    dynamics : FrictionDynamics
        The finger's dynamics.
    speed_mm_s, floor, rate_hz, longest_s : float
        The swipe's speed (mm/s), the lowest reachable ratio, the control rate (Hz), the longest swipe (s).

    Returns
    -------
    SwipeKept

    Examples
    --------
    >>> from ultraglide import grating
    >>> from ultraglide.render.physics.dynamics import FrictionDynamics
    >>> kept = swipe_contrast(grating(2.0), FrictionDynamics(), 100.0, 0.2, longest_s=0.2)
    >>> kept.speed_mm_s, 0.0 < kept.instantaneous < 1.0, kept.planned_rms > 0.0
    (100.0, True, True)
    """
    from ultraglide.textures.sampling import Sampler

    if not speed_mm_s > 0:
        raise RenderError(f"a swipe needs a positive speed, got {speed_mm_s}")
    duration = min(texture.width_mm / speed_mm_s, longest_s)
    n = int(duration * rate_hz)
    extra = int(MAX_HORIZON_S * rate_hz) + 2
    x = speed_mm_s * np.arange(n + extra) / rate_hz
    y = np.full(len(x), texture.height_mm / 2.0)
    step = speed_mm_s / rate_hz
    texture_ratio = Sampler(texture).ratio(x, y, step_mm=step, direction=(1.0, 0.0)).astype(float)
    instant, planned = felt_over(dynamics, np.maximum(texture_ratio, floor), n, speed_mm_s, floor, rate_hz)
    kept = slice(int(0.05 * rate_hz), n)
    spread = float(np.std(texture_ratio[kept]))

    def measure(felt):
        share = float(np.std(felt[kept])) / spread if spread > 1e-9 else 1.0
        return share, float(np.sqrt(np.mean((felt[kept] - texture_ratio[kept]) ** 2)))

    (k_i, e_i), (k_p, e_p) = measure(instant), measure(planned)
    return SwipeKept(speed_mm_s, k_i, k_p, e_i, e_p)
