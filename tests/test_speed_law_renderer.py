"""The renderer under a settled speed law: at each block's finger speed the inverse is the static one times
k = (v / 22 mm/s)^s, within the limit / k, open loop and through the closed loop's inverse; with s = 0 nothing
changes, bit for bit. The felt ratio is computed here by the static model's forward law at the effective
amplitude a / k, with k from the block's own finger positions, never by the renderer's inverse."""

import math

import numpy as np
import pytest
from ultraglide.devices.profiles import load_profile
from ultraglide.render.engine.friction_controller import ClosedLoopInverse, LoopCommand
from ultraglide.render.engine.friction_estimator import EstimatorSettings, FrictionEstimator
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.friction_models import StretchedExponentialModel
from ultraglide.render.physics.speed_law import SpeedLaw, SpeedLawModel
from ultraglide.render.renderer import Renderer
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures.procedural import grating

RATE_HZ = 12000.0
BLOCK = 60  # 5 ms
FORCE_N = 0.5  # the renderer's default: the path logs no force
V_REF = 22.0
STATIC = StretchedExponentialModel()
PROFILE = load_profile("sim-plate")
LIMIT = PROFILE.max_amplitude_um_pp  # 6 µm p-p
SEGMENTS = ((0.25, 20.0), (0.25, 80.0), (0.25, 200.0))  # (s, mm/s): a swipe that speeds up


def speeding_swipe() -> RecordedTrajectory:
    """Left to right at 20, then 80, then 200 mm/s, a quarter second each, knots every 5 ms (linear between)."""
    t, x = [0.0], [5.0]
    for duration, speed in SEGMENTS:
        for _ in range(int(round(duration / 0.005))):
            t.append(t[-1] + 0.005)
            x.append(x[-1] + speed * 0.005)
    return RecordedTrajectory(t, x, np.full(len(t), 25.0))


TEXTURE = grating(wavelength_mm=8.0, size_mm=(120.0, 50.0), ratio_range=(0.15, 1.0))


def render(model, trajectory=None, blocks=150):
    renderer = Renderer(TEXTURE, model, PROFILE, trajectory=trajectory or speeding_swipe())
    out = []
    for _ in range(blocks):
        block = renderer.control(BLOCK)
        x = block.x_mm.copy()
        steps = np.abs(np.diff(x))  # each sample's move from the one before; the first takes the second's (a jump
        steps = np.r_[steps[0], steps]  # between blocks is not motion): the block's speed is their mean × the rate
        out.append({"ratio": block.ratio.astype(float), "target": block.target_um_pp.copy(),
                    "amplitude": block.amplitude_um_pp.copy(), "drive": block.drive_um_pp.copy(),
                    "plate": block.plate_um_pp.copy(), "speed": float(np.mean(steps)) * RATE_HZ,
                    "down": np.broadcast_to(block.down, x.shape).copy()})
    return renderer, out


def test_s_zero_renders_bit_for_bit_what_the_model_alone_renders():
    for plain, with_law in (("stretched", "speed:0:stretched"), ("dynamic", "speed:0:dynamic")):
        _, expected = render(load_model(plain))
        renderer, got = render(load_model(with_law))
        assert renderer.speed_scale == 1.0
        for a, b in zip(expected, got, strict=True):
            for key in ("target", "amplitude", "drive", "plate"):
                assert np.array_equal(a[key], b[key]), (plain, key)


def test_open_loop_the_felt_ratio_follows_the_target_where_reachable_at_the_fingers_speed():
    law = SpeedLaw(0.5)
    renderer, blocks = render(SpeedLawModel(STATIC, law))
    unreachable = reachable = at_most = 0
    fast_clipped = slow_clipped = 0
    for block in blocks:
        k = (max(block["speed"], 2.0) / V_REF) ** 0.5  # by hand: the block's mean step × the control rate
        floor = float(STATIC.relative_friction(LIMIT / k, FORCE_N))
        # the inverse is asked within a limit under 0.1 % inside LIMIT / k (so its floor repeats across speeds):
        # exact above the floor there, the limit below the floor at LIMIT / k, between them one or the other
        inner_floor = float(STATIC.relative_friction(LIMIT / k / 1.001, FORCE_N))
        felt = STATIC.relative_friction(block["target"] / k, FORCE_N)  # the static law at a_eff = a / k
        ok = block["ratio"] >= inner_floor + 1e-6
        assert felt[ok] == pytest.approx(block["ratio"][ok], abs=1e-6)
        out = block["ratio"] < floor - 1e-6
        assert np.all(block["target"][out] == LIMIT)
        unreachable += int(np.count_nonzero(block["ratio"] < floor))
        at_most += int(np.count_nonzero(block["ratio"] < inner_floor))
        reachable += int(np.count_nonzero(ok))
        if block["speed"] > 150:
            fast_clipped += int(np.count_nonzero(out))
        elif block["speed"] < 30:
            slow_clipped += int(np.count_nonzero(out))
        for key in ("target", "amplitude", "plate"):
            assert block[key].max() <= LIMIT
        assert block["drive"].max() <= PROFILE.max_drive_um_pp
    assert unreachable <= renderer.counters.clipped_samples <= at_most
    assert at_most - unreachable < 0.01 * unreachable  # the band between the two floors is thin
    assert reachable > 3000 and fast_clipped > 500  # the floor rises with speed: most clipping is at 200 mm/s
    assert slow_clipped < fast_clipped / 10
    # the last block's scale: (200 / 22)^0.5, the amplitude a ratio needs there over what it needs at 22 mm/s
    assert renderer.speed_scale == pytest.approx((200.0 / V_REF) ** 0.5, rel=1e-3)


def test_the_closed_loops_feed_forward_goes_through_the_same_speed_scaled_inverse():
    """Following with an adapted scale of 1.25 at a measured 0.5 N: the amplitude is 1.25 k A(r), within the limit;
    the felt ratio by the static law at a / (1.25 k) is the target where reachable."""
    model = SpeedLawModel(STATIC, SpeedLaw(0.5))
    inverse = ClosedLoopInverse(model, clock=lambda: 100.0)
    inverse.command = LoopCommand(following=True, scale=1.25, force_n=FORCE_N, since_s=0.0, sensors_s=99.99,
                                  words="closed loop: following")
    renderer, blocks = render(inverse)
    assert inverse.closed_samples == 150 * BLOCK and inverse.open_samples == 0
    for block in blocks:
        k = 1.25 * (max(block["speed"], 2.0) / V_REF) ** 0.5
        floor = float(STATIC.relative_friction(LIMIT / k, FORCE_N))
        # the loop's scale and the speed law each ask within a rung of the limit ladder (under 0.1 % inside)
        inner_floor = float(STATIC.relative_friction(LIMIT / k / 1.001 ** 2, FORCE_N))
        ok = block["ratio"] >= inner_floor + 1e-6
        felt = STATIC.relative_friction(block["target"] / k, FORCE_N)
        assert felt[ok] == pytest.approx(block["ratio"][ok], abs=1e-6)
        assert np.all(block["target"][block["ratio"] < floor - 1e-6] == pytest.approx(LIMIT, abs=1e-12))
        assert block["target"].max() <= LIMIT and block["amplitude"].max() <= LIMIT


def test_with_friction_dynamics_the_planned_render_stays_within_the_limit_and_counts_what_speed_puts_out_of_reach():
    slow = render(load_model("dynamic"), blocks=150)[0].counters.clipped_samples
    renderer, blocks = render(load_model("speed:0.5:dynamic"), blocks=150)
    assert renderer.planner is not None
    assert all(block["amplitude"].max() <= LIMIT and block["target"].max() <= LIMIT for block in blocks)
    assert renderer.counters.clipped_samples > slow + 500  # the floor at 200 mm/s is far above the one at 22


def test_the_estimator_fits_the_finger_through_the_speed_law_at_the_panels_speed():
    """Sensor samples of a finger whose amplitude scale is 0.8 of the static law's and whose law weakens as
    (22 / v)^0.5, sliding at 88 mm/s (k = 2): a host with the law finds the finger's own 0.8; one without it takes
    the speed for the finger (1.6)."""
    finger_scale, mu0, speed = 0.8, 0.7, 88.0
    t = np.arange(8000) / 1000.0
    amplitude = 3.0 + 2.5 * np.sin(2 * math.pi * 1.5 * t)
    force = np.full(t.shape, FORCE_N)
    lateral = mu0 * STATIC.relative_friction(amplitude / (finger_scale * 2.0), force) * force
    settings = EstimatorSettings(sensor_delay_s=0.0, sensor_bandwidth_hz=0.0, identify_sensors=False)
    found = {}
    for name, host in (("law", SpeedLawModel(STATIC, SpeedLaw(0.5))), ("none", STATIC)):
        estimator = FrictionEstimator(host, settings, sensor_rate_hz=1000.0)
        for first in range(0, len(t), 10):
            estimator.update(first, amplitude[first:first + 10], force[first:first + 10],
                             lateral[first:first + 10], panel_speed_mm_s=speed)
        found[name] = (estimator.scale, estimator.mu0)
    assert found["law"][0] == pytest.approx(finger_scale, rel=0.02)
    assert found["none"][0] == pytest.approx(2.0 * finger_scale, rel=0.02)
    assert found["law"][1] == pytest.approx(mu0, rel=0.02)


def test_the_closed_loop_on_a_finger_with_the_law_identifies_the_finger_and_follows_it():
    """The friction loop around the simulated finger (tests/loop_rig.py) carrying the law s = 0.5 at 88 mm/s (k = 2),
    a host with the same law: the estimator finds the finger's own amplitude scale (0.8), not the speed's doubling,
    and the finger's true friction follows a slow grating, as closely as open loop with the finger's scale known."""
    from loop_rig import LoopRig
    from ultraglide.devices.sim.finger import FingerParams, FingerSpeedLaw, ForceScript

    finger_scale = 0.8

    def run(host, law):
        rig = LoopRig(host, lambda a, f: STATIC.relative_friction(a / finger_scale, f),
                      ForceScript.constant(0.5, 88.0), FingerParams(mu0=0.8, drift=0.0, moisture=0.0),
                      panel_speed_mm_s=88.0, speed_law=law)
        # 0.5-0.9: reachable at 88 mm/s (the finger's floor within 6 µm there is 0.43)
        return rig, rig.run(lambda t: 0.7 + 0.2 * np.cos(2 * math.pi * 2.0 * t), 6.0).rms_error(3.0)

    rig, error = run(SpeedLawModel(STATIC, SpeedLaw(0.5)), FingerSpeedLaw(0.5))
    assert rig.speed_scale == 2.0
    assert rig.loop.estimator.scale == pytest.approx(finger_scale, rel=0.05)
    _, without = run(STATIC, None)  # the same finger and loop with no speed law anywhere
    assert error < without + 0.005


def accelerating_swipe() -> RecordedTrajectory:
    """Left to right from 10 mm/s, 2 % faster every 5 ms knot, for 0.75 s: a new speed every block."""
    t, x, speed = [0.0], [5.0], 10.0
    for _ in range(150):
        t.append(t[-1] + 0.005)
        x.append(x[-1] + speed * 0.005)
        speed *= 1.02
    return RecordedTrajectory(t, x, np.full(len(t), 25.0))


@pytest.mark.parametrize("kind", ["stretched", "table"])
def test_a_changing_speed_evaluates_the_static_model_forward_only_in_the_first_pass_over_the_speeds(kind):
    """Under friction dynamics (the planner asks the floor at limit / k each block) with a law, a speed new every
    block: once the renderer has met those speeds, the static model is never evaluated forward on the block path
    (its floor at each rung of limit / k is remembered); the render still stays within the limit."""
    from conftest import ROOT
    from ultraglide.render.physics.dynamics import DynamicFrictionModel
    from ultraglide.render.physics.measurements import read_measurements
    from ultraglide.render.physics.table_model import TableModel

    static = (StretchedExponentialModel() if kind == "stretched"
              else TableModel(read_measurements(ROOT / "apps" / "data" / "monnoyer2018-fit.csv")))
    model = DynamicFrictionModel(SpeedLawModel(static, SpeedLaw(1.0)))
    render(model, accelerating_swipe())  # the warm-up: the speeds met once
    forward, calls = static.relative_friction, []
    static.relative_friction = lambda *args: calls.append(args) or forward(*args)
    renderer, blocks = render(model, accelerating_swipe())
    assert renderer.planner is not None
    assert len({round(block["speed"], 6) for block in blocks}) > 100  # a new speed (a new k) nearly every block
    assert calls == []
    assert all(block["amplitude"].max() <= LIMIT and block["target"].max() <= LIMIT for block in blocks)


def test_a_block_the_finger_leaves_counts_its_clamps_at_the_floor_at_that_speed():
    """A swipe at 200 mm/s that ends 2.5 ms into a block, in a trough of the grating: in that block only the samples
    still touching are counted, against the floor at that speed (the static floor at LIMIT / k), not the floor at the
    reference speed."""
    t = np.arange(0.0, 0.1026, 0.0025)
    renderer, blocks = render(SpeedLawModel(STATIC, SpeedLaw(0.5)),
                              RecordedTrajectory(t, 7.0 + 200.0 * t, np.full(len(t), 25.0)), blocks=21)
    partial = [b for b in blocks if 0 < np.count_nonzero(b["down"]) < BLOCK]
    assert len(partial) == 1
    low = high = 0
    for block in blocks:
        k = (max(block["speed"], 2.0) / V_REF) ** 0.5
        low += int(np.count_nonzero((block["ratio"] < float(STATIC.relative_friction(LIMIT / k, FORCE_N)))
                                    & block["down"]))
        inner = float(STATIC.relative_friction(LIMIT / k / 1.001, FORCE_N))  # see the open-loop test
        high += int(np.count_nonzero((block["ratio"] < inner) & block["down"]))
    block = partial[0]
    k = (max(block["speed"], 2.0) / V_REF) ** 0.5
    assert k > 2.0  # the block is fast (half of it moving): its floor is far above the one at 22 mm/s
    assert np.count_nonzero((block["ratio"] < float(STATIC.relative_friction(LIMIT / k, FORCE_N))) & block["down"]) \
        > np.count_nonzero((block["ratio"] < float(STATIC.relative_friction(LIMIT, FORCE_N))) & block["down"])
    assert low <= renderer.counters.clipped_samples <= high


def test_the_estimators_reset_starts_its_sensors_at_the_ratio_the_law_gives_at_the_panels_speed():
    """Through a 20 ms sensor delay the first samples seen are the reset's: the settled ratio at 4 µm p-p and
    88 mm/s (k = 2), the static law at 2 µm p-p, not at 4."""
    settings = EstimatorSettings(sensor_delay_s=0.02, sensor_bandwidth_hz=0.0, identify_sensors=False)
    estimator = FrictionEstimator(SpeedLawModel(STATIC, SpeedLaw(0.5)), settings, sensor_rate_hz=1000.0)
    expected = float(STATIC.relative_friction(2.0, FORCE_N))
    amplitude, force = np.full(500, 4.0), np.full(500, FORCE_N)  # one batch: long enough to be trusted as sliding
    result = estimator.update(0, amplitude, force, 0.7 * expected * force, panel_speed_mm_s=88.0)
    assert result.used.all()
    assert expected != pytest.approx(float(STATIC.relative_friction(4.0, FORCE_N)), abs=0.05)
    assert result.intended_ratio[:20] == pytest.approx(np.full(20, expected), abs=1e-9)
