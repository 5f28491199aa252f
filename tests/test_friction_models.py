"""Friction models: forward against the physics, and the inverse's contract under random input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ultraglide.render.physics.calibration import calibration_toml, fit_model, load_model, read_calibration
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import FingerParams
from ultraglide.render.physics.friction_models import (
    ExponentialModel,
    PaperModel,
    StretchedExponentialModel,
    TableModel,
)
from ultraglide.render.physics.measurements import Measurements, read_measurements
from ultraglide.render.physics.normal_contact import relative_friction

SHARED_DATA = "apps/data/monnoyer2018-fit.csv"
MODELS = {
    "paper": PaperModel(),
    "paper-uniform": PaperModel(FingerParams(contact="uniform")),
    "exponential": ExponentialModel(),
    "stretched": StretchedExponentialModel(),
    "table": TableModel(read_measurements(SHARED_DATA)),
}


def test_exponential_law_by_hand():
    model = ExponentialModel(1.32)
    # a_zp = tau sqrt(2) gives exp(-1); peak-to-peak is twice that: 2 × 1.32 × 1.41421 = 3.7335 µm
    assert model.relative_friction(3.7335) == pytest.approx(np.exp(-1), rel=1e-4)
    assert model.amplitude_um_pp(np.exp(-1)).amplitude_um_pp == pytest.approx(3.7335, rel=1e-4)


def test_exponential_reproduces_the_published_fit_points():
    data = read_measurements(SHARED_DATA)
    assert ExponentialModel().relative_friction(data.amplitude_um_pp) == pytest.approx(
        data.relative_friction, abs=1e-4)


def test_paper_model_table_matches_direct_integration():
    amplitude = np.linspace(0, 15, 61)
    for force in (0.1, 0.5, 2.0):
        expected = relative_friction(amplitude, force)
        assert MODELS["paper"].relative_friction(amplitude, force) == pytest.approx(expected, abs=1e-3)


def test_table_model_passes_through_its_points():
    data = read_measurements(SHARED_DATA)
    assert MODELS["table"].relative_friction(data.amplitude_um_pp) == pytest.approx(
        data.relative_friction, abs=1e-6)


def test_table_model_makes_noisy_data_monotone():
    data = Measurements(np.array([0, 1, 2, 3, 4.0]), np.array([1, 0.9, 0.93, 0.6, 0.5]), None, "noisy")
    model = TableModel(data)
    curve = model.relative_friction(np.linspace(0, 4, 200))
    assert np.all(np.diff(curve) <= 1e-12)
    assert model.relative_friction(1.5) == pytest.approx(0.915, abs=1e-3)  # pooled 0.9 and 0.93


def test_table_model_interpolates_between_forces():
    amplitude = np.array([0, 2, 4, 6.0] * 2)
    ratio = np.array([1, 0.8, 0.6, 0.4, 1, 0.9, 0.8, 0.7])
    force = np.array([0.2] * 4 + [0.6] * 4)
    model = TableModel(Measurements(amplitude, ratio, force, "two forces"))
    # ratio 0.8 needs 4 µm at 0.2 N and 2 µm at 0.6 N; at 0.4 N halfway: 3 µm
    assert model.amplitude_um_pp(0.8, 0.4).amplitude_um_pp == pytest.approx(3.0, abs=1e-3)
    assert model.relative_friction(3.0, 0.4) == pytest.approx(0.8, abs=1e-3)


@pytest.mark.parametrize("name", MODELS)
def test_inverse_is_exact_monotone_and_finite_over_the_reachable_range(name):
    model = MODELS[name]
    for force in (0.2, 0.5, 1.0):
        floor = float(model.floor_ratio(force, 6.0))
        ratio = np.linspace(floor, 1.0, 20001)
        result = model.amplitude_um_pp(ratio, force, 6.0)
        assert result.clamped == 0
        amplitude = result.amplitude_um_pp
        assert np.all(np.isfinite(amplitude))
        assert np.all(np.diff(amplitude) <= 1e-12)  # higher ratio, less vibration
        assert np.max(np.abs(model.relative_friction(amplitude, force) - ratio)) <= 1e-3


@settings(max_examples=200, deadline=None)
@given(
    name=st.sampled_from(sorted(MODELS)),
    ratio=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1, max_size=50),
    force=st.floats(min_value=0.0, max_value=20.0),
    limit=st.floats(min_value=0.0, max_value=30.0),
)
def test_inverse_never_exceeds_the_limit_and_counts_what_it_clamps(name, ratio, force, limit):
    model = MODELS[name]
    if not all(0 <= r < np.inf for r in ratio):  # NaN, infinite or negative: refused in one line
        with pytest.raises(ModelError, match="friction ratio must be a finite number >= 0"):
            model.amplitude_um_pp(np.array(ratio), force, limit)
        return
    result = model.amplitude_um_pp(np.array(ratio), force, limit)
    amplitude = result.amplitude_um_pp
    assert amplitude.shape == (len(ratio),)
    assert np.all(np.isfinite(amplitude))
    assert np.all((amplitude >= 0) & (amplitude <= limit))
    floor = model.floor_ratio(force, limit)
    expected = sum(1 for r in ratio if r < floor)  # NaN compares false: rest, not clamped
    assert result.clamped == expected


def test_ratio_below_reach_clamps_to_the_limit():
    result = MODELS["paper"].amplitude_um_pp([0.1, 0.95], 0.5, limit_um_pp=6.0)
    assert result.clamped == 1
    assert result.amplitude_um_pp[0] == 6.0
    assert 0 < result.amplitude_um_pp[1] < 6.0


def test_ratio_above_one_means_rest():
    assert MODELS["exponential"].amplitude_um_pp([1.2], 0.5, 5.0).amplitude_um_pp[0] == 0.0


def test_calibration_recovers_known_parameters(tmp_path):
    amplitude = np.linspace(0, 6, 13)
    truth = ExponentialModel(0.9)
    data = Measurements(amplitude, truth.relative_friction(amplitude), None, "synthetic")
    fit = fit_model(data, "exponential")
    assert fit.model.tau_um_zp == pytest.approx(0.9, rel=1e-4)
    truth_paper = PaperModel(FingerParams(youngs_modulus_pa=2.0e6, friction_exponent=0.5))
    forces = np.full(13, 0.4)
    data = Measurements(amplitude, truth_paper.relative_friction(amplitude, forces), forces, "synthetic")
    fit = fit_model(data, "paper")
    assert fit.model.params.youngs_modulus_pa == pytest.approx(2.0e6, rel=0.02)
    assert fit.model.params.friction_exponent == pytest.approx(0.5, abs=0.01)
    path = tmp_path / "cal.toml"
    path.write_text(calibration_toml(fit))
    again = read_calibration(path)
    assert again.relative_friction(amplitude, 0.4) == pytest.approx(fit.model.relative_friction(amplitude, 0.4))
    assert load_model(str(path)).describe() == again.describe()


@pytest.mark.parametrize("content, message", [
    ("amplitude_um_pp,force_n\n1,0.5\n", "missing column relative_friction"),
    ("amplitude_um_pp,relative_friction\n1,abc\n2,0.5\n", "not a number"),
    ("# only a comment\n", "no data"),
    ("amplitude_um_pp,relative_friction\n1,0.9\n", "at least two"),
    ("amplitude_um_pp,relative_friction\n-1,0.9\n2,0.5\n", "must not be negative"),
])
def test_bad_measurement_files_say_what_is_wrong(tmp_path, content, message):
    path = tmp_path / "data.csv"
    path.write_text(content)
    with pytest.raises(ModelError, match=message):
        read_measurements(path)


def test_bad_model_specs_say_what_is_wrong(tmp_path):
    with pytest.raises(ModelError, match="unknown model"):
        load_model("levitation")
    (tmp_path / "x.toml").write_text("model = 'paper'\n")
    with pytest.raises(ModelError, match="calibration file"):
        load_model(str(tmp_path / "x.toml"))


# ---- the force-aware model, forces per sample, checks at the edge ------------------------------------------


def test_stretched_model_by_hand():
    model = StretchedExponentialModel(scale_um_pp=3.0, shape=1.5, force_exponent=0.5)
    for force in (0.2, 0.5, 1.0):
        scale = 3.0 * (force / 0.5) ** 0.5  # the 1/e amplitude at this force
        assert model.relative_friction(scale, force) == pytest.approx(np.exp(-1), rel=1e-12)
        half = scale * np.log(2) ** (1 / 1.5)  # exp(-(a/s)^1.5) = 1/2
        assert model.amplitude_um_pp(np.array([0.5]), force).amplitude_um_pp[0] == pytest.approx(half, rel=1e-12)


def test_stretched_defaults_are_the_published_curve_at_half_a_newton():
    data = read_measurements(SHARED_DATA)
    assert StretchedExponentialModel().relative_friction(data.amplitude_um_pp, 0.5) == pytest.approx(
        data.relative_friction, abs=1e-4)
    # harder presses need more vibration for the same reduction: s grows as F^(1/3)
    model = StretchedExponentialModel()
    a1 = model.amplitude_um_pp(np.array([0.5]), 0.2).amplitude_um_pp[0]
    a2 = model.amplitude_um_pp(np.array([0.5]), 1.6).amplitude_um_pp[0]
    assert a2 / a1 == pytest.approx(8 ** (1 / 3), rel=1e-12)


def test_paper_model_area_law_is_a_parameter():
    amplitude = np.linspace(0, 8, 9)
    flat = PaperModel(FingerParams(area_exponent=1.0))  # A ∝ F: W_c = F / k_n does not depend on F
    assert flat.relative_friction(amplitude, 0.2) == pytest.approx(flat.relative_friction(amplitude, 1.0), abs=1e-12)
    half = PaperModel(FingerParams(area_exponent=0.5))  # W_c ∝ F^(1/2): 4× the force, 2× the amplitude
    assert half.relative_friction(2 * amplitude, 0.8) == pytest.approx(half.relative_friction(amplitude, 0.2),
                                                                        abs=1e-12)


@pytest.mark.parametrize("name", MODELS)
def test_force_per_sample_matches_one_force_at_a_time(name):
    model = MODELS[name]
    rng = np.random.default_rng(3)
    force = rng.uniform(0.05, 1.5, 400)
    ratio = rng.uniform(0.0, 1.0, 400)
    together = model.amplitude_um_pp(ratio, force, 6.0)
    alone = [model.amplitude_um_pp(np.array([r]), float(f), 6.0) for r, f in zip(ratio, force, strict=True)]
    assert together.amplitude_um_pp == pytest.approx([a.amplitude_um_pp[0] for a in alone], abs=1e-9)
    assert abs(together.clamped - sum(a.clamped for a in alone)) <= 1  # a ratio on the floor may round either way
    forward = model.relative_friction(np.full(400, 2.0), force)
    assert forward == pytest.approx([float(model.relative_friction(2.0, float(f))) for f in force], abs=1e-12)


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -0.1])
def test_bad_forces_ratios_and_amplitudes_raise_one_line(name, bad):
    model = MODELS[name]
    with pytest.raises(ModelError, match="normal force must be a finite number >= 0 N"):
        model.amplitude_um_pp(np.array([0.5, 0.6]), bad)
    with pytest.raises(ModelError, match="normal force must be a finite number >= 0 N"):
        model.amplitude_um_pp(np.array([0.5, 0.6]), np.array([0.5, bad]))  # the per-sample kernels check too
    with pytest.raises(ModelError, match="normal force"):
        model.relative_friction(1.0, bad)
    with pytest.raises(ModelError, match="friction ratio must be a finite number >= 0"):
        model.amplitude_um_pp(np.array([0.5, bad]), np.array([0.5, 0.5]))
    with pytest.raises(ModelError, match="amplitude must be a finite number >= 0"):
        model.relative_friction(np.array([1.0, bad]), 0.5)


@pytest.mark.parametrize("kwargs, key", [
    ({"shape": 0.0}, "shape"), ({"shape": -1.0}, "shape"), ({"scale_um_pp": 0.0}, "scale_um_pp"),
    ({"scale_um_pp": np.inf}, "scale_um_pp"), ({"force_exponent": np.nan}, "force_exponent"),
])
def test_stretched_parameters_that_break_the_model_are_refused(kwargs, key):
    with pytest.raises(ModelError, match=rf"^{key} must lie in \["):
        StretchedExponentialModel(**kwargs)


@settings(max_examples=80, deadline=None)
@given(scale=st.floats(0.05, 100.0), shape=st.floats(0.3, 8.0), exponent=st.floats(-2.0, 2.0),
       force=st.lists(st.floats(0.0, 20.0), min_size=1, max_size=30))
def test_every_valid_stretched_model_is_monotone_and_its_inverse_exact(scale, shape, exponent, force):
    model = StretchedExponentialModel(scale, shape, exponent)
    force = np.array(force)
    amplitude = np.linspace(0.0, 20.0, 200)
    for f in np.unique(force):
        assert np.all(np.diff(model.relative_friction(amplitude, f)) <= 0)
    ratio = np.linspace(0.0, 1.0, len(force))
    result = model.amplitude_um_pp(ratio, force, 20.0)
    reached = result.amplitude_um_pp < 20.0
    assert np.all(np.abs(model.relative_friction(result.amplitude_um_pp, force) - ratio)[reached] <= 1e-3)


def test_table_with_several_forces_is_exact_at_the_end_of_each_range():
    # at 0.2 N friction falls to 0.4 by 6 µm, at 0.6 N only to 0.7: each force's curve ends at its own point
    amplitude = np.array([0, 2, 4, 6.0] * 2)
    ratio = np.array([1, 0.8, 0.6, 0.4, 1, 0.9, 0.8, 0.7])
    force = np.array([0.2] * 4 + [0.6] * 4)
    model = TableModel(Measurements(amplitude, ratio, force, "two forces"))
    assert model.relative_friction(np.array([5.0, 6.0]), 0.6) == pytest.approx([0.75, 0.7], abs=1e-6)
    assert model.relative_friction(np.array([5.0, 6.0]), 0.2) == pytest.approx([0.5, 0.4], abs=1e-6)
    assert float(model.floor_ratio(0.6)) == pytest.approx(0.7, abs=1e-6)
