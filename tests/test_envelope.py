"""The envelope's tests."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ultraglide.devices.profiles import load_profile
from ultraglide.render.envelope import EnvelopeChain
from ultraglide.render.errors import RenderError
from ultraglide.render.physics.friction_models import ExponentialModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures import procedural

RATE = 12000.0


def _chain(**overrides) -> EnvelopeChain:
    settings = dict(rate_hz=RATE, attack_s=1 / RATE, release_s=1 / RATE, band_hz=1e9, slew_um_per_ms=1e9,
                    limit_um_pp=6.0, time_constant_s=0.0025, drive_max_um_pp=8.0, precompensate=False)
    settings.update(overrides)
    return EnvelopeChain(**settings)


@pytest.mark.parametrize("band_hz", [0.5, 100.0, 400.0])
def test_the_band_limit_is_a_first_order_low_pass_with_its_corner_at_band_hz(band_hz):
    # a first-order low pass with corner fc answers a step with 1 - exp(-2 pi fc t); the slew limit is
    # out of the way, the gate opens in one sample, so the sample n (t = (n + 1) / rate) follows it exactly
    chain = _chain(band_hz=band_hz)
    amplitude = chain.process(np.full(1200, 3.0), True).amplitude_um_pp
    t = np.arange(1, 1201) / RATE
    np.testing.assert_allclose(amplitude, 3.0 * (1 - np.exp(-2 * np.pi * band_hz * t)), rtol=1e-9, atol=1e-12)


def test_the_limits_are_refused_with_their_own_words():
    with pytest.raises(RenderError) as ramp:
        _chain(attack_s=0.0)
    assert str(ramp.value) == "attack and release must be longer than 0 s"
    with pytest.raises(RenderError) as band:
        _chain(band_hz=0.0)
    assert str(band.value) == "band and slew limits must be positive"


def test_clipped_drive_samples_are_counted_exactly_and_add_up_over_blocks():
    chain = _chain(precompensate=True)
    chain.process(np.zeros(50), True)  # nothing asked: pre-compensation drives 0, nothing clipped
    assert chain.drive_clipped == 0
    chain.process(np.full(1200, 3.0), True)  # a step: the inverse asks for more than 8 µm at first
    rise = chain.drive_clipped
    assert rise > 0
    # the gate shuts in one sample: the amplitude falls to 0 at once, and the inverse of a plate still
    # ringing would be a negative drive, clipped to 0 on every one of the next 100 samples
    block = chain.process(np.full(100, 3.0), False)
    assert np.all(block.drive_um_pp == 0.0) and np.all(block.plate_um_pp > 0.0)
    assert chain.drive_clipped == rise + 100


def test_ramps_are_counted_over_blocks():
    chain = _chain()
    chain.process(np.full(10, 1.0), True)
    chain.process(np.full(10, 1.0), False)
    chain.process(np.full(10, 1.0), np.array([0, 0, 1, 1, 0, 0, 0, 0, 0, 0], bool))
    assert chain.ramps == 4  # open, close, then open and close again inside one block


def test_the_chain_is_at_rest_only_when_gate_smoother_and_plate_have_all_come_down():
    chain = _chain(release_s=0.01, precompensate=True)  # a release of 120 samples
    assert chain.at_rest is True
    chain.process(np.full(1200, 3.0), True)
    assert chain.at_rest is False
    chain.process(np.full(60, 3.0), False)  # half-way through the release: the gate is still closing
    assert chain.at_rest is False
    chain.process(np.full(1200, 3.0), False)  # 100 ms later: the plate (tau 2.5 ms) is long at rest
    assert chain.at_rest is True


def _slew_chain(**overrides) -> EnvelopeChain:
    settings = dict(rate_hz=RATE, attack_s=1 / RATE, release_s=1 / RATE, band_hz=5000.0, slew_um_per_ms=1.0,
                    limit_um_pp=6.0, time_constant_s=0.0025, drive_max_um_pp=8.0, precompensate=False)
    settings.update(overrides)
    return EnvelopeChain(**settings)


def test_slew_limit_bounds_every_step_and_is_reached():
    chain = _slew_chain()
    target = np.concatenate([np.full(2400, 6.0), np.zeros(2400)])  # full scale up, then down
    amplitude = chain.process(target, np.concatenate([np.ones(2400, bool), np.ones(2400, bool)])).amplitude_um_pp
    steps = np.abs(np.diff(np.concatenate([[0.0], amplitude])))
    bound = 1.0 * 1e3 / RATE  # 1 µm/ms at 12 kHz: 0.0833 µm a sample
    assert steps.max() <= bound * (1 + 1e-9)
    assert steps.max() == pytest.approx(bound, rel=1e-6)  # the first step from rest is exactly the bound
    # a one-pole smoother with k = bound / limit: 63 % of the way after 1/k samples, not after a 5 kHz corner
    k = bound / 6.0
    reached = np.argmax(amplitude >= 6.0 * (1 - np.exp(-1.0)))
    assert reached == pytest.approx(1 / k, abs=2)


def test_renderer_applies_a_slew_limit_it_is_given():
    texture = procedural.grating(2.0, size_mm=(80, 50), ratio_range=(0.5, 0.5))  # uniform: 0.5 everywhere
    path = RecordedTrajectory([0.0, 0.5], [10.0, 60.0], [25.0, 25.0])
    slew = 2.0  # µm/ms; the defaults (30 µm/ms) leave the band limit in charge
    settings = RenderSettings(slew_um_per_ms=slew, attack_s=1 / RATE, precompensate=False)
    renderer = Renderer(texture, ExponentialModel(), load_profile("sim-plate"), settings, trajectory=path)
    amplitude = renderer.control(600).amplitude_um_pp
    # the finger lands at t = 0: the target jumps from rest to A, and a one-pole smoother with
    # k = (slew / rate) / limit closes the gap geometrically, A (1 - (1 - k)^(n + 1))
    target = ExponentialModel().amplitude_um_pp(0.5).amplitude_um_pp
    k = slew * 1e3 / RATE / renderer.limit_um_pp
    expected = target * (1 - (1 - k) ** np.arange(1, 601))
    np.testing.assert_allclose(amplitude, expected, rtol=1e-6)
    assert np.abs(np.diff(amplitude)).max() <= slew * 1e3 / RATE


def _ramp_lengths(attack_s, release_s):
    chain = _chain(attack_s=attack_s, release_s=release_s, band_hz=1e9, slew_um_per_ms=1e9)
    gate = np.concatenate([np.ones(1200, bool), np.zeros(1200, bool)])
    amplitude = chain.process(np.full(2400, 4.0), gate).amplitude_um_pp
    rising = np.flatnonzero(amplitude[:1200] >= 4.0 - 1e-9)[0] + 1  # samples to full
    falling = np.flatnonzero(amplitude[1200:] <= 1e-9)[0] + 1  # samples to rest
    return rising, falling


def test_attack_opens_and_release_closes_in_their_own_times():
    rising, falling = _ramp_lengths(attack_s=0.002, release_s=0.007)
    assert rising == pytest.approx(0.002 * RATE, abs=1)
    assert falling == pytest.approx(0.007 * RATE, abs=1)
    rising, falling = _ramp_lengths(attack_s=0.008, release_s=0.001)
    assert rising == pytest.approx(0.008 * RATE, abs=1)
    assert falling == pytest.approx(0.001 * RATE, abs=1)


def test_renderer_passes_attack_and_release_through():
    texture = procedural.grating(2.0, size_mm=(80, 50), ratio_range=(0.5, 0.5))  # uniform: 0.5 everywhere
    path = RecordedTrajectory([0.0, 0.3], [10.0, 40.0], [25.0, 25.0])
    settings = RenderSettings(attack_s=0.003, release_s=0.012, band_hz=5000.0, slew_um_per_ms=1000.0,
                              precompensate=False)
    renderer = Renderer(texture, ExponentialModel(), load_profile("sim-plate"), settings, trajectory=path)
    amplitude = renderer.control(int(0.4 * RATE)).amplitude_um_pp
    full = amplitude[int(0.2 * RATE)]
    assert full == pytest.approx(ExponentialModel().amplitude_um_pp(0.5).amplitude_um_pp, rel=1e-3)
    rise = np.flatnonzero(amplitude >= 0.95 * full)[0] / RATE
    lifted = np.flatnonzero(amplitude[int(0.3 * RATE):] <= 0.05 * full)[0] / RATE
    assert rise == pytest.approx(0.95 * 0.003, abs=0.0006)  # the gate's linear ramp, a little smoothed
    assert lifted == pytest.approx(0.95 * 0.012, abs=0.0006)


@pytest.mark.parametrize("attack_s, release_s", [(0.0, 0.01), (0.005, 0.0), (-0.001, 0.01), (0.005, -0.001)])
def test_a_ramp_of_no_length_is_refused_alone(attack_s, release_s):
    with pytest.raises(RenderError, match="attack and release must be longer than 0 s"):
        _slew_chain(attack_s=attack_s, release_s=release_s)


@pytest.mark.parametrize("band_hz, slew", [(0.0, 30.0), (1000.0, 0.0), (-1.0, 30.0), (1000.0, -1.0)])
def test_a_band_or_slew_limit_of_zero_is_refused_alone(band_hz, slew):
    with pytest.raises(RenderError, match="band and slew limits must be positive"):
        _slew_chain(band_hz=band_hz, slew_um_per_ms=slew)


def test_the_envelope_pre_compensates_unless_told_not_to():
    """The plate's amplitude is a first-order low-pass of its drive (tau = 2.5 ms here), modelled apart from the
    chain with scipy's lfilter: pre-compensated, a 3 µm step is reached as fast as the 8 µm drive ceiling allows
    and held without overshoot; uncompensated, the plate creeps up with its own time constant."""
    from scipy.signal import lfilter

    tau_s, n = 0.0025, 240
    settings = dict(rate_hz=RATE, attack_s=1 / RATE, release_s=0.01, band_hz=1e9, slew_um_per_ms=1e9,
                    limit_um_pp=6.0, time_constant_s=tau_s, drive_max_um_pp=8.0)
    alpha = math.exp(-1 / (RATE * tau_s))

    def plate(drive):
        return lfilter([1 - alpha], [1, -alpha], drive)

    compensated = plate(EnvelopeChain(**settings).process(np.full(n, 3.0), True).drive_um_pp)
    plain = plate(EnvelopeChain(**settings, precompensate=False).process(np.full(n, 3.0), True).drive_um_pp)
    fastest = math.ceil(math.log(1 - 3.0 / 8.0) / math.log(alpha))  # samples of 8 µm drive to lift it to 3 µm
    reached = int(np.flatnonzero(compensated >= 3.0 - 1e-9)[0]) + 1
    assert reached == fastest
    assert np.allclose(compensated[reached:], 3.0, atol=1e-9) and compensated.max() <= 3.0 + 1e-9
    assert plain[int(tau_s * RATE)] == pytest.approx(3.0 * (1 - math.exp(-1)), rel=0.05)  # 63 % at tau
