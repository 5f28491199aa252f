"""Physics that follows the pressing finger (issue 23): force in every default and every path, force
ranges said once, the squeeze-film model, the paper's missing pieces, and calibration that knows what
two forces can test. Expected values are computed by hand in each test."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from ultraglide.render.physics.calibration import (
    calibration_toml,
    compare_models,
    fit_model,
    read_calibration,
    selection_note,
)
from ultraglide.render.physics.errors import ForceRangeWarning, ModelError, QuasiStaticWarning
from ultraglide.render.physics.fingerprint import (
    FingerParams,
    dynamic_stiffness_ratio,
    glide_threshold_um_pp,
    ridge_shear_resonance_hz,
)
from ultraglide.render.physics.friction_models import PaperModel, StretchedExponentialModel
from ultraglide.render.physics.lateral import simulate_lateral
from ultraglide.render.physics.measurements import Measurements, read_measurements
from ultraglide.render.physics.normal_contact import relative_friction
from ultraglide.render.physics.squeeze_film import FilmParams, SqueezeFilmModel

import ultraglide

MONNOYER_SCALE = 2 * math.sqrt(2) * 1.32  # µm p-p: exp(-a²/2tau²) with a = a_pp / 2


def hand_amplitude(ratio, force_n):
    """The default model's static inverse (the stretched law's) by hand: s0 (F / 0.5 N)^(1/3)
    sqrt(-ln((r - d) / (1 - d))), floor d = 0.1."""
    return MONNOYER_SCALE * (force_n / 0.5) ** (1 / 3) * np.sqrt(-np.log((ratio - 0.1) / 0.9))


# ---- force in every default and every path ---------------------------------------------------------
def test_the_default_rendering_model_is_force_aware_and_says_its_law():
    model = ultraglide.load_model("stretched")
    assert "assumed from the paper's detachment law" in model.describe()
    assert model.relative_friction(3.1, 0.2) == pytest.approx(
        0.1 + 0.9 * math.exp(-(3.1 / (MONNOYER_SCALE * 0.4 ** (1 / 3))) ** 2))
    assert model.relative_friction(3.1, 0.2) == pytest.approx(0.353, abs=1e-3)
    assert model.relative_friction(3.1, 1.0) == pytest.approx(0.683, abs=1e-3)


@pytest.mark.slow
def test_export_force_changes_the_envelope_as_the_stated_law_says(tmp_path):
    envelopes = {}
    for model in ("dynamic", "stretched"):  # the default, which plans, and its static law alone
        for force in (0.1, 2.0):
            csv = tmp_path / f"{model}-{force}.csv"
            run_cli("export", "grating-1mm", "-o", tmp_path / f"{model}-{force}.wav", "--force", force,
                    "--duration-s", "0.5", "--envelope-csv", csv, "--model", model, check=True)
            envelopes[model, force] = np.genfromtxt(csv, delimiter=",", names=True)
    for (_, force), table in envelopes.items():  # the inverse is asked for the planner's ratio where it plans
        ratio, target = table["planned_ratio"], table["target_um_pp"]
        inside = (ratio < 1) & (target < 6.0)  # below the plate's 6 µm limit
        assert inside.sum() > 100
        np.testing.assert_allclose(target[inside], hand_amplitude(ratio[inside], force), rtol=1e-4, atol=1e-4)
    low, high = envelopes["stretched", 0.1]["target_um_pp"], envelopes["stretched", 2.0]["target_um_pp"]
    both = (low > 0.1) & (high < 6.0)
    assert both.sum() > 100
    np.testing.assert_allclose(high[both] / low[both], 20 ** (1 / 3), rtol=1e-4)  # (2 N / 0.1 N)^(1/3)


@pytest.mark.slow
def test_model_refuses_a_force_beyond_a_fingertips_range_with_the_range():
    line = assert_one_line_error(run_cli("model", "--force", "50"))
    assert "--force" in line and "up to 10 N" in line and "50" in line


def test_export_wav_uses_force_n_for_a_trajectory_without_force(tmp_path):
    trajectory = ultraglide.RecordedTrajectory([0.0, 0.5], [10.0, 60.0], [25.0, 25.0])
    blocks = []
    ultraglide.export_wav("grating-1mm", tmp_path / "a.wav", trajectory, force_n=2.0,  # the inverse's ratio:
                          observers=[lambda block: blocks.append((block.planned_ratio.copy(),  # the planner's
                                                                  block.target_um_pp.copy()))])
    ratio = np.concatenate([b[0] for b in blocks])
    target = np.concatenate([b[1] for b in blocks])
    inside = (ratio < 1) & (target < 6.0)
    assert inside.sum() > 100
    np.testing.assert_allclose(target[inside], hand_amplitude(ratio[inside], 2.0), rtol=1e-6)
    logged = ultraglide.RecordedTrajectory([0.0, 0.5], [10.0, 60.0], [25.0, 25.0], [0.3, 0.3])
    with pytest.raises(ultraglide.RenderError, match="brings its own force"):
        ultraglide.export_wav("grating-1mm", tmp_path / "b.wav", logged, force_n=2.0)


def test_a_force_outside_the_models_range_is_said_once():
    model = StretchedExponentialModel()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.relative_friction(2.0, 3.0)
        model.amplitude_um_pp(np.array([0.5, 0.4]), np.array([4.0, 5.0]))
        model.relative_friction(2.0, 0.005)  # a lifting finger: no word
    said = [w for w in caught if issubclass(w.category, ForceRangeWarning)]
    assert len(said) == 1 and "3 N is outside 0.01-2.44 N" in str(said[0].message)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        StretchedExponentialModel().relative_friction(1.0, 12.0)
    assert "12 N is above 10 N" in str(caught[0].message) and "takes it as 10 N" in str(caught[0].message)


def test_the_contact_area_never_exceeds_a_fingertips():
    from ultraglide.render.physics.fingerprint import contact_area_mm2

    assert float(contact_area_mm2(1.0)) == pytest.approx(138.1)
    assert float(contact_area_mm2(50.0)) == 250.0
    paper = PaperModel()
    # above 2.44 N the area is held, so W_c = 2 F h / (E A) grows as F: twice the force, twice the amplitude
    assert float(paper._detach_um_pp(8.0)) == pytest.approx(2 * float(paper._detach_um_pp(4.0)))
    assert float(paper._detach_um_pp(8.0)) == pytest.approx(2 * 8.0 * 150e-6 / (1e6 * 250e-6) * 1e6)


@pytest.mark.slow
# ---- the squeeze-film model ----------------------------------------------------------------------
def test_squeeze_film_reaches_measured_reductions_within_6_um_at_half_a_newton():
    model = SqueezeFilmModel()
    assert float(model.relative_friction(6.0, 0.5)) < 0.3
    assert float(model.amplitude_um_pp(0.3, 0.5).amplitude_um_pp) < 6.0
    # lighter touches levitate more
    assert model.relative_friction(4.0, 0.1) < model.relative_friction(4.0, 0.5) < model.relative_friction(4.0, 2.0)


def test_squeeze_film_with_its_film_off_is_the_papers_model():
    off = SqueezeFilmModel(FilmParams(film_fraction=0.0))
    amplitude = np.linspace(0.0, 10.0, 41)
    for force in (0.1, 0.35, 0.5, 2.0):
        direct = relative_friction(amplitude, force)  # eq. (9) integrated afresh
        assert np.max(np.abs(off.relative_friction(amplitude, force) - direct)) < 1e-3
        paper = PaperModel().relative_friction(amplitude, force)
        assert np.max(np.abs(off.relative_friction(amplitude, force) - paper)) == 0.0


def test_squeeze_film_pressure_by_hand():
    from ultraglide.render.physics.squeeze_film import contact_share, film_overpressure_ratio

    eps = 0.3
    assert float(film_overpressure_ratio(eps)) == pytest.approx(math.sqrt((1 + 1.5 * 0.09) / (1 - 0.09)) - 1)
    # 6 µm p-p over a 10 µm gap: eps = 0.3; film load = 0.4 x A(0.5 N) x p_a x that
    area_m2 = 138.1 * 0.5 ** (2 / 3) * 1e-6
    lift = 0.4 * area_m2 * 101325.0 * float(film_overpressure_ratio(0.3))
    assert float(contact_share(6.0, 0.5)) == pytest.approx(1 - lift / 0.5)


@pytest.mark.slow
def test_squeeze_film_inverse_is_exact_live_and_offline():
    model = SqueezeFilmModel()
    for force in (0.1, 0.5, 2.0):
        floor = float(model.floor_ratio(force, 6.0))
        ratio = np.linspace(floor, 1.0, 4001)
        out = np.empty(len(ratio))
        for forces in (force, np.full(len(ratio), force)):
            result = model.amplitude_um_pp(ratio, forces, 6.0, out=out)
            assert result.amplitude_um_pp is out and result.clamped == 0
            assert np.all(np.diff(out) <= 1e-9)
            assert np.max(np.abs(model.relative_friction(out, force) - ratio)) <= 1e-6


# ---- the paper's missing pieces ------------------------------------------------------------------
def test_ridge_shear_resonance_from_the_density():
    shear_speed = math.sqrt(1e6 / (2 * 1.4) / 900.0)
    assert ridge_shear_resonance_hz() == pytest.approx(shear_speed / (4 * 150e-6))  # 33.2 kHz
    assert ridge_shear_resonance_hz(lumped=True) == pytest.approx(shear_speed / (2 * math.pi * 150e-6))  # 21.1 kHz
    kh = math.pi / 2 * 27.83e3 / ridge_shear_resonance_hz()
    assert float(dynamic_stiffness_ratio(27.83e3)) == pytest.approx(kh / math.tan(kh))
    with pytest.warns(QuasiStaticWarning, match="27.83 kHz is 0.84 of the ridge layer's shear resonance"):
        simulate_lateral(4.0, 0.4, 27.83e3, cycles=1)


def test_the_papers_psychophysics_with_a_stated_preload():
    force, preload = 0.4, 0.1
    k_t = 1e6 / 2.8 * 138.1 * force ** (2 / 3) * 1e-6 / 150e-6
    assert float(glide_threshold_um_pp(force, FingerParams(), preload)) == pytest.approx(
        2 * (force - preload) / k_t * 1e6)  # 3.36 µm
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuasiStaticWarning)
        felt = {a: simulate_lateral(a, force, 27.83e3, preload_n=preload).slid for a in (2.0, 4.0)}
        bare = simulate_lateral(4.0, force, 27.83e3).slid
    assert felt == {2.0: False, 4.0: True}  # "no difference at 2 µm", "more slippery at 4 µm"
    assert not bare  # without the preload the model (4.48 µm) misses the 4 µm observation


# ---- calibration that knows what the data can test ------------------------------------------------
def _two_forces(noise=0.02, seed=3):
    rng = np.random.default_rng(seed)
    amplitude = np.tile(np.arange(0.0, 6.01, 0.5), 2)
    force = np.repeat([0.2, 0.6], 13)
    truth = StretchedExponentialModel(3.2, 1.8, 0.5)
    ratio = truth.relative_friction(amplitude, force) + rng.normal(0, noise, len(force))
    return Measurements(amplitude, np.clip(ratio, 0.0, 1.2), force, "two forces")


def test_two_forces_do_not_rank_force_laws():
    data = _two_forces()
    note = selection_note(data)
    assert note.startswith("2 forces: the force law could not be tested") and "k-fold error within each force" in note
    fits = compare_models(data, ("stretched", "exponential"))
    assert all("leave_one_force_out" not in f.cross_validation for f in fits)
    scores = [f.cross_validation["k_fold"] for f in fits]
    assert scores == sorted(scores)
    assert "fitted on two forces (0.2-0.6 N (2 forces)): not tested" in fits[0].model.force_law()


@pytest.mark.slow
def test_bootstrap_errors_sit_beside_the_jacobian_ones():
    fit = fit_model(_two_forces(), "stretched", bootstrap=60)
    points = fit.bootstrap["points"]
    for p in fit.parameters:
        if not p.fixed:
            assert 0.2 * p.stderr < points[p.spec.key] < 5 * p.stderr + 1e-3
    assert "force" not in fit.bootstrap  # two groups: no group bootstrap


def test_the_fitted_force_range_is_kept_and_checked(tmp_path):
    fit = fit_model(_two_forces(), "stretched")
    path = tmp_path / "cal.toml"
    path.write_text(calibration_toml(fit))
    model = read_calibration(path)
    assert model.valid_force_range_n() == (0.2, 0.6)
    with pytest.warns(ForceRangeWarning, match="outside the forces this stretched calibration was fitted on"):
        model.relative_friction(2.0, 1.5)


def test_a_noisy_csv_with_a_ratio_slightly_below_zero_is_accepted(tmp_path):
    path = tmp_path / "noisy.csv"
    path.write_text("amplitude_um_pp,relative_friction\n0,1.01\n2,0.7\n4,0.2\n6,-0.003\n")
    data = read_measurements(path)
    assert data.relative_friction[-1] == 0.0 and data.clipped_below_zero == 1 and data.above_one == 1
    assert "clipped to 0" in data.noise_words()
    result = run_cli("calibrate", path, "--bootstrap", "0")
    assert result.returncode == 0, result.stderr
    path.write_text("amplitude_um_pp,relative_friction\n0,1\n2,0.7\n6,-0.2\n")
    with pytest.raises(ModelError, match="from -0.05 to 1.2"):
        read_measurements(path)


@pytest.mark.parametrize("rows, reason", [
    ("0,0.7\n2,0.7\n4,0.7\n6,0.7\n", "not about 1"),
    ("0.4,1\n2,1\n4,0.99\n6,1\n", "does not fall with amplitude"),
])
def test_a_table_that_does_not_describe_friction_reduction_is_refused(tmp_path, rows, reason):
    path = tmp_path / "flat.csv"
    path.write_text("amplitude_um_pp,relative_friction\n" + rows)
    with pytest.raises(ModelError, match=reason):
        ultraglide.load_model(f"table:{path}")
