"""Friction models, pinned where scripts/mutation.sh found the quick tests silent: the default force (0.5 N)
and the force range (10 mN to 10 N), the 20 µm ceiling no model is evaluated beyond, the uniform table's
first and last intervals, and the one-line refusals word for word (the first bad value named). Expected
values come from the laws by hand: the stretched law exp(-(a / s)^beta) with s = s0 (F / 0.5 N)^p gives
a = s (ln(1 / ratio))^(1 / beta)."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.render.physics.calibration import load_model, model_kind
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
from ultraglide.render.physics.measurements import Measurements
from ultraglide.render.physics.normal_contact import relative_friction

S0 = 2 * np.sqrt(2) * 1.32  # Monnoyer's curve at 0.5 N, µm p-p


def _stretched_amplitude(ratio: float, force_n: float) -> float:
    return S0 * (force_n / 0.5) ** (1 / 3) * np.sqrt(np.log(1 / ratio))


def test_a_model_asked_without_a_force_works_at_half_a_newton():
    model = StretchedExponentialModel()
    assert float(model.amplitude_um_pp(0.5).amplitude_um_pp[()]) == pytest.approx(_stretched_amplitude(0.5, 0.5))
    assert float(model.relative_friction(S0)) == pytest.approx(np.exp(-1.0))  # 1/e at s0, at 0.5 N
    assert float(model.floor_ratio(limit_um_pp=S0)) == pytest.approx(np.exp(-1.0))


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
    floor = np.exp(-(20.0 / S0) ** 2)  # the ratio at 20 µm p-p, 0.5 N: about 3e-13
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
                "scale_um_pp": (200.0, "scale_um_pp must lie in [0.05, 100] µm p-p, got 200.0")}
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
    assert model.describe() == ("exponential: mu/mu0 = exp(-a²/2tau²), tau = 1 µm zero-to-peak; force law: none: "
                                "the same curve at every force (Monnoyer et al. did not state theirs)")
    assert model.parameters() == {"tau_um_zp": 1.0, "residual_ratio": 0.0}
    assert ExponentialModel(35.0).tau_um_zp == 35.0
    with pytest.raises(ModelError) as error:
        ExponentialModel(35.5)
    assert str(error.value) == "tau_um_zp must lie in [0.02, 35] µm zero-to-peak, got 35.5"


def test_the_stretched_model_describes_itself():
    model = StretchedExponentialModel(3.0, 1.5, 0.25)
    assert model.describe() == ("stretched: mu/mu0 = exp(-(a/s)^beta), s = 3 µm p-p x (F/0.5 N)^0.25, beta = 1.5; "
                                "force law: s ∝ F^0.25, as given")


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
