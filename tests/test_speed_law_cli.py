"""The settled speed law on the command line: ``--model speed:S:NAME`` and ``model --speed-mm-s``."""

import json
import math

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from ultraglide.render.physics.friction_models import StretchedExponentialModel

STATIC = StretchedExponentialModel()


def test_model_prints_the_curve_and_the_amplitude_for_a_ratio_at_a_speed():
    data = json.loads(run_cli("model", "--model", "speed:0.5:stretched", "--speed-mm-s", "88", "--ratio", "0.5",
                              "--json", check=True).stdout)
    assert data["speed_mm_s"] == 88.0 and data["amplitude_scale"] == 2.0
    assert "(assumed, ours)" in data["model"] and "(assumed, ours)" in data["speed_law"]
    for amplitude, ratio in data["curve"]:
        assert ratio == pytest.approx(float(STATIC.relative_friction(amplitude / 2.0, 0.5)), abs=1e-6)
    at_reference = float(STATIC.amplitude_um_pp(0.5, 0.5).amplitude_um_pp)
    assert data["amplitude_for_ratio_um_pp"] == pytest.approx(2.0 * at_reference, rel=1e-9)
    text = run_cli("model", "--model", "speed:0.5:stretched", "--speed-mm-s", "88", check=True).stdout
    assert "sliding at 88 mm/s" in text and "needs 2 x the amplitude" in text and "held" not in text


def test_model_at_a_speed_says_the_floor_there():
    # the default law within its 20 µm p-p at 200 mm/s under s = 0.5: the static law at 20 (22 / 200)^0.5 µm p-p
    amplitude = 20.0 * (22.0 / 200.0) ** 0.5
    floor = 0.1 + 0.9 * math.exp(-((amplitude / (2 * math.sqrt(2) * 1.32)) ** 2))  # 0.138, by hand
    text = run_cli("model", "--model", "speed:0.5:stretched", "--speed-mm-s", "200", check=True).stdout
    assert f"lowest friction within 20 µm p-p at 200 mm/s: {floor:.3f}" in text
    data = json.loads(run_cli("model", "--model", "speed:0.5:stretched", "--speed-mm-s", "200", "--json",
                              check=True).stdout)
    assert data["lowest_reachable_ratio"] == pytest.approx(floor, rel=1e-3) and data["amplitude_ceiling_um_pp"] == 20


def test_model_at_a_speed_below_2_mm_s_says_it_is_held_at_2():
    text = run_cli("model", "--model", "speed:0.5:stretched", "--speed-mm-s", "0", check=True).stdout
    assert "sliding at 0 mm/s (held at 2 mm/s)" in text
    assert f"needs {(2.0 / 22.0) ** 0.5:.3g} x the amplitude" in text  # (2 / 22)^0.5 by hand


def test_a_model_without_a_law_gives_the_same_curve_at_any_speed():
    plain = json.loads(run_cli("model", "--model", "stretched", "--json", check=True).stdout)
    fast = json.loads(run_cli("model", "--model", "stretched", "--speed-mm-s", "500", "--json", check=True).stdout)
    assert fast["curve"] == plain["curve"] and fast["speed_law"].startswith("no dependence")


@pytest.mark.parametrize("args, words", [(("--model", "speed:1.5:stretched"), "must lie in 0-1"),
                                         (("--model", "speed:x:stretched"), "is not a number"),
                                         (("--speed-mm-s", "-3"), "--speed-mm-s"),
                                         (("--speed-mm-s", "9000"), "--speed-mm-s")])
def test_a_bad_speed_law_or_speed_is_one_line_and_exit_2(args, words):
    result = run_cli("model", *args)
    assert result.returncode == 2 and result.stdout == ""
    assert words in assert_one_line_error(result)


def test_export_refuses_a_bad_speed_law_before_it_writes_anything(tmp_path):
    result = run_cli("export", "grating-1mm", "--model", "speed:2:stretched", "-o", tmp_path / "out.wav")
    assert result.returncode == 2 and not (tmp_path / "out.wav").exists()
    assert "speed exponent" in assert_one_line_error(result)


@pytest.mark.parametrize("speed_mm_s, scale", [(22.0, 1.0), (88.0, 2.0)])
def test_export_inverts_at_the_swipes_speed_through_the_block_that_ends_the_stroke(tmp_path, speed_mm_s, scale):
    # a 0.5 s swipe is one of export's second-long blocks with the lift after it: the law's scale is the swipe's
    # (22 / 22)^0.5 = 1 and (88 / 22)^0.5 = 2 by hand, not that of a mean speed slowed by the samples after the lift
    envelope = tmp_path / "envelope.csv"
    run_cli("export", "grating-2mm", "-o", tmp_path / "out.wav", "--duration-s", "0.5", "--speed-mm-s", speed_mm_s,
            "--model", "speed:0.5:stretched", "--envelope-csv", envelope, check=True)
    rows = np.genfromtxt(envelope, delimiter=",", names=True)
    within = (rows["down"] == 1) & (rows["target_ratio"] > 0.6) & (rows["target_ratio"] < 0.95)  # within 6 µm at 88
    static = STATIC.amplitude_um_pp(rows["target_ratio"][within], 0.5, 6.0).amplitude_um_pp
    assert within.sum() > 1000
    np.testing.assert_allclose(rows["target_um_pp"][within], scale * static, rtol=1e-4)
