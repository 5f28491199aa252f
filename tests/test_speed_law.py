"""The settled reduction's speed law (render/physics/speed_law.py): a_eff = a (v_ref / max(v, 2 mm/s))^s, an
assumption exposed as a parameter, none by default; its exact inverse; how models are named and read with it."""

import math

import numpy as np
import pytest
from conftest import ROOT
from ultraglide.render.physics.calibration import load_model, read_calibration
from ultraglide.render.physics.dynamics import DynamicFrictionModel
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.friction_models import (
    ExponentialModel,
    PaperModel,
    StretchedExponentialModel,
    TableModel,
)
from ultraglide.render.physics.measurements import read_measurements
from ultraglide.render.physics.speed_law import SpeedLaw, SpeedLawModel, scaled_inverse, speed_law_of
from ultraglide.render.physics.squeeze_film import SqueezeFilmModel

STATICS = [StretchedExponentialModel(), ExponentialModel(), PaperModel(), SqueezeFilmModel(),
           TableModel(read_measurements(ROOT / "apps" / "data" / "monnoyer2018-fit.csv"))]
IDS = ["stretched", "exponential", "paper", "squeeze-film", "table"]


def test_at_four_times_the_reference_speed_with_s_one_half_the_effective_amplitude_halves():
    law = SpeedLaw(0.5)  # v_ref 22 mm/s
    assert law.amplitude_scale(88.0) == 2.0  # (88 / 22)^0.5 = sqrt(4)
    assert law.effective_amplitude_um_pp(4.0, 88.0) == 2.0
    assert law.effective_amplitude_um_pp(np.array([1.0, 3.0]), 88.0).tolist() == [0.5, 1.5]
    assert law.amplitude_scale(22.0) == 1.0
    assert SpeedLaw(1.0, reference_speed_mm_s=50.0).amplitude_scale(200.0) == 4.0


def test_slower_than_2_mm_s_is_held_at_2_mm_s_and_faster_than_2000_at_2000():
    law = SpeedLaw(1.0)
    assert law.amplitude_scale([0.0, 1.0, 2.0]).tolist() == [2.0 / 22.0] * 3
    assert law.one_scale(0.0) == law.one_scale(2.0) == 2.0 / 22.0
    assert law.one_scale(5000.0) == law.one_scale(math.inf) == 2000.0 / 22.0
    assert law.amplitude_scale(np.array([5000.0, np.inf, np.nan])).tolist() == [2000.0 / 22.0] * 2 + [1.0]
    assert law.one_scale(math.nan) == 1.0  # no speed known: the model as it is


def test_no_dependence_by_default_and_zero_counts_as_none():
    assert SpeedLaw().exponent == 0.0
    assert SpeedLaw().one_scale(500.0) == 1.0
    assert speed_law_of(StretchedExponentialModel()) is None
    assert speed_law_of(SpeedLawModel(StretchedExponentialModel(), SpeedLaw(0.0))) is None
    assert speed_law_of(SpeedLawModel(StretchedExponentialModel(), SpeedLaw(0.3))) == SpeedLaw(0.3)


@pytest.mark.parametrize("exponent", [-0.1, 1.01, math.nan, math.inf, True, "0.5"])
def test_an_exponent_outside_0_to_1_is_refused_in_one_line(exponent):
    with pytest.raises(ModelError, match="speed exponent") as caught:
        SpeedLaw(exponent)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("speed", [0.5, 1001.0])
def test_a_reference_speed_outside_1_to_1000_mm_s_is_refused(speed):
    with pytest.raises(ModelError, match="reference speed"):
        SpeedLaw(0.5, speed)


@pytest.mark.parametrize("static", STATICS, ids=IDS)
def test_the_forward_law_at_a_speed_is_the_static_law_at_the_effective_amplitude(static):
    model = SpeedLawModel(static, SpeedLaw(0.5))
    amplitude = np.linspace(0.0, 8.0, 17)
    halved = static.relative_friction(amplitude / 2, 0.5)
    assert np.array_equal(model.relative_friction_at(amplitude, 0.5, 88.0), halved)
    assert np.array_equal(model.relative_friction(amplitude, 0.5), static.relative_friction(amplitude, 0.5))
    per_sample = model.relative_friction_at(np.full(3, 4.0), 0.5, np.array([22.0, 88.0, 198.0]))
    expected = [static.relative_friction(4.0, 0.5), static.relative_friction(2.0, 0.5),
                static.relative_friction(4.0 / 3.0, 0.5)]  # (198 / 22)^0.5 = 3
    assert per_sample == pytest.approx(np.array(expected, dtype=float).reshape(-1), abs=1e-12)


@pytest.mark.parametrize("static", STATICS, ids=IDS)
def test_the_inverse_at_four_times_the_reference_speed_is_twice_the_static_inverse(static):
    model = SpeedLawModel(static, SpeedLaw(0.5))
    floor = float(static.floor_ratio(0.5, 5.0))  # reachable within 5 µm at v_ref: within 10 µm at 88 mm/s
    ratios = np.linspace(1.0, floor + 0.2 * (1.0 - floor), 9)
    at_reference = static.amplitude_um_pp(ratios, 0.5, 5.0)
    fast = model.amplitude_at(ratios, 0.5, 88.0, limit_um_pp=10.0)
    assert at_reference.clamped == fast.clamped == 0
    assert fast.amplitude_um_pp == pytest.approx(2.0 * at_reference.amplitude_um_pp, rel=1e-12, abs=1e-12)
    # and forward again at that speed gives the ratios asked
    assert model.relative_friction_at(fast.amplitude_um_pp, 0.5, 88.0) == pytest.approx(ratios, abs=1e-3)


def test_a_ratio_reachable_at_the_reference_speed_is_clipped_to_the_limit_at_a_high_speed_and_counted():
    static = StretchedExponentialModel()
    model = SpeedLawModel(static, SpeedLaw(0.5))
    limit = 6.0
    ratio = float(static.relative_friction(4.0, 0.5))  # 4 µm at v_ref: 8 µm at 88 mm/s, beyond the 6 µm limit
    slow = model.amplitude_at(np.array([ratio]), 0.5, 22.0, limit)
    fast = model.amplitude_at(np.array([ratio, 1.0]), 0.5, 88.0, limit)
    assert slow.clamped == 0 and slow.amplitude_um_pp[0] == pytest.approx(4.0, abs=1e-9)
    assert fast.clamped == 1
    assert fast.amplitude_um_pp.tolist() == [limit, 0.0]
    # the floor at 88 mm/s is the static floor at 3 µm, above the one at v_ref (6 µm): it rises with speed
    assert model.floor_at(0.5, 88.0, limit) == pytest.approx(float(static.relative_friction(3.0, 0.5)), abs=1e-12)
    assert model.floor_at(0.5, 88.0, limit) > model.floor_at(0.5, 22.0, limit) == static.floor_ratio(0.5, limit)


def test_the_scaled_inverse_never_exceeds_the_limit_and_writes_in_place():
    model = StretchedExponentialModel()
    ratios = np.linspace(0.05, 1.0, 200)
    out = np.empty(200)
    for scale in (0.1, 0.5, 1.7, 3.0, 40.0):
        result = scaled_inverse(model, ratios, 0.5, 6.0, scale, out)
        assert result.amplitude_um_pp is out
        assert out.max() <= 6.0 and out.min() >= 0.0
        # asked within a limit under 0.1 % inside 6 / scale (so its floor repeats across speeds): what it clamps is
        # what is out of reach at 6 / scale, and at most what is out of reach at 6 / (1.001 scale)
        exact = int(np.count_nonzero(ratios < float(model.floor_ratio(0.5, 6.0 / scale))))
        assert exact <= result.clamped <= int(np.count_nonzero(ratios < float(model.floor_ratio(0.5, 6.0 / scale
                                                                                                 / 1.001))))
        assert np.all(out[ratios < float(model.floor_ratio(0.5, 6.0 / scale))] == 6.0)


def test_s_zero_is_the_static_inverse_bit_for_bit():
    model = StretchedExponentialModel()
    ratios = np.linspace(0.1, 1.0, 50)
    assert np.array_equal(scaled_inverse(model, ratios, 0.5, 6.0, SpeedLaw(0.0).one_scale(300.0)).amplitude_um_pp,
                          model.amplitude_um_pp(ratios, 0.5, 6.0).amplitude_um_pp)


def test_describe_and_parameters_state_the_law_as_an_assumption():
    model = SpeedLawModel(StretchedExponentialModel(), SpeedLaw(0.5))
    assert model.describe().startswith(StretchedExponentialModel().describe())
    assert "a_eff = a (22 mm/s / v)^0.5 (assumed, ours)" in model.describe()
    parameters = model.parameters()
    assert parameters["reduction_speed_exponent"] == 0.5
    assert parameters["reduction_reference_speed_mm_s"] == 22.0
    assert parameters["shape"] == StretchedExponentialModel().shape


def test_the_command_lines_name_builds_the_law_around_any_model():
    model = load_model("speed:0.5:exponential")
    assert isinstance(model, SpeedLawModel) and isinstance(model.static, ExponentialModel)
    assert model.speed_law == SpeedLaw(0.5)
    dynamic = load_model("speed:0.25:dynamic")  # the dynamics stay outside, around the static model with the law
    assert isinstance(dynamic, DynamicFrictionModel) and isinstance(dynamic.static, SpeedLawModel)
    assert dynamic.speed_law == SpeedLaw(0.25)
    inside = load_model("dynamic:speed:1:stretched")
    assert isinstance(inside, DynamicFrictionModel) and inside.speed_law == SpeedLaw(1.0)
    assert "(assumed, ours)" in inside.describe()
    assert inside.parameters()["speed_exponent"] == 0.5  # the recovery's, beside the reduction's
    assert inside.parameters()["reduction_speed_exponent"] == 1.0


@pytest.mark.parametrize("spec, words", [("speed:2:stretched", "must lie in 0-1"),
                                         ("speed:-1:stretched", "must lie in 0-1"),
                                         ("speed:fast:stretched", "is not a number"),
                                         ("speed:0.5", "give speed:S:NAME"),
                                         ("speed:0.5:", "give speed:S:NAME"),
                                         ("speed:0.5:speed:0.5:stretched", "has a speed law already"),
                                         ("speed:0.5:nonsense", "unknown model")])
def test_a_bad_speed_model_name_is_refused_in_one_line(spec, words):
    with pytest.raises(ModelError, match=words) as caught:
        load_model(spec)
    assert "\n" not in str(caught.value)


def calibration(tmp_path, speed_table: str):
    path = tmp_path / "finger.toml"
    path.write_text('ultraglide_calibration = 1\nmodel = "exponential"\n' + speed_table
                    + "[parameters]\ntau_um_zp = 1.0\n", encoding="utf-8")
    return path


def test_a_calibration_files_speed_table_gives_the_law(tmp_path):
    model = read_calibration(calibration(tmp_path, "[speed]\nexponent = 0.5\nreference_speed_mm_s = 40\n"))
    assert isinstance(model, SpeedLawModel) and model.speed_law == SpeedLaw(0.5, 40.0)
    assert model.static.parameters()["tau_um_zp"] == 1.0
    assert "(40 mm/s / v)^0.5" in model.describe()
    assert isinstance(read_calibration(calibration(tmp_path, "[speed]\nexponent = 0\n")), ExponentialModel)
    assert isinstance(read_calibration(calibration(tmp_path, "")), ExponentialModel)


@pytest.mark.parametrize("table, words", [("[speed]\nexponent = 3\n", r"\[speed\] .*must lie in 0-1"),
                                          ("[speed]\nexponent = true\n", r"\[speed\] .*must be a number"),
                                          ("[speed]\nreference_speed_mm_s = 40\n", "needs exponent"),
                                          ("[speed]\nexponent = 0.5\nspeed = 3\n", "unknown key"),
                                          ("speed = 0.5\n", "must be a table")])
def test_a_bad_speed_table_is_refused_naming_the_file(tmp_path, table, words):
    path = calibration(tmp_path, table)
    with pytest.raises(ModelError, match=words) as caught:
        read_calibration(path)
    assert str(caught.value).startswith(str(path)) and "\n" not in str(caught.value)


@pytest.mark.parametrize("kind", ["stretched", "table"])
def test_the_floor_at_a_scaled_limit_is_evaluated_once_a_rung_not_once_a_speed(kind):
    """The block path asks within limit / k, a new k whenever the speed changes: after one pass over the speeds the
    static model is never evaluated forward again for its floor, and nothing exceeds the limit."""
    model = (StretchedExponentialModel() if kind == "stretched"
             else TableModel(read_measurements(ROOT / "apps" / "data" / "monnoyer2018-fit.csv")))
    law = SpeedLaw(1.0)
    calls = []
    forward = model.relative_friction
    ratios = np.linspace(0.05, 1.0, 60)
    out = np.empty(60)
    speeds = 2.0 * 1000.0 ** np.random.default_rng(7).random(300)  # 2-2000 mm/s, no two alike
    for speed in speeds:  # the warm-up: once over the speeds
        scaled_inverse(model, ratios, 0.5, 6.0, law.one_scale(speed), out)
    model.relative_friction = lambda *args: calls.append(args) or forward(*args)
    for speed in speeds + 1e-6:  # new floats for k, the same rungs (1e-6 mm/s moves k by far under 0.1 %)
        result = scaled_inverse(model, ratios, 0.5, 6.0, law.one_scale(speed), out)
        assert out.max() <= 6.0
        k = law.one_scale(speed)
        in_reach = ratios >= float(forward(6.0 / k / 1.001, 0.5)) + 1e-9
        assert forward(out[in_reach] / k, 0.5) == pytest.approx(ratios[in_reach], abs=1e-6)
        assert result.clamped >= int(np.count_nonzero(ratios < float(forward(6.0 / k, 0.5))))
    assert calls == []


def test_the_array_scale_is_taken_against_the_laws_own_reference_speed():
    """(v / v_ref)^s by hand at v_ref = 50 mm/s, s = 1: an array of speeds and one speed agree; NaN is the reference."""
    law = SpeedLaw(1.0, reference_speed_mm_s=50.0)
    assert law.amplitude_scale(np.array([200.0, 25.0, np.nan, 1.0])).tolist() == [4.0, 0.5, 1.0, 2.0 / 50.0]
    assert [law.amplitude_scale(v) for v in (200.0, 25.0)] == [4.0, 0.5]


def test_a_files_source_is_kept_and_said_to_be_the_files_not_ours(tmp_path):
    model = read_calibration(calibration(tmp_path, '[speed]\nexponent = 0.5\nsource = "sweeps on my plate"\n'))
    assert model.describe().endswith("a_eff = a (22 mm/s / v)^0.5 (given, not ours: sweeps on my plate)")
    assert "assumed, ours" not in model.describe()
