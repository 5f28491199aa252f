"""The envelope chain's survivors of scripts/mutation.sh, killed: the band limit's corner, the clip and
ramp counters over several blocks, and when the chain is at rest. Each test was checked against its mutant."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.render.envelope import EnvelopeChain
from ultraglide.render.errors import RenderError

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
