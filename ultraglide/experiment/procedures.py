"""Adaptive and fixed psychophysical procedures: which level comes next, given the responses so far.

Every procedure is a small state machine: :meth:`next_level`, then :meth:`update` with the outcome
(1 = correct in forced choice, 1 = "yes" in yes/no). Its state is a function of the outcomes only
(and of a seed for the constant stimuli' order), so a stopped session resumes exactly by replaying
its log into a new procedure (:func:`replay`).

* :class:`Staircase`: transformed up/down (Levitt 1971: 1-up-2-down converges on 70.7 % correct,
  1-up-3-down on 79.4 %) and weighted up/down (Kaernbach 1991: up step / down step = p / (1 - p)
  converges on p), with steps in the log domain (dB of the level), halved at the 2nd and 4th reversal.
* :class:`QuestPlus`: QUEST+ (Watson 2017) on a grid: the posterior over threshold, slope and lapse
  rate is updated by Bayes' rule and the next level minimises the expected entropy of the posterior.
* :class:`ConstantStimuli`: fixed levels, each presented ``repeats`` times, in random order within
  blocks that hold each level once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ultraglide.experiment import psychometric as pf

RULES = {"1u2d": (2, 0.7071), "1u3d": (3, 0.7937)}  # correct answers in a row to step down, target P


@dataclass(frozen=True)
class StaircaseParams:
    """A staircase's settings. Levels in the parameter's units; steps in dB of the level (20·log10), whole multiples
    of ``min_step_db`` (a weighted staircase's up step is rounded to one).

    Parameters
    ----------
    start : float
        The first level, in the varied parameter's unit (within ``min_level..max_level``).
    rule : {"1u2d", "1u3d", "weighted"}
        Transformed up/down (2 or 3 correct in a row to step down) or weighted up/down.
    step_db : float
        The first step, dB of the level (6 dB: a factor of 2), halved at the 2nd and 4th reversal.
    min_step_db : float
        The smallest step, dB; levels lie on a grid of it from ``start``.
    weighted_target : float
        The P(correct) a weighted staircase converges on (0..1).
    min_level, max_level : float
        The levels the staircase stays within, in the parameter's unit.

    Examples
    --------
    >>> params = StaircaseParams(0.4, rule="1u3d")
    >>> Staircase(params).target_p        # Levitt (1971): 0.5 ** (1/3) correct in a row
    0.7937
    """

    start: float
    rule: str = "1u2d"  # 1u2d, 1u3d or weighted
    step_db: float = 6.0  # first step: a factor of 2
    min_step_db: float = 1.5
    weighted_target: float = 0.75  # the P(correct) a weighted staircase converges on
    min_level: float = 1e-4
    max_level: float = 1.0


class Staircase:
    """A transformed or weighted up/down staircase (see the module docstring). ``reversals`` lists (trial index,
    level) of each reversal.

    Parameters
    ----------
    params : StaircaseParams

    Raises
    ------
    ValueError
        An unknown rule, or a start level outside ``min_level..max_level``.

    Examples
    --------
    Two correct answers in a row (1-up-2-down) step down 6 dB, a factor of 10 ** (6 / 20) = 1.995:

    >>> staircase = Staircase(StaircaseParams(0.4))
    >>> for outcome in (1, 1):
    ...     staircase.update(staircase.next_level(), outcome)
    >>> round(staircase.next_level(), 5), round(0.4 / 10 ** (6 / 20), 5)
    (0.20047, 0.20047)
    """

    def __init__(self, params: StaircaseParams):
        if params.rule not in (*RULES, "weighted"):
            raise ValueError(f"rule must be 1u2d, 1u3d or weighted, got {params.rule!r}")
        if not 0 < params.min_level <= params.start <= params.max_level:
            raise ValueError(f"the start level {params.start:g} must lie in {params.min_level:g}..{params.max_level:g}")
        self.params = params
        unit = params.min_step_db  # levels sit on a grid of this many dB from the start, so they repeat exactly
        self._lowest = math.ceil(20 * math.log10(params.min_level / params.start) / unit - 1e-9)
        self._highest = math.floor(20 * math.log10(params.max_level / params.start) / unit + 1e-9)
        self.index = 0
        self.level = params.start
        self.direction = 0  # +1 up, -1 down, 0 none yet
        self.run = 0  # correct answers in a row since the last step
        self.trials = 0
        self.reversals: list[tuple[int, float]] = []
        self.last_was_reversal = False

    @property
    def target_p(self) -> float:
        """The P(correct) this staircase converges on: 0.7071 (1u2d), 0.7937 (1u3d) or the weighted target.

        Examples
        --------
        >>> Staircase(StaircaseParams(0.4)).target_p, Staircase(StaircaseParams(0.4, rule="weighted")).target_p
        (0.7071, 0.75)
        """
        return self.params.weighted_target if self.params.rule == "weighted" else RULES[self.params.rule][1]

    def _step_db(self) -> float:
        halvings = (len(self.reversals) >= 2) + (len(self.reversals) >= 4)
        return max(self.params.step_db / 2 ** halvings, self.params.min_step_db)

    def next_level(self) -> float:
        """The level to present next, in the parameter's unit (the staircase's current level).

        Returns
        -------
        float

        Examples
        --------
        >>> Staircase(StaircaseParams(0.4)).next_level()        # the start
        0.4
        """
        return self.level

    def update(self, level: float, outcome: int) -> None:
        """Record the outcome at ``level`` (which must be the level this procedure asked for).

        Parameters
        ----------
        level : float
            The level presented, in the parameter's unit.
        outcome : int
            1 correct (or yes), 0 not.

        Examples
        --------
        One wrong answer steps up 6 dB (a factor of 10 ** 0.3); levels stay on the grid of ``min_step_db`` from the
        start, at most ``max_level``:

        >>> staircase = Staircase(StaircaseParams(0.4, max_level=1.0))
        >>> staircase.update(0.4, 0)
        >>> round(staircase.next_level(), 6), round(0.4 * 10 ** 0.3, 6)
        (0.798105, 0.798105)
        >>> staircase.update(staircase.next_level(), 0)       # 1.59 lies above 1: the grid's highest, 5 × 1.5 dB up
        >>> round(staircase.next_level(), 6), round(0.4 * 10 ** (5 * 1.5 / 20), 6)
        (0.948549, 0.948549)
        """
        steps = max(1, round(self._step_db() / self.params.min_step_db))  # whole grid units
        move = 0
        if self.params.rule == "weighted":
            p = self.params.weighted_target
            move = -1 if outcome else +1
            steps = steps if outcome else max(1, round(steps * p / (1 - p)))
        elif outcome:
            self.run += 1
            if self.run >= RULES[self.params.rule][0]:
                move, self.run = -1, 0
        else:
            move, self.run = +1, 0
        self.last_was_reversal = bool(move and self.direction and move != self.direction)
        if self.last_was_reversal:
            self.reversals.append((self.trials, level))
        if move:
            self.direction = move
            self.index = min(max(self.index + move * steps, self._lowest), self._highest)
            self.level = float(self.params.start * 10 ** (self.index * self.params.min_step_db / 20))
        self.trials += 1

    def reversal_mean(self, last: int = 6) -> float | None:
        """Geometric mean of the levels at the last ``last`` reversals (the first two left out).

        Parameters
        ----------
        last : int
            How many of the last reversals to average.

        Returns
        -------
        float or None
            In the parameter's unit; None before a third reversal.

        Examples
        --------
        Down (two correct), up (a miss: reversal 1), down (reversal 2), up (reversal 3, at the lower level):

        >>> staircase = Staircase(StaircaseParams(0.4))
        >>> for outcome in (1, 1, 1, 1, 0, 1, 1, 0):
        ...     staircase.update(staircase.next_level(), outcome)
        >>> len(staircase.reversals), round(staircase.reversal_mean(), 5), round(0.4 / 10 ** 0.6, 5)
        (3, 0.10048, 0.10048)
        """
        levels = [level for _, level in self.reversals[2:]][-last:]
        return float(np.exp(np.mean(np.log(levels)))) if levels else None


@dataclass(frozen=True)
class QuestParams:
    """QUEST+'s grids: the levels that may be presented, and the parameters' candidate values.

    Parameters
    ----------
    levels : tuple of float
        The levels that may be presented, in the parameter's unit.
    thresholds : tuple of float
        The candidate thresholds, same unit.
    slopes : tuple of float
        The candidate slopes (the Weibull's exponent, or the logistic's rate per unit of the level).
    lapses : tuple of float
        The candidate lapse rates, 0..1.
    function : {"weibull", "logistic"}
    guess : float
        The guess rate, 1/n in n-interval forced choice.

    Examples
    --------
    >>> params = QuestParams(levels=(0.05, 0.1, 0.2), thresholds=(0.05, 0.1, 0.2))
    >>> QuestPlus(params).posterior.size          # 3 thresholds × 6 slopes × 3 lapse rates, uniform
    54
    """

    levels: tuple[float, ...]
    thresholds: tuple[float, ...]
    slopes: tuple[float, ...] = (1.0, 1.5, 2.0, 3.0, 4.5, 7.0)
    lapses: tuple[float, ...] = (0.0, 0.02, 0.04)
    function: str = "weibull"
    guess: float = 0.5

    @staticmethod
    def log_grid(low: float, high: float, n_levels: int = 40, n_thresholds: int = 60, **others) -> QuestParams:
        """Parameters on log-spaced grids: ``n_levels`` levels and ``n_thresholds`` thresholds from ``low`` to ``high``.

        Parameters
        ----------
        low, high : float
            The grids' ends, in the parameter's unit.
        n_levels, n_thresholds : int
            The grids' sizes.
        **others
            The other fields of :class:`QuestParams` (slopes, lapses, function, guess).

        Returns
        -------
        QuestParams

        Examples
        --------
        >>> params = QuestParams.log_grid(0.01, 1.0, n_levels=3, n_thresholds=5, guess=1 / 3)
        >>> [round(float(v), 6) for v in params.levels], round(float(params.thresholds[1]), 6), params.guess  # 10**-1.5
        ([0.01, 0.1, 1.0], 0.031623, 0.3333333333333333)
        """
        return QuestParams(tuple(np.geomspace(low, high, n_levels)), tuple(np.geomspace(low, high, n_thresholds)),
                           **others)


class QuestPlus:
    """QUEST+ on a grid (uniform prior over log threshold, slope and lapse).

    Parameters
    ----------
    params : QuestParams

    Examples
    --------
    Before any trial the posterior is the prior: on a log grid from 0.01 to 1 its threshold is their geometric mean,
    its slope the candidates' mean (19 / 6) and its lapse rate theirs (0.02):

    >>> quest = QuestPlus(QuestParams.log_grid(0.01, 1.0))
    >>> estimate = quest.estimate()
    >>> round(estimate["threshold"], 6), round(estimate["slope"], 6), round(estimate["lapse"], 6)
    (0.1, 3.166667, 0.02)
    """

    def __init__(self, params: QuestParams):
        self.params = params
        self.levels = np.asarray(params.levels, dtype=float)
        t, s, lam = np.meshgrid(params.thresholds, params.slopes, params.lapses, indexing="ij")
        self.grid = {"threshold": t.ravel(), "slope": s.ravel(), "lapse": lam.ravel()}
        # P(outcome = 1 | level, parameters): rows are levels, columns parameter sets
        self.p_one = pf.probability(params.function, self.levels[:, None], t.ravel()[None, :], s.ravel()[None, :],
                                    params.guess, lam.ravel()[None, :])
        self.posterior = np.full(t.size, 1.0 / t.size)
        self.trials = 0
        self.last_was_reversal = False

    def next_level(self) -> float:
        """The level whose outcome is expected to leave the least entropy in the posterior.

        Returns
        -------
        float
            One of ``params.levels``, in the parameter's unit.

        Examples
        --------
        >>> quest = QuestPlus(QuestParams.log_grid(0.01, 1.0))
        >>> quest.next_level() in quest.params.levels
        True
        """
        joint_one = self.p_one * self.posterior  # (levels, params)
        expected = np.zeros(len(self.levels))
        for joint in (joint_one, (1.0 - self.p_one) * self.posterior):
            marginal = joint.sum(axis=1, keepdims=True)  # P(outcome | level)
            conditional = joint / np.maximum(marginal, 1e-300)
            entropy = -np.sum(np.where(conditional > 0, conditional * np.log(np.maximum(conditional, 1e-300)), 0),
                              axis=1)
            expected += marginal[:, 0] * entropy
        return float(self.levels[int(np.argmin(expected))])

    def update(self, level: float, outcome: int) -> None:
        """Bayes' rule: the posterior times the likelihood of ``outcome`` at the grid level nearest ``level``.

        Parameters
        ----------
        level : float
            The level presented, in the parameter's unit.
        outcome : int
            1 correct, 0 not.

        Examples
        --------
        A miss at a level makes thresholds above it more likely:

        >>> quest = QuestPlus(QuestParams.log_grid(0.01, 1.0))
        >>> quest.update(0.1, 0)
        >>> quest.trials, quest.estimate()["threshold"] > 0.1
        (1, True)
        """
        row = int(np.argmin(np.abs(self.levels - level)))
        likelihood = self.p_one[row] if outcome else 1.0 - self.p_one[row]
        self.posterior = self.posterior * likelihood
        self.posterior /= self.posterior.sum()
        self.trials += 1

    def marginal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Values of one parameter and their posterior probabilities.

        Parameters
        ----------
        name : {"threshold", "slope", "lapse"}

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            The parameter's candidate values and their probabilities (summing to 1).

        Examples
        --------
        >>> values, probabilities = QuestPlus(QuestParams.log_grid(0.01, 1.0)).marginal("lapse")
        >>> values.tolist(), [round(float(p), 6) for p in probabilities]          # the uniform prior
        ([0.0, 0.02, 0.04], [0.333333, 0.333333, 0.333333])
        """
        values = np.asarray(getattr(self.params, name + "s"), dtype=float)
        probabilities = np.array([self.posterior[self.grid[name] == v].sum() for v in values])
        return values, probabilities

    def estimate(self) -> dict:
        """Posterior means, and the threshold's 95 % credible interval (on the grid, interpolated).

        Returns
        -------
        dict
            ``threshold`` (the posterior mean on the log scale, in the parameter's unit), ``ci`` ([low, high], same
            unit), ``slope`` and ``lapse`` (posterior means).

        Examples
        --------
        >>> estimate = QuestPlus(QuestParams.log_grid(0.01, 1.0)).estimate()
        >>> round(estimate["threshold"], 6)                    # the prior's: sqrt(0.01 × 1)
        0.1
        """
        values, probabilities = self.marginal("threshold")
        cumulative = np.cumsum(probabilities)
        logs = np.log(values)
        low, high = (float(np.exp(np.interp(q, cumulative, logs))) for q in (0.025, 0.975))
        mean = float(np.exp(np.sum(probabilities * logs)))  # on the log scale the prior is uniform on
        return {"threshold": mean, "ci": [low, high],
                "slope": float(np.sum(self.posterior * self.grid["slope"])),
                "lapse": float(np.sum(self.posterior * self.grid["lapse"]))}


@dataclass(frozen=True)
class ConstantParams:
    """The method of constant stimuli's settings.

    Parameters
    ----------
    levels : tuple of float
        The levels, in the parameter's unit.
    repeats : int
        Presentations of each level.
    seed : int
        Picks the order within each block of ``len(levels)`` trials.

    Examples
    --------
    >>> len(ConstantStimuli(ConstantParams((0.1, 0.2, 0.3), repeats=2)).schedule)
    6
    """
    levels: tuple[float, ...]
    repeats: int
    seed: int = 0


class ConstantStimuli:
    """Each level ``repeats`` times; each block of len(levels) trials a fresh random order.

    Parameters
    ----------
    params : ConstantParams

    Raises
    ------
    ValueError
        No levels, or fewer than one repeat.

    Examples
    --------
    >>> schedule = ConstantStimuli(ConstantParams((0.1, 0.2, 0.3), repeats=2, seed=4)).schedule
    >>> sorted(schedule[:3]), sorted(schedule[3:])          # every level once in each block of three
    ([0.1, 0.2, 0.3], [0.1, 0.2, 0.3])
    """

    def __init__(self, params: ConstantParams):
        if params.repeats < 1 or not params.levels:
            raise ValueError("the method of constant stimuli needs levels and at least one repeat")
        rng = np.random.default_rng([params.seed, 7])
        self.schedule = [float(level) for _ in range(params.repeats) for level in rng.permutation(params.levels)]
        self.params = params
        self.trials = 0
        self.last_was_reversal = False

    @property
    def finished(self) -> bool:
        """Whether every scheduled trial has been recorded.

        Examples
        --------
        >>> procedure = ConstantStimuli(ConstantParams((0.1,), repeats=1))
        >>> procedure.finished, procedure.update(procedure.next_level(), 1), procedure.finished
        (False, None, True)
        """
        return self.trials >= len(self.schedule)

    def next_level(self) -> float:
        """The next scheduled level, in the parameter's unit.

        Returns
        -------
        float

        Examples
        --------
        >>> procedure = ConstantStimuli(ConstantParams((0.1, 0.2), repeats=1, seed=1))
        >>> procedure.next_level() == procedure.schedule[0]
        True
        """
        return self.schedule[self.trials]

    def update(self, level: float, outcome: int) -> None:
        """Count the trial (the schedule does not depend on outcomes).

        Parameters
        ----------
        level : float
            The level presented.
        outcome : int
            1 or 0; not used.

        Examples
        --------
        >>> procedure = ConstantStimuli(ConstantParams((0.1, 0.2), repeats=1, seed=1))
        >>> procedure.update(procedure.next_level(), 0)
        >>> procedure.next_level() == procedure.schedule[1], procedure.trials
        (True, 1)
        """
        self.trials += 1


def replay(procedure, levels, outcomes) -> None:
    """Feed a logged session's outcomes into a fresh ``procedure``; each logged level must be the one it
    asks for (else the log belongs to another procedure or seed: ValueError).

    Parameters
    ----------
    procedure : Staircase, QuestPlus or ConstantStimuli
        A new procedure with the session's settings.
    levels, outcomes : sequence
        The log's levels (in the parameter's unit) and outcomes (1 or 0), in order; the same length.

    Raises
    ------
    ValueError
        A logged level that is not the one the procedure asks for.

    Examples
    --------
    >>> staircase = Staircase(StaircaseParams(0.4))
    >>> replay(staircase, [0.4, 0.4], [1, 1])          # two correct: 6 dB down
    >>> round(staircase.next_level(), 5)
    0.20047
    >>> replay(Staircase(StaircaseParams(0.4)), [0.3], [1])
    Traceback (most recent call last):
    ...
    ValueError: trial 1 of the log was at level 0.3 but the procedure asks for 0.4: ...
    """
    for trial, (level, outcome) in enumerate(zip(levels, outcomes, strict=True), start=1):
        wanted = procedure.next_level()
        if not np.isclose(wanted, level, rtol=1e-6, atol=1e-9):
            raise ValueError(f"trial {trial} of the log was at level {level:g} but the procedure asks for "
                             f"{wanted:g}: the log was written with other options or another seed")
        procedure.update(level, int(outcome))


def interval_positions(seed: int, trials: int, intervals: int) -> list[int]:
    """Where the target goes (0-based) in each trial: every position once per block of ``intervals``
    trials, in a random order per block (counterbalanced).

    Parameters
    ----------
    seed : int
    trials : int
        How many positions.
    intervals : int
        The intervals (zones) per trial.

    Returns
    -------
    list of int
        One position, 0..intervals - 1, per trial.

    Examples
    --------
    >>> positions = interval_positions(seed=5, trials=6, intervals=3)
    >>> sorted(positions[:3]), sorted(positions[3:])
    ([0, 1, 2], [0, 1, 2])
    """
    rng = np.random.default_rng([seed, 11])
    blocks = -(-trials // intervals)
    return [int(p) for _ in range(blocks) for p in rng.permutation(intervals)][:trials]
