"""Procedures, psychometric fits and the simulated observer, against hand values and probability laws."""

import math

import numpy as np
import pytest

from ultraglide.experiment import psychometric as pf
from ultraglide.experiment.errors import ExperimentError
from ultraglide.experiment.observer import SimObserver
from ultraglide.experiment.procedures import (
    ConstantParams,
    ConstantStimuli,
    QuestParams,
    QuestPlus,
    Staircase,
    StaircaseParams,
    interval_positions,
    replay,
)


def test_staircase_1u2d_steps_by_hand():
    stair = Staircase(StaircaseParams(start=0.2, rule="1u2d", step_db=6.0, min_step_db=1.5, min_level=1e-3))
    down6 = 10 ** (-6 / 20)  # 0.501187...
    levels = []
    for outcome in (1, 1, 1, 1, 0, 1, 1, 0):
        levels.append(stair.next_level())
        stair.update(levels[-1], outcome)
    # C C: down 6 dB; C C: down 6 dB; I: up 6 dB (first reversal, still 6 dB); C C: down (second reversal)...
    expected = [0.2, 0.2, 0.2 * down6, 0.2 * down6, 0.2 * down6 ** 2, 0.2 * down6, 0.2 * down6, 0.2 * down6 ** 2]
    assert levels[:7] == pytest.approx(expected[:7], rel=1e-12)
    assert [trial for trial, _ in stair.reversals] == [4, 6, 7]
    # after two reversals the step is 3 dB: the last incorrect answer moved up by 3 dB
    assert stair.next_level() == pytest.approx(0.2 * down6 ** 2 * 10 ** (3 / 20), rel=1e-12)


def test_weighted_staircase_steps_up_three_times_as_far_for_75_percent():
    stair = Staircase(StaircaseParams(start=0.1, rule="weighted", step_db=1.5, min_step_db=1.5, weighted_target=0.75))
    stair.update(0.1, 1)
    assert stair.next_level() == pytest.approx(0.1 * 10 ** (-1.5 / 20))
    stair.update(stair.next_level(), 0)
    assert stair.next_level() == pytest.approx(0.1 * 10 ** (3.0 / 20))


@pytest.mark.parametrize("rule, target", [("1u2d", 0.7071), ("1u3d", 0.7937), ("weighted", 0.75)])
def test_staircases_converge_on_their_target_probability(rule, target):
    """Levitt (1971) and Kaernbach (1991): the tracked level settles where P(correct) is the rule's target."""
    rng = np.random.default_rng(5)
    stair = Staircase(StaircaseParams(start=0.3, rule=rule, step_db=3.0, min_step_db=0.5, min_level=1e-4))
    p_at_levels = []
    for trial in range(6000):
        level = stair.next_level()
        p = float(pf.probability("weibull", level, 0.1, 2.5, 0.5, 0.0))
        if trial > 500:
            p_at_levels.append(p)
        stair.update(level, int(rng.random() < p))
    assert np.mean(p_at_levels) == pytest.approx(target, abs=0.03)


def test_quest_posterior_is_bayes_rule_by_hand():
    params = QuestParams(levels=(0.05, 0.1, 0.2), thresholds=(0.05, 0.2), slopes=(2.0,), lapses=(0.0,), guess=0.5)
    quest = QuestPlus(params)
    p = {t: 0.5 + 0.5 * (1 - math.exp(-((0.1 / t) ** 2))) for t in (0.05, 0.2)}
    quest.update(0.1, 1)
    quest.update(0.1, 0)
    unnormalised = {t: p[t] * (1 - p[t]) for t in p}
    total = sum(unnormalised.values())
    values, probabilities = quest.marginal("threshold")
    assert probabilities == pytest.approx([unnormalised[0.05] / total, unnormalised[0.2] / total], rel=1e-12)


def test_quest_picks_the_level_of_least_expected_entropy_by_brute_force():
    params = QuestParams(levels=(0.02, 0.08, 0.3), thresholds=(0.03, 0.06, 0.12, 0.24), slopes=(2.0, 4.0),
                         lapses=(0.0,), guess=0.5)
    quest = QuestPlus(params)
    quest.update(0.08, 1)
    grid = [(t, s) for t in params.thresholds for s in params.slopes]
    prior = quest.posterior.copy()

    def entropy(weights):
        weights = weights / weights.sum()
        return -sum(w * math.log(w) for w in weights if w > 0)

    expected = []
    for level in params.levels:
        pc = np.array([0.5 + 0.5 * (1 - math.exp(-((level / t) ** s))) for t, s in grid])
        total = 0.0
        for likelihood in (pc, 1 - pc):
            joint = prior * likelihood
            total += joint.sum() * entropy(joint)
        expected.append(total)
    assert quest.next_level() == params.levels[int(np.argmin(expected))]


def test_fit_recovers_parameters_and_beats_the_truth_in_likelihood():
    rng = np.random.default_rng(1)
    levels = rng.choice(np.geomspace(0.02, 0.4, 12), 6000)
    truth = dict(threshold=0.1, slope=3.0, guess=0.5, lapse=0.02)
    outcomes = rng.random(len(levels)) < pf.probability("weibull", levels, **truth)
    fit = pf.fit(levels, outcomes, "weibull", 0.5)
    assert fit.threshold == pytest.approx(0.1, rel=0.05)
    assert fit.slope == pytest.approx(3.0, rel=0.2)
    x, n, k = pf.aggregate(levels, outcomes)
    p = pf.probability("weibull", x, **truth)
    truth_log_likelihood = float(np.sum(k * np.log(p) + (n - k) * np.log(1 - p)))
    assert fit.log_likelihood >= truth_log_likelihood - 1e-9


def test_logistic_yes_no_fit_with_false_alarms():
    rng = np.random.default_rng(2)
    levels = np.repeat([0.0, 1.0, 2.0, 3.0, 4.0, 5.0], 800)
    p = 0.1 + (1 - 0.1 - 0.0) * (1 / (1 + np.exp(-2.0 * (levels - 2.5))))
    fit = pf.fit(levels, rng.random(len(levels)) < p, "logistic", guess=None, level_range=(0, 5))
    assert fit.threshold == pytest.approx(2.5, abs=0.15)
    assert fit.guess == pytest.approx(0.1, abs=0.04)
    assert pf.level_at("logistic", 0.5, fit.threshold, fit.slope) == pytest.approx(fit.threshold)


def test_constant_stimuli_blocks_hold_each_level_once_and_the_seed_fixes_the_order():
    levels = (0.0, 2.0, 4.0)
    procedure = ConstantStimuli(ConstantParams(levels, repeats=10, seed=3))
    schedule = []
    while not procedure.finished:
        schedule.append(procedure.next_level())
        procedure.update(schedule[-1], 0)
    assert len(schedule) == 30
    for block in range(10):
        assert sorted(schedule[3 * block:3 * block + 3]) == list(levels)
    assert ConstantStimuli(ConstantParams(levels, 10, 3)).schedule == schedule
    assert ConstantStimuli(ConstantParams(levels, 10, 4)).schedule != schedule


def test_interval_positions_are_counterbalanced_and_extend_without_changing():
    positions = interval_positions(seed=9, trials=60, intervals=3)
    for block in range(20):
        assert sorted(positions[3 * block:3 * block + 3]) == [0, 1, 2]
    assert interval_positions(9, 30, 3) == positions[:30]
    assert np.bincount(positions).tolist() == [20, 20, 20]


def test_replay_rebuilds_the_state_and_refuses_a_foreign_log():
    stair = Staircase(StaircaseParams(start=0.2))
    levels, outcomes = [], [1, 1, 0, 1, 1, 1, 1, 0, 0, 1]
    for outcome in outcomes:
        levels.append(stair.next_level())
        stair.update(levels[-1], outcome)
    again = Staircase(StaircaseParams(start=0.2))
    replay(again, levels, outcomes)
    assert again.next_level() == stair.next_level() and again.reversals == stair.reversals
    with pytest.raises(ValueError, match="trial 1 of the log"):
        replay(Staircase(StaircaseParams(start=0.3)), levels, outcomes)


def test_simulated_observer_answers_with_its_psychometric_function():
    observer = SimObserver.parse("sim:threshold=0.1,slope=3,lapse=0.04", seed=1)
    for level in (0.05, 0.1, 0.2):
        answers = [observer.respond(trial, level, 3, trial % 3)[0] == trial % 3 for trial in range(4000)]
        expected = 1 / 3 + (1 - 1 / 3 - 0.04) * (1 - math.exp(-((level / 0.1) ** 3)))
        assert np.mean(answers) == pytest.approx(expected, abs=3.5 * math.sqrt(expected * (1 - expected) / 4000))
    assert observer.respond(7, 0.1, 2, 0) == observer.respond(7, 0.1, 2, 0)  # one generator per trial


@pytest.mark.parametrize("spec", ["sim", "sim:slope=3", "sim:threshold=x", "sim:threshold=0.1,colour=red",
                                  "human:threshold=1", "sim:threshold=-1", "sim:threshold=1,lapse=0.7"])
def test_bad_observer_specs_say_what_is_wrong(spec):
    with pytest.raises(ExperimentError):
        SimObserver.parse(spec)


def test_posterior_and_bootstrap_intervals_hold_the_truth_and_shrink_with_data():
    rng = np.random.default_rng(3)
    widths = {}
    for trials in (100, 3000):
        levels = rng.choice(np.geomspace(0.02, 0.4, 10), trials)
        outcomes = rng.random(trials) < pf.probability("weibull", levels, 0.1, 3.0, 0.5, 0.02)
        bayes = pf.posterior(levels, outcomes, "weibull", 0.5, (0.005, 0.6))
        boot = pf.bootstrap(pf.fit(levels, outcomes, "weibull", 0.5, (0.005, 0.6)), levels, 200, seed=1,
                            level_range=(0.005, 0.6))
        for low, high in (bayes.ci, boot.ci):
            assert low <= 0.1 <= high
        widths[trials] = (bayes.ci[1] - bayes.ci[0], boot.ci[1] - boot.ci[0])
    assert widths[3000][0] < widths[100][0] / 3 and widths[3000][1] < widths[100][1] / 3


def test_posterior_without_trials_is_the_prior():
    """No data: the marginal is the prior, uniform on log threshold, so the interval is its 2.5-97.5 % span."""
    bayes = pf.posterior(np.array([]), np.array([]), "weibull", 0.5, (0.01, 1.0))
    assert math.log(bayes.threshold) == pytest.approx(math.log(0.1), abs=0.03)
    assert math.log(bayes.ci[0]) == pytest.approx(math.log(0.01) + 0.025 * math.log(100), abs=0.05)
