"""bench/finger_bound.py: the least error any plan reaches against the finger's dynamics, checked where it is known by
hand (a step, first-order onset and recovery) and where it is zero (a target the finger can follow exactly)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from ultraglide.devices.sim.finger import FingerDynamics

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from finger_bound import feel, felt_bound, plate_plan, steps_per_sample  # noqa: E402

RATE = 12000.0


def step_target(down_s=0.1, up_s=0.3, duration_s=0.6, low=0.3):
    t = np.arange(int(round(duration_s * RATE))) / RATE
    return np.where((t >= down_s) & (t < up_s), low, 1.0)


@pytest.mark.parametrize("speed_mm_s", [50.0, 100.0, 200.0])
def test_the_bound_on_a_step_is_the_one_computed_by_hand(speed_mm_s):
    """A step 1 -> 0.3 -> 1 with the settled ratio held within 0.3..1: each edge is best met by commanding the
    new level a time t before it, the felt ratio an exponential with the edge's time constant tau (onset for the
    fall, recovery at the speed for the rise). Its squared error, 0.49 tau (a - 2 (1 - e^-a) + (1 - e^-2a)/2 +
    e^-2a/2) with a = t/tau, is least at t = tau ln 2: 0.49 tau (ln 2 - 1/2) an edge (by hand, continuous time)."""
    dynamics = FingerDynamics()
    c_on, c_rec = steps_per_sample(dynamics, speed_mm_s, RATE)
    target = step_target()
    best = felt_bound(target, np.ones(len(target)), 0.3, c_on, c_rec)
    tau_rec = dynamics.recovery_s * (dynamics.reference_speed_mm_s / speed_mm_s) ** dynamics.speed_exponent
    by_hand = 0.49 * (dynamics.onset_s + tau_rec) * (math.log(2.0) - 0.5)  # s (squared ratio x seconds)
    squared = best.solver_rms ** 2 * len(target) / RATE
    assert squared == pytest.approx(by_hand, rel=0.02), squared / by_hand  # measured: within 0.3 %
    # the bound's plan, felt by the simulated finger's own kernel, is felt as the programme says
    felt = feel(best.command, dynamics, speed_mm_s, RATE)
    assert np.sqrt(np.mean((felt - target) ** 2)) == pytest.approx(best.solver_rms, rel=1e-4)
    assert best.rms == pytest.approx(best.solver_rms, rel=1e-4)
    # and no plan of the hand's family (the new level commanded t before each edge) does better, whatever t
    for lead_s in (0.0, 0.5 * tau_rec, math.log(2.0) * tau_rec, tau_rec):
        t = np.arange(len(target)) / RATE
        command = np.where((t >= 0.1 - math.log(2.0) * dynamics.onset_s) & (t < 0.3 - lead_s), 0.3, 1.0)
        error = np.sqrt(np.mean((feel(command, dynamics, speed_mm_s, RATE) - target) ** 2))
        assert error >= best.solver_rms * (1.0 - 1e-6)


def test_a_target_the_finger_can_follow_is_bound_at_zero():
    """A target that is itself the felt friction of some settled ratios within the floor..1 is reached exactly."""
    rng = np.random.default_rng(7)
    dynamics = FingerDynamics()
    c_on, c_rec = steps_per_sample(dynamics, 100.0, RATE)
    command = np.repeat(rng.uniform(0.2, 1.0, 60), 40)  # 60 levels, each held 40 samples
    target = feel(command, dynamics, 100.0, RATE)
    best = felt_bound(target, np.ones(len(target)), 0.2, c_on, c_rec)
    assert best.solver_rms < 1e-5 and best.rms < 1e-5
    # and a target it cannot follow is not: the same ratios asked at once
    assert felt_bound(command, np.ones(len(command)), 0.2, c_on, c_rec).rms > 0.05


def test_a_floor_below_the_step_lets_the_fall_be_hastened_and_the_bound_only_falls():
    """With the plate's floor below the step's low (0.168 against 0.3) the fall can be driven harder: the bound is
    below the hand's (which holds the settled ratio within 0.3..1), and a plan with the plate's envelope is felt no
    better than it."""
    dynamics = FingerDynamics()
    c_on, c_rec = steps_per_sample(dynamics, 100.0, RATE)
    target = step_target()
    scored = np.ones(len(target))
    held = felt_bound(target, scored, 0.3, c_on, c_rec)
    lower = felt_bound(target, scored, 0.168, c_on, c_rec)
    assert lower.solver_rms < held.solver_rms * 0.999
    assert lower.command.min() < 0.25  # the fall driven below the step's low

    def law(amplitude_um_pp):  # the default finger's law at 0.5 N: floor 0.1, 3.73 µm p-p, Gaussian
        return 0.1 + 0.9 * np.exp(-(np.asarray(amplitude_um_pp) / 3.7335) ** 2)

    floor = float(law(6.0))
    bound = felt_bound(target, scored, floor, c_on, c_rec)
    planned = plate_plan(target, scored, law, dynamics, 100.0, RATE, 0.00255, 6.0, 8.0, bound.command,
                         max_iterations=50)
    assert planned.rms >= bound.solver_rms * (1.0 - 1e-9)
    assert planned.rms < held.rms  # the plate's lag costs less than the floor gains (measured: see the bench)


def test_a_bound_that_does_not_converge_is_no_bound():
    """Stopped at its iteration cap the solver's iterate is neither the optimum nor a plan: felt_bound says so in
    one line rather than returning it; with room enough, the same step converges."""
    from finger_bound import BoundError

    c_on, c_rec = steps_per_sample(FingerDynamics(), 100.0, RATE)
    target = step_target()
    with pytest.raises(BoundError, match="did not converge in 3 iterations") as error:
        felt_bound(target, np.ones(len(target)), 0.3, c_on, c_rec, max_iterations=3)
    assert "\n" not in str(error.value)
    assert felt_bound(target, np.ones(len(target)), 0.3, c_on, c_rec).iterations < 200


def test_a_singular_newton_system_is_one_line_not_a_linalg_traceback():
    """A recovery of 1e-5 a sample from friction at rest (felt0 = 1), goals at and beyond the ends: the Newton
    system's Cholesky fails to rounding near the optimum (iteration 17; scipy's LinAlgError before)."""
    from finger_bound import BoundError

    goals = np.array([2.0, 0.525, 0.05, 1.0, 2.0, 1.0, 1.0, 2.0, 0.0, 2.0, 0.5810562472046952, 0.05, 2.0,
                      0.5810562472046952, 0.5810562472046952, 0.525, 0.05, 2.0, 0.0, 0.525, 0.5810562472046952, 0.525])
    with pytest.raises(BoundError, match="singular to rounding") as error:
        felt_bound(goals, np.ones(len(goals)), 0.05, 1.0, 1e-5, felt0=1.0)
    assert "\n" not in str(error.value)
