"""The simulated finger and its force sensors, against hand-computed values and their own truth."""

import csv
import math
import time

import numpy as np
import pytest
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.sim.finger import FingerParams, ForceScript, SimulatedFinger
from ultraglide.devices.sim.finger_log import HEADER, FingerLog
from ultraglide.devices.sim.force_sensors import ForceSensorParams

FS = 48000
STILL = FingerParams(drift=0.0, moisture=0.0)
IDEAL = ForceSensorParams(noise_n=0.0, bandwidth_hz=0.0, delay_s=0.0)


def gaussian(a, f):
    return np.exp(-(np.asarray(a) / 3.0) ** 2)


def run(finger, amplitude, block=96, start_s=0.0):
    """Feed ``amplitude`` (one value a plate sample) block by block; the sensors' normal and lateral output."""
    normal, lateral = [], []
    first = int(round(start_s * FS))
    for k in range(0, len(amplitude), block):
        n, lat = finger.forces((first + k) / FS, amplitude[k:k + block])
        normal.append(n.copy())
        lateral.append(lat.copy())
    return np.concatenate(normal), np.concatenate(lateral)


def test_lateral_force_is_mu0_times_the_law_times_the_force():
    finger = SimulatedFinger(gaussian, ForceScript.constant(0.4), FingerParams(mu0=0.8, drift=0, moisture=0), IDEAL)
    amplitude = np.full(FS // 10, 2.0)
    normal, lateral = run(finger, amplitude)
    expected = 0.8 * math.exp(-(2.0 / 3.0) ** 2) * 0.4  # 0.2052 N
    assert normal[-1] == pytest.approx(0.4)
    assert lateral[-1] == pytest.approx(expected, rel=1e-12)
    assert finger.last.relative_friction[-1] == pytest.approx(math.exp(-4 / 9))


def test_friction_follows_the_plates_amplitude_sample_by_sample():
    finger = SimulatedFinger(gaussian, ForceScript.constant(0.5), STILL, IDEAL)
    amplitude = np.linspace(0.0, 5.0, 4800)
    _, lateral = run(finger, amplitude, block=37)  # any block length
    np.testing.assert_allclose(lateral, 0.5 * np.exp(-(amplitude / 3.0) ** 2), rtol=1e-12)


def test_the_sensors_delay_and_bandwidth():
    sensors = ForceSensorParams(noise_n=0.0, bandwidth_hz=200.0, delay_s=0.002)
    finger = SimulatedFinger(gaussian, ForceScript.constant(0.5), STILL, sensors)
    amplitude = np.zeros(FS // 10)
    amplitude[2400:] = 3.0  # at 50 ms the friction steps from 0.5 N to 0.5 exp(-1) N
    _, lateral = run(finger, amplitude, block=12)
    step_out = 2400 + 96  # 2 ms later
    assert np.all(lateral[1000:step_out] == pytest.approx(0.5, abs=1e-9))  # settled at 0.5 N, then held for 2 ms
    assert lateral[step_out] < 0.5
    low = 0.5 * math.exp(-1.0)
    # first order: 1 - 1/e of the way after 1 / (2 pi 200 Hz) = 0.796 ms = 38.2 samples
    tau_samples = FS / (2 * math.pi * 200.0)
    k = int(round(tau_samples))
    expected = low + (0.5 - low) * math.exp(-2 * math.pi * 200.0 * (k + 1) / FS)
    assert lateral[step_out + k] == pytest.approx(expected, rel=1e-9)
    assert lateral[-1] == pytest.approx(low, rel=1e-6)


def test_blocks_of_any_length_give_the_same_readings():
    sensors = ForceSensorParams(noise_n=0.005, bandwidth_hz=300.0, delay_s=0.001)
    amplitude = 3.0 + 2.0 * np.sin(np.arange(FS // 5) * 2 * math.pi * 150 / FS)
    outputs = []
    for block in (12, 96, 1000):
        finger = SimulatedFinger(gaussian, ForceScript.walk(seed=3), FingerParams(), sensors)
        outputs.append(run(finger, amplitude, block=block))
    for normal, lateral in outputs[1:]:
        np.testing.assert_allclose(normal, outputs[0][0], atol=1e-12)
        np.testing.assert_allclose(lateral, outputs[0][1], atol=1e-12)


def test_noise_is_as_stated_per_sensor_sample_and_held_over_a_period():
    sensors = ForceSensorParams(noise_n=0.005, bandwidth_hz=0.0, delay_s=0.0, sensor_rate_hz=1000)
    finger = SimulatedFinger(gaussian, ForceScript.constant(0.5, speed_mm_s=0.0), STILL, sensors)
    normal, lateral = run(finger, np.zeros(FS * 4), block=480)
    per_period = normal.reshape(-1, 48)  # what the firmware averages into one sensor sample
    assert np.all(per_period.max(axis=1) - per_period.min(axis=1) < 1e-12)  # held over each period
    samples = per_period.mean(axis=1) - 0.5
    assert len(samples) == 4000
    assert samples.std() == pytest.approx(0.005, rel=0.05)
    assert abs(samples.mean()) < 0.0005
    lateral_samples = lateral.reshape(-1, 48).mean(axis=1)
    assert lateral_samples.std() == pytest.approx(0.005, rel=0.05)
    assert abs(np.corrcoef(samples, lateral_samples)[0, 1]) < 0.1  # independent channels


def test_a_finger_at_rest_sticks_and_a_lifted_one_presses_nothing():
    points = ForceScript.points([0.0, 0.1, 0.1001, 0.2, 0.2001], [0.5, 0.5, 0.5, 0.5, 0.0], [100, 100, 0, 0, 0])
    finger = SimulatedFinger(gaussian, points, STILL, IDEAL)
    normal, lateral = run(finger, np.full(int(0.3 * FS), 1.0))
    ms = FS // 1000
    assert lateral[50 * ms] == pytest.approx(0.5 * math.exp(-1 / 9))  # sliding
    assert lateral[150 * ms] == 0.0 and normal[150 * ms] == pytest.approx(0.5)  # resting: no friction
    assert lateral[250 * ms] == 0.0 and normal[250 * ms] == 0.0  # lifted
    assert not finger.last.sliding.any()


def test_the_law_drifts_in_scale():
    params = FingerParams(drift=0.3, drift_period_s=1.0, moisture=0.0)
    finger = SimulatedFinger(gaussian, ForceScript.constant(0.5), params, IDEAL)
    amplitude = np.full(FS, 3.0)
    _, lateral = run(finger, amplitude, block=48)
    quarter = FS // 4  # k = 1.3: the law is stretched, friction is higher
    for at, k in ((quarter, 1.3), (3 * quarter, 0.7)):
        ratio = lateral[at] / 0.5
        assert ratio == pytest.approx(math.exp(-(3.0 / (3.0 * k)) ** 2), rel=1e-6)


def test_friction_rises_with_dwell_and_dries_after_a_lift():
    params = FingerParams(drift=0.0, moisture=0.5, moisture_tau_s=0.2)
    points = ForceScript.points([0.0, 1.0, 1.0001], [0.5, 0.5, 0.0], [100, 100, 100])
    finger = SimulatedFinger(gaussian, points, params, IDEAL)
    _, lateral = run(finger, np.zeros(int(1.2 * FS)), block=96)
    def wet(i):  # dw/dt = (1 - w) / tau from w = 0, sample by sample
        return 1.0 - math.exp(-(i + 1) / (FS * 0.2))

    for at in (96, int(0.2 * FS), FS - 1):  # at 0.2 s: 1 - 1/e of the way to mu0 (1 + 0.5)
        assert lateral[at] / 0.5 == pytest.approx(1.0 + 0.5 * wet(at), rel=1e-9)
    assert wet(int(0.2 * FS)) == pytest.approx(1 - math.exp(-1), rel=1e-4)


def test_the_random_walk_stays_in_its_range_and_wanders_across_it():
    finger = SimulatedFinger(gaussian, ForceScript.walk(0.2, 1.0, seed=7), STILL, IDEAL)
    normal, _ = run(finger, np.zeros(60 * FS), block=48000)
    assert normal.min() >= 0.2 - 1e-12 and normal.max() <= 1.0 + 1e-12
    assert normal.max() - normal.min() > 0.5  # a minute covers most of the range
    again = SimulatedFinger(gaussian, ForceScript.walk(0.2, 1.0, seed=7), STILL, IDEAL)
    np.testing.assert_allclose(run(again, np.zeros(FS), block=480)[0], normal[:FS], rtol=1e-12)  # seeded


def test_force_specs_and_scripts(tmp_path):
    assert ForceScript.parse("0.7").force_n == 0.7
    walk = ForceScript.parse("walk:0.3-0.9", speed_mm_s=50)
    assert (walk.low_n, walk.high_n, walk.speed_mm_s) == (0.3, 0.9, 50)
    script = tmp_path / "force.csv"
    script.write_text("t_s,force_n,speed_mm_s\n0,0.2,100\n1,0.6,0\n")
    points = ForceScript.parse(str(script))
    finger = SimulatedFinger(gaussian, points, STILL, IDEAL)
    normal, _ = run(finger, np.zeros(FS), block=4800)
    assert normal[FS // 2] == pytest.approx(0.4, abs=1e-4)
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,force_n\n0,0.2\n1,heavy\n")
    with pytest.raises(DeviceError, match="line 3"):
        ForceScript.parse(str(bad))
    for spec in ("walk:1-0.2", "-1", "sideways"):
        with pytest.raises(DeviceError):
            ForceScript.parse(spec)
    with pytest.raises(DeviceError):
        FingerParams(drift=2.0)
    with pytest.raises(DeviceError):
        ForceSensorParams(noise_n=float("nan"))


def test_the_log_is_the_truth_on_the_hosts_clock(tmp_path):
    path = tmp_path / "finger.csv"
    log = FingerLog(path, rate_hz=1000.0)
    finger = SimulatedFinger(gaussian, ForceScript.constant(0.5), STILL, IDEAL, log=log)
    origin = time.perf_counter()
    log.clock_origin_s = origin
    amplitude = np.linspace(0.0, 4.0, FS // 2)
    run(finger, amplitude, block=96)
    assert not path.exists() and path.with_name("finger.csv.part").exists()  # not whole until closed
    finger.close()
    assert path.exists() and not path.with_name("finger.csv.part").exists()
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    assert ",".join(rows[0]) == HEADER
    data = np.array(rows[1:], dtype=float)
    assert len(data) == 500
    np.testing.assert_allclose(data[:, 0] - origin, np.arange(500) / 1000.0, atol=2e-6)
    np.testing.assert_allclose(data[:, 1], amplitude[::48], atol=1e-5)
    np.testing.assert_allclose(data[:, 3], np.exp(-(amplitude[::48] / 3.0) ** 2), atol=1e-5)
    assert set(data[:, 4]) == {1.0} and set(data[:, 2]) == {0.5}
