"""Friction models: forward against the physics, and the inverse's contract under random input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ultraglide.render.physics.calibration import calibration_toml, fit_model, load_model, model_kind, read_calibration
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import FingerParams
from ultraglide.render.physics.friction_models import (
    ExponentialModel,
    FrictionModel,
    PaperModel,
    StretchedExponentialModel,
    TableModel,
    UniformTable,
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
    model = StretchedExponentialModel(scale_um_pp=3.0, shape=1.5, force_exponent=0.5, residual_ratio=0.0)
    for force in (0.2, 0.5, 1.0):
        scale = 3.0 * (force / 0.5) ** 0.5  # the 1/e amplitude at this force
        assert model.relative_friction(scale, force) == pytest.approx(np.exp(-1), rel=1e-12)
        half = scale * np.log(2) ** (1 / 1.5)  # exp(-(a/s)^1.5) = 1/2
        assert model.amplitude_um_pp(np.array([0.5]), force).amplitude_um_pp[0] == pytest.approx(half, rel=1e-12)


def test_stretched_defaults_are_the_published_curve_at_half_a_newton_above_the_measured_floor():
    data = read_measurements(SHARED_DATA)
    # d + (1 - d) x the fitted curve, d = 0.10: the mean measured at full amplitude (Wiertlewski et al. 2016)
    assert StretchedExponentialModel().relative_friction(data.amplitude_um_pp, 0.5) == pytest.approx(
        0.10 + 0.90 * data.relative_friction, abs=1e-4)
    assert StretchedExponentialModel(residual_ratio=0.0).relative_friction(data.amplitude_um_pp, 0.5) == \
        pytest.approx(data.relative_friction, abs=1e-4)
    # harder presses need more vibration for the same reduction: s grows as F^(1/3)
    model = StretchedExponentialModel()
    a1 = model.amplitude_um_pp(np.array([0.5]), 0.2).amplitude_um_pp[0]
    a2 = model.amplitude_um_pp(np.array([0.5]), 1.6).amplitude_um_pp[0]
    assert a2 / a1 == pytest.approx(8 ** (1 / 3), rel=1e-12)


def test_the_default_floor_is_never_crossed_and_ratios_below_it_are_counted():
    model = StretchedExponentialModel()
    assert model.residual_ratio == 0.10
    assert float(model.relative_friction(20.0, 0.5)) == pytest.approx(0.10, abs=1e-12)  # far beyond any plate
    floor_at_6 = 0.10 + 0.90 * np.exp(-(6.0 / (2 * np.sqrt(2) * 1.32)) ** 2)  # 0.168: the plate's limit 6 µm
    assert float(model.floor_ratio(0.5, 6.0)) == pytest.approx(floor_at_6, rel=1e-12)
    asked = np.array([1.0, 0.5, 0.2, 0.15, 0.05, 0.0])
    result = model.amplitude_um_pp(asked, 0.5, limit_um_pp=6.0)
    assert result.clamped == 3  # 0.15, 0.05 and 0 lie below the floor: held at the limit and counted
    assert result.amplitude_um_pp[-3:].tolist() == [6.0, 6.0, 6.0]
    assert float(model.relative_friction(result.amplitude_um_pp[2], 0.5)) == pytest.approx(0.2, abs=1e-9)
    assert "floor d = 0.1" in model.describe() and "Wiertlewski" in model.describe()


@pytest.mark.parametrize("model", [ExponentialModel(), StretchedExponentialModel(residual_ratio=0.0)])
def test_models_that_reach_zero_say_so(model):
    assert float(model.relative_friction(20.0, 0.5)) < 1e-6
    assert "reaches 0" in model.describe()


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


def test_a_table_at_three_forces_spans_them_and_never_rises_above_rest():
    # a sensor's noise put one point at rest above 1 (friction at rest is the ratio's 1 by definition)
    amplitude = np.array([0, 2, 4, 6.0] * 3)
    ratio = np.array([1.08, 0.8, 0.6, 0.4, 1, 0.85, 0.7, 0.55, 1, 0.9, 0.8, 0.7])
    force = np.array([0.2] * 4 + [0.4] * 4 + [0.6] * 4)
    model = TableModel(Measurements(amplitude, ratio, force, "three forces"))
    assert model.valid_force_range_n() == (0.2, 0.6)  # the lightest to the heaviest, not the first two
    assert repr(model) == "TableModel('three forces', forces 0.2–0.6 N)"
    for f in (0.2, 0.4, 0.6):
        assert float(model.relative_friction(np.array([0.0]), f)[0]) == pytest.approx(1.0, abs=1e-9)
    assert np.all(model.relative_friction(np.linspace(0.0, 6.0, 61), 0.2) <= 1.0)
    assert float(model.amplitude_um_pp(1.0, 0.2, 6.0).amplitude_um_pp[()]) == 0.0  # rest needs no vibration
    # 1.08 taken as 1 before the curve is drawn: 0.2 N's points are then on a line, which PCHIP keeps
    assert model.relative_friction(np.array([0.5, 1.0, 3.0]), 0.2) == pytest.approx([0.95, 0.9, 0.7], abs=1e-6)


def test_a_models_repr_leaves_out_only_a_floor_at_its_class_default():
    assert repr(StretchedExponentialModel(3.0, 2.0, 0.25)) == \
        "StretchedExponentialModel(scale_um_pp=3.0, shape=2.0, force_exponent=0.25)"
    assert repr(StretchedExponentialModel(3.0, 2.0, 0.25, residual_ratio=0.0)) == \
        "StretchedExponentialModel(scale_um_pp=3.0, shape=2.0, force_exponent=0.25, residual_ratio=0.0)"


S0 = 2 * np.sqrt(2) * 1.32  # Monnoyer's curve at 0.5 N, µm p-p


D = 0.1  # the default floor: the mean measured at full amplitude (Wiertlewski et al. 2016)


def _stretched_amplitude(ratio: float, force_n: float) -> float:
    """The default stretched law's inverse by hand: s (ln((1 - d) / (ratio - d)))^(1/2), d = 0.1."""
    return S0 * (force_n / 0.5) ** (1 / 3) * np.sqrt(np.log((1 - D) / (ratio - D)))


def test_a_model_asked_without_a_force_works_at_half_a_newton():
    model = StretchedExponentialModel()
    assert float(model.amplitude_um_pp(0.5).amplitude_um_pp[()]) == pytest.approx(_stretched_amplitude(0.5, 0.5))
    assert float(model.relative_friction(S0)) == pytest.approx(D + (1 - D) * np.exp(-1.0))  # 1/e of it at s0, 0.5 N
    assert float(model.floor_ratio(limit_um_pp=S0)) == pytest.approx(D + (1 - D) * np.exp(-1.0))


@pytest.mark.parametrize("fast", [True, False], ids=["compiled", "numpy"])
def test_forces_beyond_10_n_count_as_10_n_and_below_10_mn_as_10_mn(fast):
    model = StretchedExponentialModel()
    ratio = np.array([0.5, 0.5, 0.5, 0.5])
    forces = np.array([10.0, 25.0, 0.01, 0.001])
    if fast:
        got = model.amplitude_um_pp(ratio, forces).amplitude_um_pp
    else:  # a 2-d query takes the numpy path
        got = model.amplitude_um_pp(ratio.reshape(2, 2), forces.reshape(2, 2)).amplitude_um_pp.ravel()
    expected = [_stretched_amplitude(0.5, 10.0)] * 2 + [_stretched_amplitude(0.5, 0.01)] * 2
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    assert float(model.scale_at_um_pp(40.0)) == pytest.approx(S0 * 20 ** (1 / 3))


@pytest.mark.parametrize("fast", [True, False], ids=["compiled", "numpy"])
def test_no_model_asks_for_more_than_20_um_without_a_limit(fast):
    model = StretchedExponentialModel()
    floor = D + (1 - D) * np.exp(-(20.0 / S0) ** 2)  # the ratio at 20 µm p-p, 0.5 N: the floor and 3e-13
    assert float(model.floor_ratio()) == pytest.approx(floor, rel=1e-9)
    ratio = np.array([0.0, 0.0, 0.5, 1.0])
    result = model.amplitude_um_pp(ratio if fast else ratio.reshape(2, 2))
    np.testing.assert_allclose(result.amplitude_um_pp.ravel(), [20.0, 20.0, _stretched_amplitude(0.5, 0.5), 0.0],
                               rtol=1e-9)
    assert result.clamped == 2  # a ratio of 0 is a valid target, out of reach: held at the ceiling, counted
    assert PaperModel().max_amplitude_um_pp == 20.0


def test_a_uniform_table_interpolates_in_its_first_and_last_intervals():
    table = UniformTable(0.0, 4.0, np.array([0.0, 1.0, 4.0, 9.0, 16.0]))  # x^2 at 0, 1, 2, 3, 4
    np.testing.assert_allclose(table(np.array([-1.0, 0.0, 0.25, 0.5, 3.5, 3.75, 4.0, 5.0])),
                               [0.0, 0.0, 0.25, 0.5, 12.5, 14.25, 16.0, 16.0])  # held beyond the ends
    rows = UniformTable(1.0, 3.0, np.array([[0.0, 2.0, 6.0], [1.0, 1.0, 0.0]]))
    np.testing.assert_allclose(rows(np.array([1.5, 3.0]), row=1), [1.0, 0.0])
    np.testing.assert_allclose(rows(2.5), 4.0)


def test_bad_forces_are_refused_naming_the_first_bad_value():
    model = StretchedExponentialModel()
    with pytest.raises(ModelError) as error:
        model.relative_friction(1.0, -0.1)
    assert str(error.value) == "normal force must be a finite number >= 0 N, got -0.1"
    for forces, named in (([0.5, -1.0, np.nan], "-1.0"), ([0.5, np.inf], "inf"), ([np.nan, -2.0], "nan")):
        with pytest.raises(ModelError) as error:
            model.relative_friction(1.0, np.array(forces))
        assert str(error.value) == f"normal force must be a finite number >= 0 N, got {named}"
    model.relative_friction(1.0, np.array([0.0, 0.5, 1e6]))  # zero and huge forces are fine (clipped)


def test_bad_ratios_are_refused_in_words_and_zero_is_a_ratio():
    model = ExponentialModel()
    with pytest.raises(ModelError) as error:
        model.amplitude_um_pp(np.array([[0.5, -0.25]]))
    assert str(error.value) == "friction ratio must be a finite number >= 0 (1 = plate at rest), got -0.25"
    assert model.amplitude_um_pp(np.array([[0.0]]), limit_um_pp=5.0).amplitude_um_pp[0, 0] == 5.0



def test_bad_amplitudes_and_limits_are_refused_in_words_and_a_zero_limit_is_a_limit():
    model = ExponentialModel()
    with pytest.raises(ModelError) as error:
        model.relative_friction(np.array([1.0, -3.0]))
    assert str(error.value) == "amplitude must be a finite number >= 0 µm p-p, got -3.0"
    with pytest.raises(ModelError) as error:
        model.amplitude_um_pp(np.array([0.5]), limit_um_pp=-1.0)
    assert str(error.value) == "the amplitude limit must be >= 0 µm, got -1.0"
    for ratio in (np.array([0.5, 1.0]), np.array([[0.5, 1.0]])):  # the compiled path and the numpy path
        stopped = model.amplitude_um_pp(ratio, limit_um_pp=0.0)  # a plate that may not move: every ratio under 1
        np.testing.assert_array_equal(stopped.amplitude_um_pp.ravel(), [0.0, 0.0])  # is out of reach
        assert stopped.clamped == 1
        half = model.amplitude_um_pp(ratio, limit_um_pp=0.5)
        np.testing.assert_allclose(half.amplitude_um_pp.ravel(), [0.5, 0.0])
        assert half.clamped == 1


@pytest.mark.parametrize("shape", [(4,), (2, 2)], ids=["compiled", "numpy"])
def test_amplitudes_are_written_into_out_by_every_path(shape):
    model = StretchedExponentialModel()
    ratio = np.array([0.5, 0.8, 1.0, 0.5]).reshape(shape)
    forces = np.array([0.5, 0.5, 2.0, 4.0]).reshape(shape)
    out = np.full(shape, np.nan)
    result = model.amplitude_um_pp(ratio, forces, out=out)
    assert result.amplitude_um_pp is out
    expected = [_stretched_amplitude(0.5, 0.5), _stretched_amplitude(0.8, 0.5), 0.0, _stretched_amplitude(0.5, 4.0)]
    np.testing.assert_allclose(out.ravel(), expected, rtol=1e-9)
    single = np.full(shape, np.nan, dtype=np.float32)  # float32: not the kernels' type, written all the same
    assert model.amplitude_um_pp(ratio, forces, out=single).amplitude_um_pp is single
    np.testing.assert_allclose(single.ravel(), expected, rtol=1e-6)


@pytest.mark.parametrize("missing", ["relative_friction", "_amplitude_in_reach", "describe"])
def test_a_model_must_give_its_forward_law_its_inverse_and_a_description(missing):
    methods = {"relative_friction": lambda self, amplitude_um_pp, force_n=0.5: np.ones(np.shape(amplitude_um_pp)),
               "_amplitude_in_reach": lambda self, ratio, force_n: np.zeros(np.shape(ratio)),
               "describe": lambda self: "a model"}
    del methods[missing]
    with pytest.raises(TypeError, match=missing):
        type("Incomplete", (FrictionModel,), methods)()
    methods[missing] = lambda *args: None
    type("Complete", (FrictionModel,), methods)()


def test_the_paper_models_table_follows_the_direct_integration_over_every_force_and_amplitude():
    """The tabulated law against :func:`render.physics.normal_contact.relative_friction` (the paper's integral done
    afresh at each point) from 10 mN to 10 N and 0 to the 20 µm ceiling: the 384 nodes, dense where the
    curve bends near rest, keep it within 2e-4 of the ratio."""
    model = PaperModel()
    amplitude = np.linspace(0.0, 20.0, 81)
    for force in (0.01, 0.1, 0.5, 2.0, 10.0):
        np.testing.assert_allclose(model.relative_friction(amplitude, force), relative_friction(amplitude, force),
                                   atol=2e-4, err_msg=f"{force} N")
    # and its inverse by the numpy path (a 2-d query) gives the amplitude that the law maps back to the ratio
    ratio = np.linspace(float(model.floor_ratio(0.5)) + 1e-3, 1.0, 40).reshape(5, 8)
    found = model.amplitude_um_pp(ratio, 0.5).amplitude_um_pp
    np.testing.assert_allclose(relative_friction(found, 0.5), ratio, atol=2e-4)
    np.testing.assert_allclose(found.ravel(), model.amplitude_um_pp(ratio.ravel(), 0.5).amplitude_um_pp, rtol=1e-9)


def test_the_paper_model_describes_itself_and_gives_its_finger_parameters():
    params = FingerParams(youngs_modulus_pa=2.5e6, friction_exponent=0.5, area_exponent=0.6, contact="uniform")
    model = PaperModel(params)
    assert model.describe() == ("paper: ridge springs with non-Coulombic friction (E = 2.5 MPa, n = 0.5, A ∝ F^0.6, "
                                "uniform contact)")
    assert model.parameters() == {"youngs_modulus_pa": 2.5e6, "friction_exponent": 0.5, "area_exponent": 0.6}
    assert model_kind(model) == "paper-uniform"


@pytest.mark.parametrize(("model", "kind"), [(StretchedExponentialModel(), "stretched"),
                                             (ExponentialModel(), "exponential")])
def test_a_model_is_named_in_calibration_files_by_its_kind(model, kind):
    assert model_kind(model) == kind
    assert type(load_model(kind)) is type(model)


def test_the_stretched_models_parameters_are_refused_outside_their_ranges_in_words():
    for exponent in (-2.0, 2.0):  # the ends are allowed
        assert StretchedExponentialModel(force_exponent=exponent).force_exponent == exponent
    refusals = {"force_exponent": (2.01, "force_exponent must lie in [-2, 2], got 2.01"),
                "shape": (9.0, "shape must lie in [0.3, 8], got 9.0"),
                "scale_um_pp": (200.0, "scale_um_pp must lie in [0.05, 100] µm p-p, got 200.0"),
                "residual_ratio": (0.95, "residual_ratio must lie in [0, 0.9], got 0.95")}
    for name, (value, message) in refusals.items():
        with pytest.raises(ModelError) as error:
            StretchedExponentialModel(**{name: value})
        assert str(error.value) == message
    with pytest.raises(ModelError) as error:
        StretchedExponentialModel(force_exponent=-2.01)
    assert str(error.value) == "force_exponent must lie in [-2, 2], got -2.01"


def test_the_exponential_law_has_no_force_term_and_its_tau_range_is_0_02_to_35_um():
    model = ExponentialModel(1.0)
    at_rest_force = model.amplitude_um_pp(np.array([0.5]), 0.5).amplitude_um_pp
    np.testing.assert_allclose(model.amplitude_um_pp(np.array([0.5]), 4.0).amplitude_um_pp, at_rest_force)
    np.testing.assert_allclose(at_rest_force, 2 * np.sqrt(2) * np.sqrt(np.log(2)))  # a_pp = 2 sqrt 2 tau sqrt(ln 2)
    assert model.describe() == ("exponential: mu/mu0 = exp(-a²/2tau²), tau = 1 µm zero-to-peak, no floor: reaches 0, "
                                "which no measured finger does; force law: none: the same curve at every force "
                                "(Monnoyer et al. did not state theirs)")
    assert model.parameters() == {"tau_um_zp": 1.0, "residual_ratio": 0.0}
    assert ExponentialModel(35.0).tau_um_zp == 35.0
    with pytest.raises(ModelError) as error:
        ExponentialModel(35.5)
    assert str(error.value) == "tau_um_zp must lie in [0.02, 35] µm zero-to-peak, got 35.5"


def test_the_stretched_model_describes_itself():
    model = StretchedExponentialModel(3.0, 1.5, 0.25)
    assert model.describe() == ("stretched: mu/mu0 = d + (1 - d) exp(-(a/s)^beta), s = 3 µm p-p x (F/0.5 N)^0.25, "
                                "beta = 1.5, "
                                "floor d = 0.1 (the mean measured at 6 µm p-p, 0.02-0.30 across people: Wiertlewski "
                                "et al. 2016); force law: s ∝ F^0.25, as given")
    # the law as written is the one evaluated: at a = s, d + (1 - d) e^-1, not e^-1
    assert float(model.relative_friction(3.0, 0.5)) == pytest.approx(0.1 + 0.9 * np.exp(-1.0))
    floored = ExponentialModel(1.0, residual_ratio=0.2)
    assert floored.describe().startswith("exponential: mu/mu0 = d + (1 - d) exp(-a²/2tau²), tau = 1 µm zero-to-peak, "
                                         "floor d = 0.2;")
    assert float(floored.relative_friction(2.0, 0.5)) == pytest.approx(0.2 + 0.8 * np.exp(-0.5))  # a = tau zp


def test_a_table_whose_points_fall_to_0_says_it_reaches_0_and_one_with_a_floor_does_not():
    amplitude = np.array([0.0, 2.0, 4.0, 6.0])
    zero = TableModel(Measurements(amplitude, np.array([1.0, 0.6, 0.2, 0.0]), None, "zero.csv"))
    assert float(zero.floor_ratio(0.5, 6.0)) == pytest.approx(0.0, abs=1e-9)
    assert zero.describe() == ("table: zero.csv (0.5 N, up to 6 µm p-p), reaches 0 (its points fall to 0), which "
                               "no measured finger does")
    floored = TableModel(Measurements(amplitude, np.array([1.0, 0.6, 0.2, 0.05]), None, "floor.csv"))
    assert float(floored.floor_ratio(0.5, 6.0)) == pytest.approx(0.05)
    assert "reaches 0" not in floored.describe()


def test_a_table_model_needs_two_amplitudes_a_force_and_names_its_source():
    two = Measurements(np.array([0.0, 4.0]), np.array([1.0, 0.2]), None, "two.csv")
    model = TableModel(two)
    assert model_kind(model) == "table"
    assert model.describe() == "table: two.csv (0.5 N, up to 4 µm p-p)"
    assert float(model.relative_friction(4.0)) == pytest.approx(0.2, abs=1e-6)
    with pytest.raises(ModelError) as error:
        TableModel(Measurements(np.array([2.0, 2.0]), np.array([1.0, 0.5]), None, "one.csv"))
    assert str(error.value) == "one.csv: at 0.5 N there must be two amplitudes or more"


@pytest.mark.parametrize("shape", [(5,), (5, 1)], ids=["compiled", "numpy"])
def test_a_table_at_three_forces_interpolates_the_amplitude_linearly_in_force(shape):
    # ratio = 1 - a / (10 F) at 0.5, 1 and 2 N, measured at 0, 2 and 4 µm: a ratio of 0.9 needs a = F µm
    amplitude = np.tile([0.0, 2.0, 4.0], 3)
    forces = np.repeat([0.5, 1.0, 2.0], 3)
    model = TableModel(Measurements(amplitude, 1 - amplitude / (10 * forces), forces, "three.csv"))
    asked = np.array([0.5, 1.0, 1.5, 2.0, 3.0]).reshape(shape)  # 3 N: beyond the last force, held at 2 N
    found = model.amplitude_um_pp(np.full(shape, 0.9), asked).amplitude_um_pp
    np.testing.assert_allclose(found.ravel(), [0.5, 1.0, 1.5, 2.0, 2.0], rtol=1e-3)
    assert model.describe() == "table: three.csv (0.5, 1, 2 N, up to 4 µm p-p)"
    assert model.parameters() == {"source": "three.csv"}


@pytest.mark.parametrize("shape", [(4,), (4, 1)], ids=["compiled", "numpy"])
def test_a_table_at_three_forces_reads_between_the_two_forces_around_each_force(shape):
    # ratio = 1 - a / (10 g) with g = 0.5, 1 and 4 at 0.5, 1 and 2 N: not linear in force, so the pair of rows
    # matters. A ratio of 0.95 needs a = g / 2: 0.25, 0.5 and 2 µm; between rows, linear in force:
    # 0.75 N -> (0.25 + 0.5) / 2 = 0.375; 1.5 N -> (0.5 + 2) / 2 = 1.25. Extrapolating from the wrong pair
    # would give 0.125 at 0.75 N (rows at 1 and 2 N) and 0.75 at 1.5 N (rows at 0.5 and 1 N).
    amplitude = np.tile([0.0, 2.0, 4.0], 3)
    forces = np.repeat([0.5, 1.0, 2.0], 3)
    g = np.repeat([0.5, 1.0, 4.0], 3)
    model = TableModel(Measurements(amplitude, 1 - amplitude / (10 * g), forces, "curved.csv"))
    asked = np.array([0.6, 0.75, 1.5, 1.9]).reshape(shape)
    found = model.amplitude_um_pp(np.full(shape, 0.95), asked).amplitude_um_pp
    expected = [0.25 + 0.25 * 0.2, 0.375, 1.25, 0.5 + 1.5 * 0.9]
    np.testing.assert_allclose(found.ravel(), expected, rtol=1e-3)


def test_a_table_measured_above_1_near_rest_still_rests_at_a_ratio_of_1():
    # measurement noise above 1 at 0 µm: friction cannot rise above the plate at rest, so 1 needs no vibration
    model = TableModel(Measurements(np.array([0.0, 2.0, 4.0]), np.array([1.1, 0.5, 0.2]), None, "noisy.csv"))
    assert float(model.relative_friction(0.0)) == pytest.approx(1.0, abs=1e-9)
    assert model.amplitude_um_pp(np.array([1.0, 1.0])).amplitude_um_pp.tolist() == [0.0, 0.0]
