"""The simulated finger with a settled speed law (devices/sim/finger.py, the plate's own implementation of the law
docs/physics.md states), and the renderer compensating such a finger as its speed changes."""

import numpy as np
import pytest
from test_speed_law_renderer import BLOCK, FORCE_N, LIMIT, PROFILE, SEGMENTS, STATIC, TEXTURE, speeding_swipe
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.sim.finger import FingerParams, FingerSpeedLaw, ForceScript, SimulatedFinger
from ultraglide.devices.sim.force_sensors import ForceSensorParams
from ultraglide.render.engine.finger_setup import FingerConfig, build_finger
from ultraglide.render.physics.speed_law import SpeedLaw, SpeedLawModel
from ultraglide.render.renderer import Renderer

STILL = FingerParams(drift=0.0, moisture=0.0)
QUIET = ForceSensorParams(noise_n=0.0)


def law(amplitude_um_pp, force_n):
    return STATIC.relative_friction(amplitude_um_pp, force_n)


def test_the_fingers_law_is_evaluated_at_a_v_ref_over_v_to_the_s():
    amplitude = np.linspace(0.0, 6.0, 480)
    for speed, effective in ((88.0, amplitude / 2.0), (22.0, amplitude), (1.0, amplitude * (22.0 / 2.0) ** 0.5)):
        finger = SimulatedFinger(law, ForceScript.constant(FORCE_N, speed), STILL, QUIET,
                                 speed_law=FingerSpeedLaw(0.5))
        truth = finger.truth(np.arange(480) / 48000.0, amplitude)
        expected = STATIC.relative_friction(effective, FORCE_N)
        assert truth.relative_friction == pytest.approx(expected, abs=1e-12), speed
    plain = SimulatedFinger(law, ForceScript.constant(FORCE_N, 88.0), STILL, QUIET, speed_law=FingerSpeedLaw(0.0))
    assert plain.speed_law is None
    assert plain.truth(np.arange(480) / 48000.0, amplitude).relative_friction == pytest.approx(
        STATIC.relative_friction(amplitude, FORCE_N), abs=1e-12)


@pytest.mark.parametrize("exponent, reference", [(-0.1, 22.0), (1.5, 22.0), (0.5, 0.0), (float("nan"), 22.0)])
def test_a_speed_law_out_of_range_is_refused(exponent, reference):
    with pytest.raises(DeviceError, match="speed law"):
        FingerSpeedLaw(exponent, reference)


def test_a_finger_given_a_speed_law_model_carries_the_law():
    finger = build_finger(FingerConfig(law="speed:0.5:stretched", force="0.5", speed_mm_s=88.0, drift=0.0,
                                       moisture=0.0, noise_n=0.0))
    assert finger.speed_law == FingerSpeedLaw(0.5, 22.0) and finger.dynamics is None
    amplitude = np.full(48, 4.0)
    truth = finger.truth(np.arange(48) / 48000.0, amplitude)
    assert truth.relative_friction == pytest.approx(STATIC.relative_friction(amplitude / 2.0, FORCE_N), abs=1e-9)
    assert "reduction x (22 mm/s / v)^0.5" in repr(finger)
    lagging = FingerConfig(law="speed:0.5:dynamic")
    assert lagging.lags and build_finger(lagging).speed_law == FingerSpeedLaw(0.5)
    spelled = FingerConfig(law="dynamic:speed:0.5:stretched")  # the spelling docs/physics.md lists
    assert spelled.lags and build_finger(spelled).speed_law == FingerSpeedLaw(0.5)
    assert build_finger(FingerConfig(law="stretched")).speed_law is None


def felt_error(model) -> float:
    """The renderer's plate amplitude on the speeding swipe, played to a finger with the speed law s = 0.5 sliding
    at the swipe's speeds: the RMS of the finger's true ratio against the target, where the target is reachable at
    that speed (and the envelope's first 50 ms left out)."""
    renderer = Renderer(TEXTURE, model, PROFILE, trajectory=speeding_swipe())
    blocks = [renderer.control(BLOCK) for _ in range(150)]
    plate = np.concatenate([b.plate_um_pp for b in blocks])
    target = np.concatenate([b.ratio for b in blocks]).astype(float)
    times, speeds, start = [], [], 0.0
    for duration, speed in SEGMENTS:
        times += [start, start + duration - 1e-4]
        speeds += [speed, speed]
        start += duration
    script = ForceScript.points(times, [FORCE_N] * len(times), speeds)
    finger = SimulatedFinger(law, script, STILL, QUIET, speed_law=FingerSpeedLaw(0.5))
    truth = finger.truth(np.arange(4 * len(plate)) / 48000.0, np.repeat(plate, 4)).relative_friction[::4]
    t = np.arange(len(plate)) / 12000.0
    speed_at = np.interp(t, times, speeds)
    floor = STATIC.relative_friction(LIMIT * (22.0 / speed_at) ** 0.5, FORCE_N)
    pick = (t > 0.05) & (target > floor + 0.02)
    assert np.count_nonzero(pick) > 4000
    return float(np.sqrt(np.mean((truth[pick] - target[pick]) ** 2)))


def test_the_renderer_with_the_law_compensates_a_finger_whose_reduction_weakens_with_speed():
    compensated = felt_error(SpeedLawModel(STATIC, SpeedLaw(0.5)))
    ignored = felt_error(STATIC)
    assert compensated < 0.02  # what is left: the envelope's band limit and slew on the grating's edges
    assert ignored > 4 * compensated


def test_a_finger_given_a_calibration_with_a_speed_table_carries_its_reference_speed(tmp_path):
    """The file's reference speed reaches the finger; the file edited since is read as it is now."""
    path = tmp_path / "finger.toml"
    for reference in (40.0, 60.0):
        path.write_text('ultraglide_calibration = 1\nmodel = "exponential"\n[speed]\nexponent = 0.5\n'
                        f"reference_speed_mm_s = {reference}\n[parameters]\ntau_um_zp = 1.0\n", encoding="utf-8")
        assert build_finger(FingerConfig(law=str(path))).speed_law == FingerSpeedLaw(0.5, reference)


def test_plate_sim_runs_a_finger_with_a_speed_law_and_logs_its_truth(tmp_path):
    """``plate-sim --finger speed:1:stretched`` at 88 mm/s, played a grating: the finger's logged friction is the
    stretched law at a quarter of each logged amplitude (22 / 88, by hand), not at the amplitude itself."""
    import csv
    import json
    import signal
    import subprocess
    import sys
    import threading

    from conftest import run_cli

    log, link = tmp_path / "truth.csv", tmp_path / "plate"
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--link", str(link), "--json",
                                "--finger", "speed:1:stretched", "--finger-speed-mm-s", "88", "--finger-force", "0.5",
                                "--finger-drift", "0", "--finger-moisture", "0", "--finger-log", str(log)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        serving = json.loads(process.stdout.readline())
        assert serving["event"] == "serving" and "speed" in serving["finger"], serving
        threading.Thread(target=process.communicate, daemon=True).start()  # its events never fill a pipe
        result = run_cli("play", "grating-1mm", "--device", f"serial:{link}", "--profile", "sim-plate",
                         "--duration-s", "1.0", "--json")
        # a machine loaded far past two CPU hogs can starve plate-sim until the host's write times out: play then
        # says the plate was lost (exit 4); what the finger logged until then still counts
        assert result.returncode == 0 or (result.returncode == 4 and "lost" in result.stderr), result.stderr
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=60)
    with open(log, newline="") as file:
        rows = list(csv.DictReader(file))
    amplitude = np.array([float(r["amplitude_um_pp"]) for r in rows])
    ratio = np.array([float(r["relative_friction"]) for r in rows])
    assert amplitude.max() > 1.0  # the grating played
    np.testing.assert_allclose(ratio, STATIC.relative_friction(amplitude / 4.0, 0.5), atol=3e-5)  # the log: 5 places
    assert np.max(np.abs(ratio - STATIC.relative_friction(amplitude, 0.5))) > 0.1  # the law made a difference
