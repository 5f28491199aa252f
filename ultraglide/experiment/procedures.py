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
    """Levels in the parameter's units; steps in dB of the level (20·log10), whole multiples of
    ``min_step_db`` (a weighted staircase's up step is rounded to one)."""

    start: float
    rule: str = "1u2d"  # 1u2d, 1u3d or weighted
    step_db: float = 6.0  # first step: a factor of 2
    min_step_db: float = 1.5
    weighted_target: float = 0.75  # the P(correct) a weighted staircase converges on
    min_level: float = 1e-4
    max_level: float = 1.0


class Staircase:
    """See the module docstring. ``reversals`` lists (trial index, level) of each reversal."""

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
        return self.params.weighted_target if self.params.rule == "weighted" else RULES[self.params.rule][1]

    def _step_db(self) -> float:
        halvings = (len(self.reversals) >= 2) + (len(self.reversals) >= 4)
        return max(self.params.step_db / 2 ** halvings, self.params.min_step_db)

    def next_level(self) -> float:
        return self.level

    def update(self, level: float, outcome: int) -> None:
        """Record the outcome at ``level`` (which must be the level this procedure asked for)."""
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
        """Geometric mean of the levels at the last ``last`` reversals (the first two left out)."""
        levels = [level for _, level in self.reversals[2:]][-last:]
        return float(np.exp(np.mean(np.log(levels)))) if levels else None


@dataclass(frozen=True)
class QuestParams:
    """The grids: levels that may be presented, and the parameters' candidate values."""

    levels: tuple[float, ...]
    thresholds: tuple[float, ...]
    slopes: tuple[float, ...] = (1.0, 1.5, 2.0, 3.0, 4.5, 7.0)
    lapses: tuple[float, ...] = (0.0, 0.02, 0.04)
    function: str = "weibull"
    guess: float = 0.5

    @staticmethod
    def log_grid(low: float, high: float, n_levels: int = 40, n_thresholds: int = 60, **others) -> QuestParams:
        return QuestParams(tuple(np.geomspace(low, high, n_levels)), tuple(np.geomspace(low, high, n_thresholds)),
                           **others)


class QuestPlus:
    """QUEST+ on a grid (uniform prior over log threshold, slope and lapse)."""

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
        """The level whose outcome is expected to leave the least entropy in the posterior."""
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
        row = int(np.argmin(np.abs(self.levels - level)))
        likelihood = self.p_one[row] if outcome else 1.0 - self.p_one[row]
        self.posterior = self.posterior * likelihood
        self.posterior /= self.posterior.sum()
        self.trials += 1

    def marginal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Values of one parameter and their posterior probabilities."""
        values = np.asarray(getattr(self.params, name + "s"), dtype=float)
        probabilities = np.array([self.posterior[self.grid[name] == v].sum() for v in values])
        return values, probabilities

    def estimate(self) -> dict:
        """Posterior means, and the threshold's 95 % credible interval (on the grid, interpolated)."""
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
    levels: tuple[float, ...]
    repeats: int
    seed: int = 0


class ConstantStimuli:
    """Each level ``repeats`` times; each block of len(levels) trials a fresh random order."""

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
        return self.trials >= len(self.schedule)

    def next_level(self) -> float:
        return self.schedule[self.trials]

    def update(self, level: float, outcome: int) -> None:
        self.trials += 1


def replay(procedure, levels, outcomes) -> None:
    """Feed a logged session's outcomes into a fresh ``procedure``; each logged level must be the one it
    asks for (else the log belongs to another procedure or seed: ValueError)."""
    for trial, (level, outcome) in enumerate(zip(levels, outcomes, strict=True), start=1):
        wanted = procedure.next_level()
        if not np.isclose(wanted, level, rtol=1e-6, atol=1e-9):
            raise ValueError(f"trial {trial} of the log was at level {level:g} but the procedure asks for "
                             f"{wanted:g}: the log was written with other options or another seed")
        procedure.update(level, int(outcome))


def interval_positions(seed: int, trials: int, intervals: int) -> list[int]:
    """Where the target goes (0-based) in each trial: every position once per block of ``intervals``
    trials, in a random order per block (counterbalanced)."""
    rng = np.random.default_rng([seed, 11])
    blocks = -(-trials // intervals)
    return [int(p) for _ in range(blocks) for p in rng.permutation(intervals)][:trials]
