"""Equations (1)–(6) against hand-computed values and the paper's own statements."""

import math

import numpy as np
import pytest
from ultraglide.render.physics.fingerprint import (
    FingerParams,
    contact_area_mm2,
    detach_amplitude_um_pp,
    friction_coefficient,
    glide_threshold_um_pp,
    normal_stiffness_n_per_m,
    shear_modulus_pa,
    tangential_stiffness_n_per_m,
)
from ultraglide.render.physics.lateral import (
    simulate_lateral,
    simulated_glide_threshold_um_pp,
    steady_glide_threshold_um_pp,
)


def test_contact_area_is_k_f_to_two_thirds():
    # 138.1 mm²/N^(2/3) × 0.5^(2/3) = 138.1 × 0.629961 = 86.998 mm²
    assert contact_area_mm2(0.5) == pytest.approx(86.998, abs=1e-3)
    assert contact_area_mm2(1.0) == pytest.approx(138.1)


def test_stiffnesses_by_hand():
    # k_n = E A / h = 1e6 Pa × 86.998e-6 m² / 150e-6 m = 579,987 N/m
    assert normal_stiffness_n_per_m(0.5) == pytest.approx(1e6 * 86.998e-6 / 150e-6, rel=1e-4)
    # G = 1 MPa / 2.8 = 357,143 Pa; k_t = G A / h
    assert shear_modulus_pa() == pytest.approx(357142.857, rel=1e-6)
    assert tangential_stiffness_n_per_m(0.5) == pytest.approx(357142.857 * 86.998e-6 / 150e-6, rel=1e-4)
    assert tangential_stiffness_n_per_m(0.5) / normal_stiffness_n_per_m(0.5) == pytest.approx(1 / 2.8)


def test_paper_worked_example_0_15_n_needs_about_1_2_um():
    assert detach_amplitude_um_pp(0.15) == pytest.approx(1.2, abs=0.06)


def test_detach_amplitude_grows_as_cube_root_of_force():
    # W = F / (E k F^(2/3) / h) ∝ F^(1/3): eight times the force, twice the amplitude
    assert detach_amplitude_um_pp(0.8) / detach_amplitude_um_pp(0.1) == pytest.approx(2.0)


def test_glide_threshold_is_about_4_um_at_about_0_4_n():
    assert 3.6 <= glide_threshold_um_pp(0.4) <= 4.8
    assert 3.6 <= steady_glide_threshold_um_pp(0.4) <= 4.8


def test_simulated_glide_threshold_matches_equation_5():
    for force in (0.1, 0.4, 1.0):
        simulated = simulated_glide_threshold_um_pp(force, tolerance_um=1e-3)
        assert simulated == pytest.approx(float(glide_threshold_um_pp(force)), abs=5e-3)


def test_figure_2_case_sticks_then_slides_at_mu_d():
    force = 0.5
    sim = simulate_lateral(5.0, force, 20e3, cycles=4, steps_per_cycle=4000)
    assert sim.slid
    # static friction caps the spring force; while sliding it is exactly mu_d F
    assert np.max(np.abs(sim.lateral_force_n)) <= 1.0 * force + 1e-12
    assert np.allclose(np.abs(sim.lateral_force_n[sim.sliding]), 0.7 * force)
    # slides end where the plate velocity reverses (V = 0): the last sliding step of each run
    ends = np.flatnonzero(sim.sliding[:-1] & ~sim.sliding[1:])
    assert len(ends) >= 4
    period_steps = 4000
    for end in ends:
        phase = (end % period_steps) / period_steps
        assert min(abs(phase - 0.25), abs(phase - 0.75)) < 2 / period_steps


def test_below_threshold_no_slip_and_force_follows_plate():
    force = 0.5
    amplitude = 0.9 * float(glide_threshold_um_pp(force))
    sim = simulate_lateral(amplitude, force)
    assert not sim.slid
    k_t = tangential_stiffness_n_per_m(force)
    assert np.allclose(sim.lateral_force_n, k_t * sim.plate_position_m)


def test_non_coulombic_coefficient_falls_with_force():
    # mu = 0.8 F^(-1/3): 0.8 at 1 N, 1.6 at 1/8 N
    assert friction_coefficient(1.0) == pytest.approx(0.8)
    assert friction_coefficient(0.125) == pytest.approx(1.6)


@pytest.mark.parametrize("bad", [
    {"youngs_modulus_pa": 0}, {"ridge_height_m": -1}, {"poisson_ratio": 0.5},
    {"friction_exponent": 1.5}, {"dynamic_friction": 2.0}, {"contact": "square"},
    {"area_coefficient_mm2": math.nan},
])
def test_parameters_are_validated(bad):
    with pytest.raises(ValueError):
        FingerParams(**bad)
