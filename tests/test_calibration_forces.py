"""The forces a calibration was fitted at survive being written and read back, and the force asked of a press is
inside them: a participant calibrated at 0.5 N renders at 0.5 N without being told it is extrapolated."""

import csv
import tomllib
import warnings

import pytest
from conftest import run_cli
from test_calibration_on_plate import record_in_simulated_time
from ultraglide.apps.calibration.plan import CalibrationPlan
from ultraglide.apps.calibration.recording import FORCE_RESOLUTION_N
from ultraglide.render.engine.finger_setup import FingerConfig
from ultraglide.render.physics.calibration import calibration_toml, fit_model, read_calibration
from ultraglide.render.physics.errors import ForceRangeWarning


def test_a_press_is_its_mean_force_to_the_sensors_resolution_and_reads_back_exactly(tmp_path):
    plan = CalibrationPlan((0.5,), 6.0, passes=1, step_s=0.2, settle_s=0.08, lead_s=0.6)
    recorder = record_in_simulated_time(plan, FingerConfig(drift=0.0))
    data, missing = recorder.measurements("simulated participant", "P1")
    assert missing == 0 and len(data) == plan.levels
    assert set(data.force_n.tolist()) == {0.5}  # the finger pressed 0.5 N: its mean within 0.5 mN of it
    assert FORCE_RESOLUTION_N == 0.001
    path = tmp_path / "p1.toml"
    path.write_text(calibration_toml(fit_model(data, "stretched"), participant="P1"))
    assert tomllib.loads(path.read_text())["fit"]["forces_n"] == [0.5]
    model = read_calibration(path)
    assert model.fitted.forces_n == (0.5,)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ForceRangeWarning)
        model.relative_friction(2.0, 0.5)  # the force it was fitted at: no warning
    with pytest.warns(ForceRangeWarning, match=r"0\.6 N is outside the forces this stretched calibration was "
                                               r"fitted on \(0\.5 N only\)"):
        read_calibration(path).relative_friction(2.0, 0.6)  # another force still is said to be extrapolated


@pytest.mark.slow
def test_calibrate_then_model_at_the_pressed_force_says_no_warning(tmp_path):
    output = tmp_path / "p1.toml"
    result = run_cli("calibrate", "--device", "sim", "--participant", "P1", "-o", output, "--no-window",
                     "--forces", "0.5", "--passes", "1", "--step-ms", "200", "--finger-drift", "0", "--bootstrap", "0")
    assert result.returncode == 0, result.stderr
    fitted = tomllib.loads(output.read_text())["fit"]["forces_n"]
    with open(output.with_suffix(".csv"), newline="") as handle:
        written = {float(row["force_n"]) for row in csv.DictReader(handle)}
    assert fitted == [0.5] and written == {0.5}  # the points' file and the calibration hold the same force
    shown = run_cli("model", "--model", output, "--force", "0.5")
    assert shown.returncode == 0 and "warning" not in shown.stderr, shown.stderr
    refit = run_cli("calibrate", output.with_suffix(".csv"), "-o", tmp_path / "again.toml", "--bootstrap", "0")
    assert refit.returncode == 0, refit.stderr
    assert tomllib.loads((tmp_path / "again.toml").read_text())["fit"]["forces_n"] == [0.5]
    assert "warning" not in run_cli("model", "--model", tmp_path / "again.toml").stderr
