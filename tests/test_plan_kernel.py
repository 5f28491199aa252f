"""render/kernels.py's planning kernels: one decision (``_plan_qp``) is its programme's optimum, as a separate solver
(bench/finger_bound.py's, scipy's banded Cholesky, nothing of the kernel's) finds it; and ``plan_friction`` takes
degenerate inputs (no horizon, NaN or infinite targets, a floor above the ceiling) without raising or holding."""

import sys
from pathlib import Path

import numpy as np
import pytest
from ultraglide.render import kernels

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from finger_bound import felt_bound  # noqa: E402


def instances():
    """(felt, goals, floor, hold_on, hold_rec): random ones, then extreme ones (holds near 0 and 1, floors near
    1, the felt ratio and the goals at the ends, goals beyond them at 0 and 2). Seeded."""
    rng = np.random.default_rng(20261130)
    for _ in range(40):
        n = int(rng.integers(2, 51))
        floor = rng.uniform(0.05, 0.9)
        yield (rng.uniform(floor, 1.0), rng.uniform(0.0, 1.2, n), floor, rng.uniform(0.0, 0.9),
               rng.uniform(0.5, 0.999))
    for _ in range(60):
        n = int(rng.integers(2, 51))
        floor = float(rng.choice([0.05, 0.168, 0.5, 0.99, 0.9999]))
        hold_on = float(rng.choice([0.0, 0.3, 0.8, rng.uniform(0.0, 0.8)]))
        hold_rec = float(rng.choice([0.9, 0.99, 0.999, 0.99999, rng.uniform(0.5, 0.99999)]))
        felt = float(rng.choice([floor, 1.0, (floor + 1.0) / 2.0, rng.uniform(floor, 1.0)]))
        goals = rng.choice([floor, 1.0, 0.0, 2.0, (floor + 1.0) / 2.0, rng.uniform(0.0, 1.0)], n)
        yield felt, goals, floor, hold_on, hold_rec


@pytest.mark.parametrize("case", list(enumerate(instances())), ids=lambda case: str(case[0]))
def test_a_decision_is_the_optimum_of_its_programme(case):
    """The felt ratios the kernel plans over the horizon (work[0]) have the least squared error to the goals any
    reachable plan has, as the bound's solver finds it on the same step-level programme (a step is its sample,
    c = 1 - hold), and the command is the one that reaches its first: the reviewer's 700 instances agreed within
    2e-12 (objective, relative) and 3e-9 (command; the kernel's command within 1e-4 of an end is the end). No
    decision runs to the iteration cap (median 11, most 22)."""
    _, (felt, goals, floor, hold_on, hold_rec) = case
    n = len(goals)
    work = np.zeros((kernels.PLAN_WORK_ROWS, n))
    command = kernels._plan_qp(felt, goals, n, floor, 1.0, hold_on, hold_rec, work)
    assert work[19, 0] < kernels.PLAN_ITERATIONS
    plan = work[0, :n].copy()
    best = felt_bound(goals, np.ones(n), floor, 1.0 - hold_on, 1.0 - hold_rec, felt0=felt)
    assert best.iterations < 200
    ours, theirs = np.sum((plan - goals) ** 2), best.solver_rms ** 2 * n
    assert abs(ours - theirs) <= 1e-9 * max(theirs, 1e-3), (ours, theirs)
    span = 1e-4 * (1.0 - floor)  # the kernel's commands within 1e-4 of an end are the end
    expected = min(max(best.command[0], floor), 1.0)
    expected = floor if expected < floor + span else 1.0 if expected > 1.0 - span else expected
    assert command == pytest.approx(expected, abs=1e-6)


def plan(target, floor=0.1, ceiling=1.0, k_onset=0.02, k_recovery=0.002, stride=24, steps=4, felt=1.0, ahead=None):
    """plan_friction over one block, the finger on, a decision at its first sample: the command per sample and
    the state returned."""
    target = np.asarray(target, dtype=float)
    if ahead is None:
        ahead = np.full(max(steps, 1), 0.5, dtype=np.float32)
    out = np.full(len(target), -1.0)
    first_ahead = -(-len(target) // stride) * stride + stride - 1  # the end of the first step past the block
    state = kernels.plan_friction(target, ahead, first_ahead, floor, ceiling, k_onset, k_recovery, stride, steps,
                                  felt, 0, 1.0, 1, out, np.empty((kernels.PLAN_WORK_ROWS, max(steps, 1))))
    return out, state


def test_no_horizon_asks_the_target_at_once():
    """steps = 0 (the Planner never asks it): nothing to plan over, so the command is the target, within the
    floor..ceiling, rather than a ZeroDivisionError."""
    out, (_, _, command, below) = plan(np.r_[np.full(24, 0.5), np.full(24, 0.05)], steps=0)
    assert out[:24].tolist() == [0.5] * 24 and out[24:].tolist() == [0.1] * 24
    assert command == 0.1 and below == 24
    assert kernels._plan_qp(0.7, np.empty(0), 0, 0.1, 1.0, 0.5, 0.9, np.empty((kernels.PLAN_WORK_ROWS, 1))) == 0.7


def test_a_nan_target_is_left_out_not_held_to():
    """A block whose second half has no target (NaN) is planned as if its steps kept the first half's 0.5:
    with dynamics that follow at once (k = 1) the command is 0.5 throughout (it held the felt 1 for the
    block's first 48 samples before); with the finger's lag, exactly the plan of a block at 0.5 everywhere."""
    half = np.r_[np.full(48, 0.5), np.full(48, np.nan)]
    out, _ = plan(half, k_onset=1.0, k_recovery=1.0)
    assert np.allclose(out, 0.5, rtol=0, atol=1e-9)  # the interior point's rounding
    lagging, _ = plan(half)
    assert lagging.tolist() == plan(np.full(96, 0.5))[0].tolist()
    assert lagging[0] < 0.5  # the plan drives below the target to fall faster: not the held felt 1
    # no target at all: the felt ratio held (nothing asked), a NaN in the lookahead keeps the step before
    out, _ = plan(np.full(48, np.nan), felt=0.7, ahead=np.full(4, np.nan, dtype=np.float32), k_onset=1.0,
                  k_recovery=1.0)
    assert np.allclose(out, 0.7, rtol=0, atol=1e-9)


@pytest.mark.parametrize("value, end, felt", [(np.inf, 1.0, 0.5), (-np.inf, 0.1, 1.0)])
def test_an_infinite_target_is_the_end_it_points_to(value, end, felt):
    """+inf asks the most friction there is (the ceiling), -inf the least (the floor), in the block and in the
    lookahead (k = 1: the command is the goal; it held the felt ratio before)."""
    out, _ = plan(np.full(48, value), felt=felt, k_onset=1.0, k_recovery=1.0, ahead=np.full(4, value, np.float32))
    assert np.allclose(out, end, rtol=0, atol=1e-9)
    # one infinite sample among a step's 24 at 0.5 counts as that end in the step's mean: (23 x 0.5 + end) / 24
    target = np.full(48, 0.5)
    target[10] = value
    out, _ = plan(target, felt=felt, k_onset=1.0, k_recovery=1.0)
    assert np.allclose(out[:24], (23 * 0.5 + end) / 24, rtol=0, atol=1e-9)
    assert np.allclose(out[24:], 0.5, rtol=0, atol=1e-9)


def test_a_floor_above_the_ceiling_is_the_ceiling():
    """floor 1.2 with ceiling 1: the plate reaches 1 at most, so 1 is commanded (it commanded 1.2 before)."""
    out, (_, _, command, _) = plan(np.full(48, 0.5), floor=1.2)
    assert out.tolist() == [1.0] * 48 and command == 1.0
    assert kernels._plan_qp(1.0, np.full(3, 0.5), 3, 1.2, 1.0, 0.5, 0.9,
                            np.empty((kernels.PLAN_WORK_ROWS, 3))) == 1.0
