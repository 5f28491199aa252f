"""Section IV: equilibrium (7), detachment, Hertz (8), relative friction (9), against independent integrals."""

import functools

import numpy as np
import pytest
from scipy import integrate, optimize
from ultraglide.render.physics.fingerprint import FingerParams, detach_amplitude_um_pp
from ultraglide.render.physics.normal_contact import (
    bed_reaction,
    cycle_reaction_n,
    relative_friction,
    relative_friction_of_u,
)

PHASE = np.linspace(0.0, 2.0 * np.pi, 8192, endpoint=False)
UNIFORM = FingerParams(contact="uniform")
HERTZ = FingerParams(contact="hertz")


@pytest.mark.parametrize("params", [UNIFORM, HERTZ], ids=["uniform", "hertz"])
@pytest.mark.parametrize("amplitude", [0.1, 1.0, 2.0, 4.0, 8.0, 15.0])
def test_equilibrium_eq7_mean_reaction_equals_load(params, amplitude):
    reaction = cycle_reaction_n(amplitude, 0.5, PHASE, params)
    assert np.mean(reaction) == pytest.approx(0.5, rel=2e-4)
    assert np.all(reaction >= 0)


def test_uniform_bed_detaches_exactly_above_eq6():
    force = 0.5
    critical = float(detach_amplitude_um_pp(force))
    assert cycle_reaction_n(0.98 * critical, force, PHASE, UNIFORM).min() > 0
    assert cycle_reaction_n(1.02 * critical, force, PHASE, UNIFORM).min() == 0


def test_hertz_contact_periphery_detaches_first():
    # Below eq. (6) the uniform bed stays attached and its reaction is linear in the plate
    # position. The Hertzian rim (zero static pressure at r = b) lets go at any amplitude, so its
    # total reaction is clipped on the unloading half: its minimum sits above the linear one.
    reaction = cycle_reaction_n(0.5, 0.5, PHASE, HERTZ)
    uniform = cycle_reaction_n(0.5, 0.5, PHASE, UNIFORM)
    u = 0.5 / float(detach_amplitude_um_pp(0.5))
    assert uniform == pytest.approx(0.5 * (1 + u * np.sin(PHASE)))
    assert reaction.min() > uniform.min() + 1e-3
    assert reaction.max() == pytest.approx(uniform.max(), abs=1e-3)  # the loading half is alike
    assert reaction.min() > 0


def _brute_force_hertz_reaction(u, phase):
    """Independent route: annuli in r with eq. (8), each solved by brentq, integrated by quad."""
    @functools.cache  # each phase's quad visits the same radii first: solve each once
    def offset(v):
        def mean_load(s):
            # quad told where the integrand's kinks are (where s + sin t crosses zero) converges in a few
            # panels rather than bisecting towards them: a quarter of the time, to within 2e-5 of the reaction
            kinks = (np.pi + np.arcsin(s), 2 * np.pi - np.arcsin(s)) if -1 < s < 1 else None
            return integrate.quad(lambda t: max(s + np.sin(t), 0.0), 0, 2 * np.pi, limit=200,
                                  points=kinks)[0] / (2 * np.pi)
        return optimize.brentq(lambda s: mean_load(s) - 1 / v, -1, 1, xtol=1e-12)

    def ring(rho, theta):
        local_pressure = 1.5 * np.sqrt(1 - rho**2)  # P / mean pressure
        v = u / local_pressure  # local amplitude over local static compression
        if v <= 1:
            value = local_pressure * (1 + v * np.sin(theta))
        else:
            value = local_pressure * v * max(offset(v) + np.sin(theta), 0.0)
        return value * 2 * rho  # annulus 2 pi r dr over pi b²
    return [integrate.quad(ring, 0, 1, args=(t,), limit=100, epsabs=1e-7)[0] for t in phase]


@pytest.mark.slow
@pytest.mark.parametrize("u", [0.6, 1.4, 3.0])
def test_hertz_reaction_matches_brute_force_integration(u):
    phase = np.array([-1.2, 0.7, 4.0])
    expected = _brute_force_hertz_reaction(u, phase)
    amplitude = u * float(detach_amplitude_um_pp(0.5))
    assert cycle_reaction_n(amplitude, 0.5, phase, HERTZ) / 0.5 == pytest.approx(expected, abs=2e-4)


def test_uniform_relative_friction_without_detachment_is_mean_of_power():
    # below detachment F(t) = F (1 + v sin θ): ratio = (1/2π) ∫ (1 + v sin θ)^n dθ
    n = 2 / 3
    for v in (0.3, 0.9):
        expected = integrate.quad(lambda t, v=v: (1 + v * np.sin(t)) ** n, 0, 2 * np.pi)[0] / (2 * np.pi)
        assert relative_friction_of_u(v, UNIFORM)[0] == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("params", [UNIFORM, HERTZ], ids=["uniform", "hertz"])
def test_coulomb_friction_gives_no_reduction(params):
    # n = 1: the mean friction force is mu times the mean load, which equilibrium fixes
    coulomb = params.with_(friction_exponent=1.0)
    assert relative_friction(np.array([0.5, 3.0, 10.0]), 0.5, coulomb) == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize("params", [UNIFORM, HERTZ], ids=["uniform", "hertz"])
def test_relative_friction_falls_modestly_and_never_levitates(params):
    amplitude = np.linspace(0, 20, 81)
    ratio = relative_friction(amplitude, 0.5, params)
    assert ratio[0] == pytest.approx(1.0)
    assert np.all(np.diff(ratio) <= 1e-9)
    assert 0.55 < ratio[-1] < 0.85  # tens of percent, not levitation
    assert 0.65 < relative_friction(8.0, 0.5, params) < 0.85


def test_ratio_depends_on_amplitude_only_through_the_detach_amplitude():
    for force in (0.1, 0.35, 1.0):
        u = 2.5
        amplitude = u * float(detach_amplitude_um_pp(force))
        assert relative_friction(amplitude, force) == pytest.approx(relative_friction_of_u(u)[0], abs=1e-9)


def test_bed_reaction_closed_form_mean():
    # g(s) closed form: the mean of the normalised reaction is 1 for any amplitude
    for v in (0.5, 1.0, 1.5, 10.0, 100.0):
        assert np.mean(bed_reaction(v, PHASE)) == pytest.approx(1.0, rel=1e-4)


@pytest.mark.parametrize("amplitude", [0.5, 3.0, 8.0])
def test_cycle_friction_averages_to_the_relative_friction(amplitude):
    # the mean of mu(F) F over a cycle, over mu(F_n) F_n at rest, is the relative coefficient (eq. 9)
    from ultraglide.render.physics.fingerprint import friction_force_n
    from ultraglide.render.physics.normal_contact import cycle_friction_n

    friction = cycle_friction_n(amplitude, 0.5, PHASE, HERTZ)
    assert np.mean(friction) / friction_force_n(0.5) == pytest.approx(relative_friction(amplitude, 0.5), abs=2e-4)


@pytest.mark.slow
def test_rigid_pad_reading_of_eq_8_differs_by_the_documented_amounts():
    # docs/physics.md quotes these numbers; both readings must satisfy eq. (7)
    from ultraglide.render.physics.normal_contact import rigid_hertz_reaction

    phase = (np.arange(512) + 0.5) / 512 * np.pi - np.pi / 2
    assert np.mean(rigid_hertz_reaction(3.0, phase)) == pytest.approx(1.0, abs=1e-9)
    u = np.array([1.4, 2.0, 4.0, 6.0])
    rigid = np.array([np.mean(np.maximum(rigid_hertz_reaction(x, phase), 0) ** (2 / 3)) for x in u])
    difference = relative_friction_of_u(u) - rigid
    assert difference == pytest.approx([0.0144, 0.0123, 0.0122, 0.0120], abs=3e-4)
    # zero amplitude: both are the plate at rest
    assert np.mean(rigid_hertz_reaction(0.0, phase)) == pytest.approx(1.0, abs=1e-12)
