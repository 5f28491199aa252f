"""Calibration: least squares, uncertainties and cross-validation against independent computations;
the typed calibration-file loader under random input."""

import math

import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import curve_fit
from ultraglide.render.physics.calibration import (
    PARAMETERS,
    calibration_toml,
    compare_models,
    cross_validation_errors,
    fit_model,
    read_calibration,
)
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.friction_models import PaperModel, StretchedExponentialModel
from ultraglide.render.physics.measurements import Measurements, read_measurements

SHARED_DATA = "apps/data/monnoyer2018-fit.csv"
FORCES = (0.2, 0.5, 1.0)
AMPLITUDES = np.linspace(0.0, 7.0, 12)


def synthetic(truth, noise=0.01, seed=1, forces=FORCES, amplitudes=AMPLITUDES) -> Measurements:
    rng = np.random.default_rng(seed)
    amplitude = np.tile(amplitudes, len(forces))
    force = np.repeat(forces, len(amplitudes))
    ratio = truth.relative_friction(amplitude, force) + rng.normal(0.0, noise, len(amplitude))
    return Measurements(amplitude, np.clip(ratio, 0.005, 1.1), force, "synthetic")


def exponential(a_pp, tau):
    return np.exp(-((a_pp / 2) ** 2) / (2 * tau**2))


def test_fit_and_standard_error_agree_with_scipy_curve_fit():
    data = synthetic(StretchedExponentialModel(3.2, 2.0, 0.0), noise=0.02, forces=(0.5,))
    fit = fit_model(data, "exponential", hold={"residual_ratio": 0.0})  # Monnoyer's law, without a floor
    (tau,), covariance = curve_fit(exponential, data.amplitude_um_pp, data.relative_friction, p0=[1.3])
    assert fit.model.tau_um_zp == pytest.approx(tau, rel=1e-5)
    assert fit.parameters[0].stderr == pytest.approx(math.sqrt(covariance[0, 0]), rel=1e-3)


def test_leave_one_out_agrees_with_a_hand_computation():
    amplitude = np.linspace(0.0, 6.0, 9)  # fewer than 10 points: k-fold becomes leave-one-out
    rng = np.random.default_rng(7)
    ratio = exponential(amplitude, 1.1) + rng.normal(0, 0.02, 9)
    data = Measurements(amplitude, ratio, None, "nine points")
    held_out = []
    for i in range(9):
        keep = np.arange(9) != i
        (tau,), _ = curve_fit(exponential, amplitude[keep], ratio[keep], p0=[1.3])
        held_out.append(ratio[i] - exponential(amplitude[i], tau))
    expected = math.sqrt(np.mean(np.square(held_out)))
    assert cross_validation_errors(data, "exponential", hold={"residual_ratio": 0.0})["k_fold"] == pytest.approx(
        expected, rel=1e-4)


@pytest.mark.parametrize("kind, values", [
    ("stretched", {"scale_um_pp": 3.1, "shape": 1.7, "force_exponent": 0.45, "residual_ratio": 0.12}),
    ("stretched", {"scale_um_pp": 5.0, "shape": 0.6, "force_exponent": -0.3, "residual_ratio": 0.0}),
    ("exponential", {"tau_um_zp": 1.2, "residual_ratio": 0.05}),
])
def test_the_fits_closed_form_law_is_the_models_and_its_jacobian_the_derivative(kind, values):
    from ultraglide.render.physics.fitting import _EmpiricalLaw
    from ultraglide.render.physics.model_parameters import build_model

    amplitude = np.array([0.0, 0.3, 1.0, 2.5, 4.0, 7.0, 0.0, 3.0, 12.0])
    force = np.array([0.5, 0.5, 0.2, 0.2, 1.0, 1.0, 3.0, 0.004, 12.0])  # and forces the model clips
    data = Measurements(amplitude, np.linspace(1.0, 0.1, 9), force, "points")
    keys = list(values)

    def values_of(x):
        return {**{"force_exponent": 1 / 3}, **dict(zip(keys, map(float, x), strict=True))}

    law = _EmpiricalLaw(kind, data, keys, values_of)
    x = np.array([values[k] for k in keys])
    model = build_model(kind, values)
    model._range_said = True
    assert law.prediction(x) == pytest.approx(model.relative_friction(amplitude, force), rel=1e-13, abs=1e-15)
    numeric = np.column_stack([(law.residual(x + step) - law.residual(x - step)) / (2 * 1e-6)
                               for step in np.eye(len(x)) * 1e-6])
    assert law.jacobian(x) == pytest.approx(numeric, abs=1e-7)


def test_multi_force_fit_recovers_the_force_law_within_its_uncertainty():
    truth = StretchedExponentialModel(3.5, 1.6, 0.45)
    fit = fit_model(synthetic(truth), "stretched", cross_validate=True)
    for p in fit.parameters:
        assert not p.fixed and 0 < p.stderr < 0.2
        assert abs(p.value - getattr(truth, p.spec.key)) < 4 * p.stderr
    # noise of 0.01 is what a right model leaves, in sample and out of it
    assert 0.006 < fit.rms_residual < 0.014
    assert fit.cross_validation["k_fold"] < 0.015
    assert fit.cross_validation["leave_one_force_out"] < 0.02
    assert fit.warnings() == []


def test_one_force_holds_the_force_exponent_and_says_so():
    fit = fit_model(read_measurements(SHARED_DATA), "stretched")
    held = {p.spec.key: p for p in fit.parameters}["force_exponent"]
    assert held.fixed and math.isnan(held.stderr) and held.value == pytest.approx(1 / 3)
    # the bundled curve is Monnoyer's Gaussian law: the shape comes back as 2, the scale as 2 √2 × 1.32 µm
    values = fit.model.parameters()
    assert values["shape"] == pytest.approx(2.0, abs=2e-3)
    assert values["scale_um_pp"] == pytest.approx(2 * math.sqrt(2) * 1.32, rel=1e-3)


def test_a_force_blind_model_cannot_predict_another_force():
    data = synthetic(StretchedExponentialModel(3.5, 2.0, 0.5))
    exponential_fit = fit_model(data, "exponential", cross_validate=True)
    stretched_fit = fit_model(data, "stretched", cross_validate=True)
    # the scale differs by (1/0.5)^0.5 = 1.41 between 0.5 N and 1 N: ignoring it costs > 0.1 in ratio
    assert exponential_fit.cross_validation["leave_one_force_out"] > 0.1
    assert stretched_fit.cross_validation["leave_one_force_out"] < 0.03


def test_compare_ranks_the_model_that_made_the_data_first():
    ranking = compare_models(synthetic(StretchedExponentialModel(3.0, 1.3, 0.4)),
                             kinds=("exponential", "stretched", "table"))
    assert [f.kind for f in ranking][0] == "stretched"
    paper_data = synthetic(PaperModel(), noise=0.005, amplitudes=np.linspace(0.0, 9.0, 10))
    ranking = compare_models(paper_data, kinds=("exponential", "stretched", "paper"))
    assert ranking[0].kind == "paper"
    assert ranking[0].warnings() == []


def test_paper_model_leaving_its_physics_is_named():
    fit = fit_model(read_measurements(SHARED_DATA), "paper")
    n = {p.spec.key: p for p in fit.parameters}["friction_exponent"]
    assert n.value < 0.5  # the measured fall is far steeper than non-Coulombic friction alone gives
    warnings = fit.warnings()
    assert len(warnings) == 1 and warnings[0].startswith("friction_exponent = ")
    assert "\n" not in warnings[0]


def test_calibration_file_keeps_the_fit_and_reads_back(tmp_path):
    data = synthetic(StretchedExponentialModel(3.5, 1.6, 0.45))
    fit = fit_model(data, "stretched", cross_validate=True)
    path = tmp_path / "cal.toml"
    path.write_text(calibration_toml(fit))
    model = read_calibration(path)
    amplitude = np.linspace(0, 8, 17)
    for force in FORCES:
        assert model.relative_friction(amplitude, force) == pytest.approx(fit.model.relative_friction(amplitude, force))
    assert "leave_one_force_out" in path.read_text()


@pytest.mark.parametrize("model, parameters, fragment", [
    ("stretched", {"scale_um_pp": 0.0, "shape": 2.0}, "scale_um_pp = 0.0 is outside the allowed range [0.05, 100]"),
    ("stretched", {"scale_um_pp": math.inf, "shape": 2.0}, "scale_um_pp = inf is outside the allowed range"),
    ("stretched", {"scale_um_pp": 3.0, "shape": 0.0}, "shape = 0.0 is outside the allowed range [0.3, 8]"),
    ("stretched", {"scale_um_pp": 3.0}, "parameter shape is missing (allowed range [0.3, 8])"),
    ("exponential", {"tau_um_zp": "1.3"}, "parameter tau_um_zp must be a number"),
    ("exponential", {"tau_um_zp": 1.3, "tau": 1.0}, "unknown parameter tau for the exponential model"),
    ("paper", {"youngs_modulus_pa": 1e6, "friction_exponent": 0.0}, "friction_exponent = 0.0 is outside"),
])
def test_bad_calibration_files_name_the_key_and_range(tmp_path, model, parameters, fragment):
    path = tmp_path / "cal.toml"
    path.write_text(tomli_w.dumps({"ultraglide_calibration": 1, "model": model, "parameters": parameters}))
    with pytest.raises(ModelError) as error:
        read_calibration(path)
    assert fragment in str(error.value) and "\n" not in str(error.value)


values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6), st.booleans(),
                   st.text(max_size=5))


@settings(max_examples=150, deadline=None)
@given(model=st.sampled_from(sorted(PARAMETERS)), data=st.data())
def test_calibration_loader_refuses_or_gives_a_sound_model(tmp_path_factory, model, data):
    keys = [s.key for s in PARAMETERS[model]]
    chosen = data.draw(st.dictionaries(st.sampled_from([*keys, "extra"]), values, max_size=4))
    # half the time, in-range numbers for every key, so that the success path is exercised too
    if data.draw(st.booleans()):
        chosen = {s.key: data.draw(st.floats(s.low, s.high)) for s in PARAMETERS[model]}
    path = tmp_path_factory.mktemp("cal") / "cal.toml"
    path.write_text(tomli_w.dumps({"ultraglide_calibration": 1, "model": model, "parameters": chosen}))
    try:
        loaded = read_calibration(path)
    except ModelError as error:
        message = str(error)
        assert "\n" not in message
        assert any(key in message for key in [*keys, "extra"]) or "must" in message
        return
    for spec in PARAMETERS[model]:
        value = chosen.get(spec.key, spec.default)
        assert spec.low <= value <= spec.high
    amplitude = np.linspace(0.0, 20.0, 101)
    for force in (0.1, 0.5, 2.0):
        curve = loaded.relative_friction(amplitude, force)
        assert np.all(np.isfinite(curve)) and np.all(np.diff(curve) <= 1e-12)
        floor = float(loaded.floor_ratio(force, 10.0))
        ratio = np.linspace(floor, 1.0, 50)
        inverse = loaded.amplitude_um_pp(ratio, force, 10.0).amplitude_um_pp
        assert np.all(np.diff(inverse) <= 1e-9)
        assert np.max(np.abs(loaded.relative_friction(inverse, force) - ratio)) <= 1e-3


def test_a_parameter_pushed_to_its_bound_is_named():
    amplitude = np.linspace(0.0, 6.0, 25)
    ratio = np.exp(-((amplitude / 3.0) ** 14))  # a fall far sharper than any allowed shape (at most 8)
    fit = fit_model(Measurements(amplitude, ratio, None, "cliff"), "stretched")
    assert {p.spec.key: p for p in fit.parameters}["shape"].value == pytest.approx(8.0, rel=1e-3)
    assert [w.split(" = ")[0] for w in fit.warnings()] == ["shape"]
    assert "sits at the bound 8" in fit.warnings()[0]


def test_participants_are_cross_validated_and_selectable(tmp_path):
    rng = np.random.default_rng(11)
    rows = ["amplitude_um_pp,relative_friction,force_n,participant"]
    for participant, scale in (("P01", 3.0), ("7.0", 4.5)):  # two fingers: one slips sooner than the other
        for a in np.linspace(0, 6, 10):
            rows.append(f"{a:.2f},{np.exp(-(a / scale) ** 2) + rng.normal(0, 0.005):.5f},0.5,{participant}")
    path = tmp_path / "two-fingers.csv"
    path.write_text("\n".join(rows) + "\n")
    data = read_measurements(path)
    errors = cross_validation_errors(data, "stretched")
    # independently: fit each finger with curve_fit and predict the other one
    held_out = []
    assert sorted(set(data.participant)) == ["7", "P01"]  # ids kept as text; a number however written
    for participant in ("P01", "7"):
        train, test = data.participant != participant, data.participant == participant
        (scale, shape), _ = curve_fit(lambda a, s, b: np.exp(-((a / s) ** b)), data.amplitude_um_pp[train],
                                      data.relative_friction[train], p0=[3.7, 2.0])
        held_out += list(data.relative_friction[test] - np.exp(-((data.amplitude_um_pp[test] / scale) ** shape)))
    assert errors["leave_one_participant_out"] == pytest.approx(math.sqrt(np.mean(np.square(held_out))), rel=1e-4)
    one = fit_model(data.subset(data.participant == "7"), "stretched")
    assert one.model.scale_um_pp == pytest.approx(4.5, rel=0.02)
