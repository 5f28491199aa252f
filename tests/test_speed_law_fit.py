"""The reduction's speed law fitted from points at several sliding speeds (render/physics/speed_fit.py), read from
a measurement CSV's ``speed_mm_s`` column, written by ``calibrate`` into a calibration's ``[speed]`` table and read
back as a model; kept only where it predicts points it did not see better than ignoring speed."""

import json

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.friction_models import StretchedExponentialModel
from ultraglide.render.physics.measurements import Measurements, read_measurements
from ultraglide.render.physics.speed_fit import fit_speed_law

STATIC = StretchedExponentialModel()
AMPLITUDES = np.linspace(0.0, 6.0, 13)


def points(exponent: float, speeds, noise: float = 0.01, seed: int = 0) -> Measurements:
    """The stretched law at 0.5 N evaluated at a (22 / v)^s, by hand, with Gaussian noise."""
    amplitude = np.tile(AMPLITUDES, len(speeds))
    speed = np.repeat(np.asarray(speeds, dtype=float), len(AMPLITUDES))
    ratio = STATIC.relative_friction(amplitude * (22.0 / speed) ** exponent, 0.5)
    ratio = ratio + np.random.default_rng(seed).normal(0.0, noise, len(ratio))
    return Measurements(amplitude, ratio, np.full(len(ratio), 0.5), "by hand", speed_mm_s=speed)


def write_csv(path, data: Measurements):
    rows = ["amplitude_um_pp,relative_friction,force_n,speed_mm_s"]
    rows += [f"{a:.5f},{r:.5f},{f:g},{v:g}" for a, r, f, v in
             zip(data.amplitude_um_pp, data.relative_friction, data.force_n, data.speed_mm_s, strict=True)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("speeds", [(25.0, 150.0), (20.0, 60.0, 180.0)])
@pytest.mark.parametrize("exponent", [0.3, 0.7])
def test_the_exponent_is_recovered_within_its_interval_and_kept(exponent, speeds):
    fitted = fit_speed_law(points(exponent, speeds))
    low, high = fitted.interval
    assert low <= exponent <= high and high - low < 0.2, fitted
    assert abs(fitted.exponent - exponent) < 0.05
    assert fitted.kept and fitted.held_out_with_law < fitted.held_out_without
    assert fitted.law().exponent == round(fitted.exponent, 3) and fitted.law().source.startswith("fitted to ")


@pytest.mark.parametrize("speeds", [(25.0, 150.0), (20.0, 60.0, 180.0)])
def test_points_that_do_not_depend_on_speed_keep_no_law(speeds):
    fitted = fit_speed_law(points(0.0, speeds, seed=4))
    assert not fitted.kept and fitted.law() is None
    assert fitted.interval[0] == 0.0 and fitted.held_out_without <= fitted.held_out_with_law
    assert "cannot be told" in fitted.note


def test_one_speed_cannot_tell_and_no_speeds_or_a_table_are_refused():
    one = fit_speed_law(points(0.5, (40.0,)))
    assert not one.kept and np.isnan(one.exponent) and "1 speed" in one.note
    data = points(0.5, (25.0, 150.0))
    with pytest.raises(ModelError, match="speed_mm_s"):
        fit_speed_law(Measurements(data.amplitude_um_pp, data.relative_friction, data.force_n, "no speeds"))
    with pytest.raises(ModelError, match="table"):
        fit_speed_law(data, "table")


def test_the_csv_s_speed_column_is_read_checked_and_splits_the_conditions(tmp_path):
    data = read_measurements(write_csv(tmp_path / "m.csv", points(0.5, (25.0, 150.0))))
    assert sorted(set(data.speed_mm_s.tolist())) == [25.0, 150.0]  # the same amplitudes at two speeds: allowed
    for bad, said in (("0", "speed_mm_s"), ("-3", "speed_mm_s"), ("2500", "speed_mm_s"), ("nan", "speed_mm_s")):
        text = (tmp_path / "m.csv").read_text().replace(",25\n", f",{bad}\n", 1)
        with pytest.raises(ModelError, match=said):
            read_measurements(write_text(tmp_path / "bad.csv", text))
    flat = "amplitude_um_pp,relative_friction,speed_mm_s\n0,1,25\n3,0.5,25\n6,0.2,25\n0,1,80\n3,1,80\n6,0.99,80\n"
    with pytest.raises(ModelError, match="at 80 mm/s does not fall"):
        read_measurements(write_text(tmp_path / "flat.csv", flat))
    twice = "amplitude_um_pp,relative_friction,speed_mm_s\n0,1,25\n3,0.5,25\n3.0000001,0.5,25\n6,0.2,25\n"
    with pytest.raises(ModelError, match="at 25 mm/s differ by less than"):
        read_measurements(write_text(tmp_path / "twice.csv", twice))


def write_text(path, text):
    path.write_text(text)
    return path


def test_a_table_model_takes_one_speed_only(tmp_path):
    path = write_csv(tmp_path / "m.csv", points(0.5, (25.0, 150.0)))
    line = assert_one_line_error(run_cli("model", "--model", f"table:{path}"))
    assert "a table holds one sliding speed" in line


def test_calibrate_writes_the_law_and_the_model_reads_it_back(tmp_path):
    """s = 0.5 at 25, 60 and 150 mm/s: the calibration's [speed] holds the fitted exponent, and the model it loads
    gives at 88 mm/s the stretched law at half the amplitude ((22 / 88)^0.5, by hand), within the fit's error."""
    path = write_csv(tmp_path / "m.csv", points(0.5, (25.0, 60.0, 150.0), noise=0.005))
    output = tmp_path / "p.toml"
    result = run_cli("calibrate", path, "-o", output, "--json", "--bootstrap", "0", check=True)
    summary = json.loads(result.stdout)["speed_law"]
    assert summary["kept"] and summary["interval"][0] <= 0.5 <= summary["interval"][1]
    assert summary["held_out_rms_with_law"] < summary["held_out_rms_without"]
    assert "[speed]" in output.read_text()
    model = load_model(str(output))
    assert abs(model.speed_law.exponent - 0.5) < 0.03
    assert "(fitted to 39 points at 25, 60 and 150 mm/s, 95 % interval" in model.describe()
    amplitude = np.linspace(0.0, 6.0, 25)
    np.testing.assert_allclose(model.relative_friction_at(amplitude, 0.5, 88.0),
                               STATIC.relative_friction(amplitude / 2.0, 0.5), atol=0.02)
    words = run_cli("calibrate", path, check=True).stdout
    assert "speed law: 3 speeds (25, 60 and 150 mm/s): the speed law is kept, s = 0.5" in words


def test_calibrate_keeps_no_law_where_speed_cannot_be_told(tmp_path):
    path = write_csv(tmp_path / "m.csv", points(0.0, (25.0, 150.0), seed=2))
    output = tmp_path / "p.toml"
    result = json.loads(run_cli("calibrate", path, "-o", output, "--json", "--bootstrap", "0", check=True).stdout)
    assert not result["speed_law"]["kept"] and "[speed]" not in output.read_text()
    assert load_model(str(output)).describe().find("sliding speed") == -1
    compared = json.loads(run_cli("calibrate", path, "--compare", "--json", check=True).stdout)  # a table ranked too
    assert compared["ranking"] and not compared["speed_law"]["kept"]


def test_a_simulated_finger_s_speed_law_is_recovered_from_two_on_plate_calibrations(tmp_path):
    """The simulated plate's finger with s = 0.5 (devices/sim/finger.py), calibrated on the plate at 25 and 150 mm/s:
    each session's points carry their speed, and the two files joined give s = 0.5 back."""
    joined = []
    for speed in (25, 150):
        output = tmp_path / f"p{speed}.toml"
        run_cli("calibrate", "--device", "sim", "--participant", "P1", "-o", output, "--no-window", "--json",
                "--forces", "0.5", "--passes", "1", "--step-ms", "200", "--finger-drift", "0", "--finger-moisture", "0",
                "--bootstrap", "0", "--finger", "speed:0.5:stretched", "--finger-speed-mm-s", str(speed),
                "--finger-force", "0.5", check=True)
        lines = output.with_suffix(".csv").read_text().splitlines()
        assert lines[0] == "amplitude_um_pp,relative_friction,force_n,speed_mm_s,participant"
        assert all(line.split(",")[3] == str(speed) for line in lines[1:])
        joined += lines[1:] if joined else lines
    both = write_text(tmp_path / "both.csv", "\n".join(joined) + "\n")
    summary = json.loads(run_cli("calibrate", both, "--json", "--bootstrap", "0", check=True).stdout)["speed_law"]
    assert summary["kept"] and abs(summary["exponent"] - 0.5) < 0.05, summary
