"""The planner's decision: of the plans it weighs, it keeps the first command of the one with the least error,
as a sample-by-sample simulation of every one of those plans (written here, with none of the kernel's sums)
finds it."""

import numpy as np
import pytest
from ultraglide.render import kernels
from ultraglide.render.physics.dynamics import FrictionDynamics
from ultraglide.render.planning import LEVELS, Planner


def simulated_errors(goals, felt, floor, k_onset, k_recovery, stride, levels):
    """Every plan the planner weighs, simulated a sample at a time: (first commands, errors). An error is the sum
    over the steps of the mean, over the step's samples, of (felt ratio - the step's target)^2."""
    steps = len(goals)
    hold_on, hold_rec = (1.0 - k_onset) ** stride, (1.0 - k_recovery) ** stride
    grid = [floor + (1.0 - floor) * c / (levels - 1) for c in range(levels)]

    def greedy(y, r):
        hold = np.where(r < y, hold_on, hold_rec)
        return np.clip((r - y * hold) / (1.0 - hold), floor, 1.0)

    plans = []  # (level or None for the greedy command, level first?, steps before the switch)
    span_list = [1]
    while span_list[-1] < steps:
        span_list.append(span_list[-1] * 2)
    plans += [(level, True, span) for level in grid for span in span_list]
    plans.append(("greedy", True, 1))
    delays = [d for d in span_list if d < steps]
    plans += [(level, False, delay) for delay in delays for level in grid]
    first_greedy = float(greedy(np.array(felt), goals[0]))
    levels_held = np.array([first_greedy if p[0] == "greedy" else p[0] for p in plans])
    level_first = np.array([p[1] for p in plans])
    switch = np.array([p[2] for p in plans])
    y = np.full(len(plans), felt)
    error = np.zeros(len(plans))
    first = None
    for j, r in enumerate(goals):
        x = np.where((j < switch) == level_first, levels_held, greedy(y, r))
        if first is None:
            first = x.copy()
        k = np.where(x < y, k_onset, k_recovery)
        for _ in range(stride):
            y = y + k * (x - y)
            error += (y - r) ** 2 / stride
    return first, error


def decide(goals, felt, floor, k_onset, k_recovery, stride, levels=LEVELS):
    """The kernel's first command for a decision at a block's first sample, its targets ``goals`` (one a step)."""
    steps = len(goals)
    target = np.full(stride, goals[0])
    ahead = np.asarray(goals[1:] if steps > 1 else goals, dtype=np.float32)
    out = np.empty(stride)
    kernels.plan_friction(target, ahead, 2 * stride - 1, floor, 1.0, k_onset, k_recovery, stride, steps, levels,
                          felt, 0, 1.0, 1, out, np.empty((kernels.PLAN_ROWS, steps + 1)))
    return float(out[0])


def assert_least_error(goals, felt, floor, k_onset, k_recovery, stride):
    goals = np.asarray(goals, dtype=np.float32).astype(float)  # as the look ahead holds them
    chosen = decide(goals, felt, floor, k_onset, k_recovery, stride)
    first, error = simulated_errors(goals, felt, floor, k_onset, k_recovery, stride, LEVELS)
    its_plans = np.isclose(first, chosen, rtol=0.0, atol=1e-9)
    assert its_plans.any(), f"the command {chosen} begins none of the plans weighed"
    assert error[its_plans].min() <= error.min() + 1e-9 * max(1.0, error.min())


@pytest.mark.parametrize("speed_mm_s", [20.0, 100.0, 200.0])
@pytest.mark.parametrize("felt", [0.15, 0.5, 0.95])
def test_on_a_fine_grating_the_decision_is_the_least_error_plans_first_command(speed_mm_s, felt):
    planner = Planner(FrictionDynamics(), 12000.0)
    planner.set_speed(speed_mm_s)
    samples = np.arange(planner.steps) * planner.stride / 12000.0
    goals = 0.55 + 0.45 * np.cos(2.0 * np.pi * speed_mm_s * samples / 1.0)  # a 1 mm grating
    assert_least_error(goals, felt, 0.1, planner.k_onset, planner.k_recovery, planner.stride)


@pytest.mark.parametrize("felt", [0.3, 1.0])
def test_before_an_edge_the_decision_is_the_least_error_plans_first_command(felt):
    planner = Planner(FrictionDynamics(), 12000.0)
    planner.set_speed(100.0)
    goals = np.r_[np.full(planner.steps // 3, 0.3), np.ones(planner.steps - planner.steps // 3)]
    assert_least_error(goals, felt, 0.1, planner.k_onset, planner.k_recovery, planner.stride)


def test_on_random_targets_and_dynamics_the_decision_is_the_least_error_plans_first_command():
    rng = np.random.default_rng(43)
    for _ in range(150):
        steps = int(rng.integers(1, 40))
        stride = int(rng.integers(1, 12))
        shape = rng.integers(3)
        if shape == 0:
            goals = rng.uniform(0.0, 1.0, steps)
        elif shape == 1:  # stairs
            goals = np.repeat(rng.uniform(0.0, 1.0, steps // 4 + 1), 4)[:steps]
        else:
            goals = 0.5 + 0.5 * np.cos(rng.uniform(0.1, 2.0) * np.arange(steps))
        assert_least_error(goals, float(rng.uniform(0.0, 1.0)), float(rng.uniform(0.0, 0.4)),
                           float(rng.uniform(0.005, 1.0)), float(rng.uniform(0.001, 0.3)), stride)
