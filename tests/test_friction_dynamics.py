"""The dynamic friction model: asymmetric first-order onset and recovery, against the analytic step response."""

import json
import math

import numpy as np
import pytest
from ultraglide.render.physics.dynamics import DynamicFrictionModel, FrictionDynamics
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.friction_models import ExponentialModel, StretchedExponentialModel

import ultraglide

RATE = 12000.0


def test_a_fall_reaches_63_percent_at_the_onset_time_constant():
    felt = FrictionDynamics().respond(np.zeros(600), RATE, 22.0, felt=1.0)
    at_tau = int(round(0.005 * RATE)) - 1  # out[i] is the ratio at the end of sample i: t = (i + 1) / rate
    assert felt[at_tau] == pytest.approx(math.exp(-1.0), rel=1e-12)  # 1 - 63.2 % of the way down
    assert felt[2 * int(0.005 * RATE) - 1] == pytest.approx(math.exp(-2.0), rel=1e-12)


def test_a_rise_takes_the_recovery_time_constant_at_the_reference_speed():
    felt = FrictionDynamics().respond(np.ones(2400), RATE, 22.0, felt=0.3)
    at_tau = int(round(0.070 * RATE)) - 1
    assert felt[at_tau] == pytest.approx(0.3 + 0.7 * (1 - math.exp(-1.0)), rel=1e-12)


def test_recovery_is_slower_than_onset_and_slower_when_sliding_slower():
    dynamics = FrictionDynamics()
    down = dynamics.respond(np.full(120, 0.3), RATE, 22.0, felt=1.0)
    up = dynamics.respond(np.ones(120), RATE, 22.0, felt=0.3)
    # after 10 ms: 0.7 (1 - e^-2) = 0.605 of the way down, 0.7 (1 - e^(-1/7)) = 0.093 up: 6.5 times less
    assert 1.0 - down[-1] == pytest.approx(0.7 * (1 - math.exp(-2.0)), rel=1e-12)
    assert up[-1] - 0.3 == pytest.approx(0.7 * (1 - math.exp(-10 / 70)), rel=1e-12)
    # (v_ref / v)^0.5: four times the speed, half the time constant (35 ms at 88 mm/s)
    assert dynamics.recovery_at_s(88.0) == pytest.approx(0.035, rel=1e-12)
    fast = dynamics.respond(np.ones(1200), RATE, 88.0, felt=0.0)
    assert fast[int(round(0.035 * RATE)) - 1] == pytest.approx(1 - math.exp(-1.0), rel=1e-12)
    slow = dynamics.respond(np.ones(1200), RATE, 5.0, felt=0.0)
    assert slow[-1] < fast[-1]
    # a per-sample speed gives what one speed gives
    assert dynamics.respond(np.ones(1200), RATE, np.full(1200, 88.0), felt=0.0) == pytest.approx(fast, rel=1e-15)


def test_the_speed_law_is_exposed_and_zero_means_no_dependence():
    flat = FrictionDynamics(speed_exponent=0.0)
    assert flat.recovery_at_s(5.0) == flat.recovery_at_s(500.0) == 0.07
    distance = FrictionDynamics(speed_exponent=1.0)  # a fixed sliding distance: 70 ms x 22 mm/s = 1.54 mm
    assert distance.recovery_at_s(154.0) * 154.0 == pytest.approx(1.54, rel=1e-12)
    assert "assumed" in FrictionDynamics().describe() and "Meyer" in FrictionDynamics().describe()


@pytest.mark.parametrize("field, value", [("onset_s", 0.0), ("onset_s", 1.0), ("recovery_s", math.nan),
                                          ("speed_exponent", -1.0), ("reference_speed_mm_s", 0.0)])
def test_parameters_outside_their_range_are_refused_with_the_range(field, value):
    with pytest.raises(ModelError, match="must lie in"):
        FrictionDynamics(**{field: value})


def test_the_dynamic_model_settles_on_its_static_model():
    model = DynamicFrictionModel(StretchedExponentialModel())
    amplitude = np.r_[np.zeros(12), np.full(2400, 4.0)]
    felt = model.felt(amplitude, RATE, 0.5, 100.0)
    assert felt[-1] == pytest.approx(float(StretchedExponentialModel().relative_friction(4.0, 0.5)), abs=1e-9)
    assert felt[0] == 1.0 and felt[20] > felt[-1]  # it lags: not there at once
    inverse = model.amplitude_um_pp(np.array([0.5, 0.01]), 0.5, 6.0)
    static = StretchedExponentialModel().amplitude_um_pp(np.array([0.5, 0.01]), 0.5, 6.0)
    assert inverse.amplitude_um_pp.tolist() == static.amplitude_um_pp.tolist() and inverse.clamped == 1


def test_dynamic_models_load_by_name():
    assert isinstance(ultraglide.load_model("dynamic").static, StretchedExponentialModel)
    # the public API names them, as it names the static models
    assert isinstance(ultraglide.load_model("dynamic"), ultraglide.DynamicFrictionModel)
    assert ultraglide.load_model("dynamic").dynamics == ultraglide.FrictionDynamics()
    assert isinstance(ultraglide.load_model("speed:0.5:stretched"), ultraglide.SpeedLawModel)
    assert ultraglide.load_model("speed:0.5:stretched").speed_law == ultraglide.SpeedLaw(0.5)
    assert isinstance(ultraglide.load_model("dynamic:exponential").static, ExponentialModel)
    assert "in time: onset 5 ms" in ultraglide.load_model("dynamic").describe()
    with pytest.raises(ModelError, match="wraps a static one"):
        ultraglide.load_model("dynamic:dynamic")
    # a speed law around a dynamic model has the published dynamics, not a finger's fitted ones: said so
    with pytest.raises(ModelError) as error:
        ultraglide.load_model("dynamic:speed:0.5:dynamic")
    assert str(error.value) == ("speed:0.5:dynamic has friction dynamics already (the published ones): give --model "
                                "speed:0.5:dynamic (dynamic: adds the published ones to a static model)")


def test_the_model_command_says_the_dynamics_and_what_a_grating_keeps():
    from conftest import run_cli

    result = json.loads(run_cli("model", "--model", "dynamic", "--json", check=True).stdout)
    dynamics = result["dynamics"]
    assert dynamics["onset_s"] == 0.005 and dynamics["recovery_s"] == 0.07
    assert dynamics["recovery_s_at_mm_s"]["100"] == pytest.approx(0.07 * (22 / 100) ** 0.5, rel=1e-12)
    for grating in dynamics["grating_1mm"]:  # 100 Hz and more of modulation: the finger keeps little of it
        assert grating["contrast_instantaneous"] < 0.3
        assert grating["rms_planned"] < grating["rms_instantaneous"]
    assert "in time: onset 5 ms" in result["model"]
