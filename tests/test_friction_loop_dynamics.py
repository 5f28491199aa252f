"""The friction loop on a finger whose friction lags the amplitude (onset 5 ms, recovery 70 ms at 22 mm/s),
closed around the real simulated finger in simulated time (tests/loop_rig.py) and judged by its own truth.

A static model predicts friction where the finger's has not yet come back; fitted to those readings, friction at
rest (mu0) comes out far too low and the loop drives the finger further from its target. A host model with the
finger's dynamics predicts through them and identifies the finger."""

import math
import sys

import numpy as np
import pytest
from conftest import ROOT
from loop_rig import LoopRig, floored
from ultraglide.devices.sim.finger import FingerDynamics, FingerParams, ForceScript
from ultraglide.render.engine.friction_estimator import FrictionEstimator
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.dynamics import FrictionDynamics

sys.path.insert(0, str(ROOT / "bench"))
from closed_loop_rig import ClosedLoopRig  # noqa: E402
from ultraglide.render.engine.finger_setup import FingerConfig  # noqa: E402
from ultraglide.textures.procedural import grating as sine_grating  # noqa: E402

STATIC = load_model("stretched")
DYNAMIC = load_model("dynamic")  # the same static law with the published dynamics
MU0, SCALE = 0.8, 0.7  # the finger: friction at rest 0.8, needing 30 % less vibration than the host's law


finger_law = floored(lambda a, f: STATIC.relative_friction(a / SCALE, f), 0.0)


def grating(hz, low=0.4):
    middle, swing = (1.0 + low) / 2.0, (1.0 - low) / 2.0
    return lambda t: middle + swing * np.cos(2 * math.pi * hz * t)


def run(host, hz, closed=True, seconds=6.0):
    rig = LoopRig(host, finger_law, ForceScript.walk(seed=4), FingerParams(mu0=MU0, drift=0.0, moisture=0.0),
                  plate_tau_s=0.0003, closed=closed, dynamics=FingerDynamics())
    return rig, rig.run(grating(hz), seconds)


@pytest.mark.slow
def test_a_host_model_with_the_dynamics_identifies_a_lagging_finger_and_a_static_one_does_not():
    dynamic, _ = run(DYNAMIC, 5)
    assert dynamic.loop.estimator.mu0 == pytest.approx(MU0, rel=0.03)
    assert dynamic.loop.estimator.scale == pytest.approx(SCALE, rel=0.03)
    static, _ = run(STATIC, 5)
    assert abs(static.loop.estimator.mu0 - MU0) > 0.08  # the lag read as a slipperier finger at rest


@pytest.mark.slow
def test_the_loop_on_a_lagging_finger_beats_open_loop_and_says_its_error_as_the_finger_felt_it():
    errors = {}
    for closed in (False, True):
        rig, result = run(DYNAMIC, 5, closed)
        errors[closed] = result.rms_error(2.0)
    assert errors[True] < 0.7 * errors[False]
    assert rig.loop.status()["friction_error_rms"] == pytest.approx(errors[True], abs=0.02)
    # 100 Hz of modulation: neither follows it, but the loop no longer makes it worse, as the static model's does
    _, fast_open = run(DYNAMIC, 100, closed=False)
    _, fast_dynamic = run(DYNAMIC, 100)
    _, fast_static = run(STATIC, 100)
    assert fast_dynamic.rms_error(2.0) < fast_open.rms_error(2.0) < fast_static.rms_error(2.0)


def test_the_estimators_prediction_lags_as_the_dynamics_do():
    """A step of the amplitude from 0 to 3 µm p-p and back, the finger sliding at 22 mm/s: the estimator's predicted
    ratio (before its sensor model) falls with the onset's and comes back with the recovery's time constant."""
    dynamics = FrictionDynamics()
    estimator = FrictionEstimator(DYNAMIC, sensor_rate_hz=1000.0)
    static = np.r_[np.ones(50), np.full(200, float(STATIC.relative_friction(3.0, 0.5))), np.ones(300)]
    slope = np.zeros_like(static)
    felt, _, intended = estimator._felt_through_dynamics(static, slope, static.copy(), 22.0)
    low = static[60]
    t_down = np.arange(1, 201) / 1000.0
    assert felt[50:250] == pytest.approx(low + (1 - low) * np.exp(-t_down / dynamics.onset_s), abs=1e-9)
    start = felt[249]
    t_up = np.arange(1, 301) / 1000.0
    assert felt[250:] == pytest.approx(1 - (1 - start) * np.exp(-t_up / dynamics.recovery_s), abs=1e-9)
    assert intended == pytest.approx(felt, abs=1e-12)  # the intended ratio through the same lag


def test_the_renderer_plans_through_the_loops_inverse_as_through_the_model():
    """Before the sensors speak, the loop's inverse is the host model: a renderer given it plans the felt friction
    (a model with dynamics) exactly as one given the model itself."""
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.engine.friction_loop import FrictionLoop
    from ultraglide.render.paths import SwipePath
    from ultraglide.render.renderer import Renderer
    from ultraglide.textures.library import resolve_texture

    texture, profile = resolve_texture("grating-1mm"), load_profile("sim-plate")
    blocks = []
    for model in (DYNAMIC, FrictionLoop(DYNAMIC, 12000.0).inverse):
        renderer = Renderer(texture, model, profile, trajectory=SwipePath(duration_s=0.2, speed_mm_s=100.0))
        assert renderer.planner is not None
        blocks.append(renderer.control(1200).target_um_pp.copy())
    assert np.array_equal(blocks[0], blocks[1])
    assert Renderer(texture, FrictionLoop(STATIC, 12000.0).inverse, profile).planner is None


def two_force_table(folder):
    """A finger measured at two forces (bench_closed_loop.table_fingers'): the published fit's tau 1.32 -/+ 0.45 µm
    zero-to-peak at 0.3 and 0.8 N, a floor of 0.1. Its amplitudes grow as F^0.72 between them (the host's law:
    F^(1/3)) and are held beyond."""
    rows = ["amplitude_um_pp,relative_friction,force_n"]
    for force_n, tau_um in ((0.3, 0.87), (0.8, 1.77)):
        for a in np.linspace(0.0, 6.0, 25):
            rows.append(f"{a:.3f},{0.1 + 0.9 * math.exp(-((a / 2.0) ** 2) / (2.0 * tau_um ** 2)):.5f},{force_n}")
    path = folder / "two-force-finger.csv"
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.slow
def test_on_the_firmware_core_a_lagging_table_finger_with_a_walking_force_does_not_drift(tmp_path):
    """Issue 43, in simulated time on the firmware core: the two-force table finger with the published lag, its force
    walking in 0.2-1 N, the host playing --model dynamic on a 1 mm grating at 100 mm/s. The plan holds the felt
    friction nearly steady, so the samples fix only mu0 r(a / k); the force law unlike the model's moved the fit
    along that product, mu0 fell to 0.49 by 6 s (the finger's: 1.07) and k rose towards its bound, and the finger
    missed what the plan means felt by 0.30 rms. Judged by the finger's own truth."""
    finger = FingerConfig(law=f"table:{two_force_table(tmp_path)}", dynamics=True)
    rig = ClosedLoopRig(sine_grating(1.0, size_mm=(80.0, 50.0), ratio_range=(0.4, 1.0)), 100.0, True, finger=finger,
                        model="dynamic", seconds=6.0)
    run = rig.run(6.0)
    # the finger's mu0: 1, gaining 25 % with dwell at a time constant of 20 s (plate-sim's finger), touching throughout
    truth_mu0 = 1.0 + 0.25 * (1.0 - math.exp(-float(run.t[-1]) / 20.0))
    assert rig.loop.estimator.mu0 == pytest.approx(truth_mu0, rel=0.12)
    assert run.planned_error(2.0) < 0.05  # issue 43's aim, against what the plan means the lagging finger to feel
    # the loop's own figures (against the texture and against the plan, from the sensors) within 0.02 of the finger's
    # truth; the one against the plan is what the finger could be given, far below the texture's
    assert run.status["friction_error_rms"] == pytest.approx(run.rms_error(0.5), abs=0.02)
    assert run.status["friction_error_plan_rms"] == pytest.approx(run.planned_error(0.5), abs=0.02)
    assert run.status["friction_error_plan_rms"] < 0.5 * run.status["friction_error_rms"]
