"""On-plate calibration: the plan, its recording from the plate's sensors, the fit, the file with the participant.

Recovery is checked in simulated time (the firmware core, the plate's physics and a simulated participant joined
by protocol frames: the same parts as ``calibrate --device sim``, whatever the machine's load); the command is
checked for what it writes and says."""

import csv
import json
import tomllib
from dataclasses import replace

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from ultraglide.apps.calibration.guide import advice
from ultraglide.apps.calibration.plan import CalibrationPlan
from ultraglide.apps.calibration.recording import PlanSource, StepRecorder
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.plate import PlateSimulator
from ultraglide.render.engine.finger_setup import FingerConfig, build_finger
from ultraglide.render.physics.calibration import fit_model, read_calibration
from ultraglide.render.physics.measurements import participant_id

HOST_SCALE_UM_PP = 3.7335  # the stretched law's scale at 0.5 N (2 sqrt 2 x 1.32 µm)


def record_in_simulated_time(plan: CalibrationPlan, finger: FingerConfig) -> StepRecorder:
    """The plan played to the simulated plate (its amplitude loop on), SENSORS into the recorder, in simulated time."""
    profile = load_profile("sim-plate")
    times, forces = plan.force_points()
    simulated = build_finger(replace(finger, force_points=(tuple(times), tuple(forces))))
    plate = PlateSimulator(profile, finger=simulated)
    plate._started = plate._clock = 0.0
    recorder = StepRecorder(plan, 12000)
    source = PlanSource(plan, 12000)
    framer, decoder = p.SetpointFramer(12000), p.FrameDecoder()
    seq = 0
    for kind, payload in ((p.HELLO, p.hello_payload()), (p.SET_LOOP, p.set_loop_payload(1)),
                          (p.SET_CARRIER, p.carrier_payload(profile.resonance_hz)), (p.ENABLE, p.enable_payload(True))):
        seq += 1
        plate.receive(p.encode_frame(kind, seq, payload))
    index = 0
    for ms in range(int((plan.duration_s + 0.2) * 1000)):
        values = source.pull(12, ms / 1000.0) / profile.full_scale_um_pp
        seq += 1
        plate.receive(framer.frame(seq, index, values))
        index += 12
        for reply in plate.advance(ms / 1000.0):
            for frame in decoder.feed(reply):
                if frame.kind == p.SENSORS:
                    recorder.take(p.parse_sensors(frame.payload))
    return recorder


@pytest.mark.slow
def test_on_plate_calibration_recovers_the_simulated_participants_law():
    """The default simulated finger (the stretched law x0.7 with a floor of 0.1, its friction at rest rising with
    dwell) at three presses: the fitted law is the finger's within stated tolerances."""
    plan = CalibrationPlan((0.25, 0.5, 0.9), 6.0, passes=1, step_s=0.2, settle_s=0.08, lead_s=0.6)
    recorder = record_in_simulated_time(plan, FingerConfig(drift=0.0, moisture=0.25, moisture_tau_s=5.0))
    data, missing = recorder.measurements("simulated participant", 7)
    assert missing == 0 and len(data) == 3 * plan.levels
    assert sorted(set(data.force_n.round(2))) == [0.25, 0.5, 0.9]
    fit = fit_model(data, "stretched", cross_validate=True)
    values = fit.model.parameters()
    assert values["scale_um_pp"] == pytest.approx(0.7 * HOST_SCALE_UM_PP, rel=0.05)
    assert values["shape"] == pytest.approx(2.0, rel=0.1)
    assert values["force_exponent"] == pytest.approx(1 / 3, abs=0.1)
    assert values["residual_ratio"] == pytest.approx(0.1, abs=0.03)
    assert fit.rms_residual < 0.02 and fit.cv_rms < 0.03


def test_the_plan_interleaves_rest_and_plays_each_amplitude_at_each_press():
    plan = CalibrationPlan((0.3, 0.8), 6.0, levels=4, passes=2, step_s=0.25, settle_s=0.1, lead_s=1.0)
    steps = plan.steps()
    for level in (0, 1):
        amplitudes = [s.amplitude_um_pp for s in steps if s.level == level]
        assert amplitudes[0] == 0.0 and amplitudes[-1] == 0.0
        assert all(amplitudes[k] == 0.0 for k in range(1, len(amplitudes), 2))  # a rest between every two steps
        stepped = [a for a in amplitudes if a > 0]
        top = 0.95 * 6.0  # up to 95 % of the limit, from a twelfth of that: 0.475, 2.217, 3.958, 5.7 µm p-p
        ladder = [top / 12 + k * (top - top / 12) / 3 for k in range(4)]
        assert stepped == pytest.approx(ladder + ladder[::-1])  # up, then down
    assert plan.duration_s == pytest.approx(2 * (1.0 + 16 * 0.25 + 0.25))
    assert plan.amplitude_at([0.5, 1.3, 1.55]).tolist() == pytest.approx([0.0, 0.475, 0.0])
    assert plan.step_at(1.26) is None and plan.step_at(1.36) == 2  # a step is measured after its settling
    times, forces = plan.force_points()
    assert np.interp(plan.level_starts_s()[1] + 1.0, times, forces) == pytest.approx(0.8)


def test_the_guide_asks_for_a_steady_press():
    assert advice(float("nan"), 0.5, False) == "put your finger on the plate and slide"
    assert advice(0.3, 0.5, True) == "press heavier"
    assert advice(0.7, 0.5, True) == "press lighter"
    assert advice(0.55, 0.5, True) == "steady: keep sliding"


@pytest.mark.slow
def test_calibrate_on_the_simulator_in_its_window_writes_the_participants_calibration(tmp_path):
    output = tmp_path / "p07.toml"
    result = run_cli("calibrate", "--device", "sim", "--participant", "P07", "-o", output, "--passes", "2",
                     "--step-ms", "200", "--forces", "0.3,0.8", "--finger-drift", "0", "--bootstrap", "0",
                     "--no-finger-dynamics", "--windowed", env={"SDL_VIDEODRIVER": "dummy"})
    assert result.returncode == 0, result.stderr
    assert "participant P07:" in result.stdout and "wrote" in result.stdout
    document = tomllib.loads(output.read_text())
    assert document["fit"]["participant"] == "P07" and "2 presses (0.3, 0.8 N)" in document["fit"]["procedure"]
    model = read_calibration(output)  # what experiments and the demo take (--model CAL.toml)
    assert model.name == "stretched"
    with open(output.with_suffix(".csv"), newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) >= 8 and {row["participant"] for row in rows} == {"P07"}  # the passes averaged: 8 a press
    refit = run_cli("calibrate", output.with_suffix(".csv"), "--bootstrap", "0", "--participant", "P07", "--json")
    assert refit.returncode == 0, refit.stderr  # the points refit as any CSV, the participant chosen by its id
    assert json.loads(refit.stdout)["fit"]["points"] == len(rows)


@pytest.mark.slow
def test_calibrate_on_the_simulator_without_a_window_recovers_the_simulated_law(tmp_path):
    """``calibrate --device sim --no-window`` in real time, as a script runs it: the default simulated finger (the
    host's stretched law with its scale x0.7 and a floor of 0.1, not drifting; without its lag, whose fit
    test_calibration_dynamics_on_plate.py checks) at three presses; the fitted law is the finger's: scale within
    5 %, shape within 10 %, force exponent 1/3 within 0.1, floor within 0.03."""
    output = tmp_path / "p07.toml"
    result = run_cli("calibrate", "--device", "sim", "--participant", "7", "-o", output, "--no-window", "--json",
                     "--passes", "1", "--step-ms", "200", "--finger-drift", "0", "--bootstrap", "0",
                     "--no-finger-dynamics")
    assert result.returncode == 0, result.stderr
    assert "press 3 of 3: slide at a steady 0.9 N" in result.stderr  # the guide's words, on the terminal
    report = json.loads(result.stdout)
    assert report["participant"] == "7" and report["points"] >= 12  # of 24 steps (a loaded machine underruns some)
    values = {name: entry["value"] for name, entry in report["fit"]["parameters"].items()}
    assert values["scale_um_pp"] == pytest.approx(0.7 * HOST_SCALE_UM_PP, rel=0.05)
    assert values["shape"] == pytest.approx(2.0, rel=0.1)
    assert values["force_exponent"] == pytest.approx(1 / 3, abs=0.1)
    assert values["residual_ratio"] == pytest.approx(0.1, abs=0.03)
    assert read_calibration(output).name == "stretched"


def test_participant_ids_are_text_and_numbers_the_same_id_however_written():
    assert [participant_id(text) for text in ("P01", " s-12_b.3 ", "7", "7.0", "07", "-2")] == \
        ["P01", "s-12_b.3", "7", "7", "7", "-2"]
    for bad in ("", "P 01", "a,b", "x" * 65, "p\n1", "é#"):
        with pytest.raises(ValueError, match="participant id"):
            participant_id(bad)


def test_calibrate_takes_a_csv_or_a_device_and_a_device_needs_a_participant(cli, tmp_path):
    line = assert_one_line_error(cli("calibrate", "--device", "sim", "--participant", "P 01", "-o",
                                     str(tmp_path / "c.toml"), "--no-window"))
    assert "participant id" in line
    line = assert_one_line_error(cli("calibrate", "--participant", "3"))
    assert "DATA.csv" in line and "--device" in line
    line = assert_one_line_error(cli("calibrate", "--device", "sim", "-o", str(tmp_path / "c.toml")))
    assert "--participant" in line
    line = assert_one_line_error(cli("calibrate", "--device", "null", "--participant", "3", "-o",
                                     str(tmp_path / "c.toml"), "--no-window"))
    assert "force sensors" in line
    assert not list(tmp_path.iterdir())
