"""The carrier's tests."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.carrier import Carrier, check_carrier


def expected_sine(carrier_hz: float, rate_hz: float, start: int, frames: int) -> np.ndarray:
    """sin(2 pi f n / fs) for samples start .. start + frames - 1, in float64, phase reduced exactly."""
    n = np.arange(start, start + frames, dtype=np.float64)
    return np.sin(2 * np.pi * ((carrier_hz * n) % rate_hz) / rate_hz)


def test_a_carrier_up_to_four_tenths_of_the_rate_is_carried_and_above_it_is_refused_saying_what_rate_would():
    check_carrier(38400.0, 96000.0)  # exactly 0.4 fs
    Carrier(38400.0, 96000.0)
    with pytest.raises(DeviceError) as refused:
        check_carrier(38500.0, 96000.0)
    # 38500 Hz / 0.4 = 96250 Hz
    assert str(refused.value) == ("a 38500 Hz carrier needs a sample rate of at least 96,250 Hz (got 96,000 Hz); "
                                  "use 96000 or 192000")
    with pytest.raises(DeviceError, match="at least 62,500 Hz"):
        Carrier(25000.0, 48000.0)


@pytest.mark.parametrize("carrier_hz", [0.0, -25000.0, float("nan")])
def test_a_carrier_that_is_not_a_positive_frequency_is_refused(carrier_hz):
    with pytest.raises(DeviceError, match=r"^the carrier must be a positive frequency, got .* Hz$"):
        Carrier(carrier_hz, 96000.0)


# (carrier, rate) -> samples in one exact period: fs / gcd(f, fs), or f's denominator over it for a
# fractional f (23456.7 Hz = 234567 / 10 Hz: 960000 / gcd(234567, 960000) = 960000 / 3)
PERIODS = {(25000.0, 96000.0): 96, (24000.0, 96000.0): 4, (18000.0, 48000.0): 8, (23456.7, 96000.0): 320000,
           (1.0, float(1 << 20)): 1 << 20}


@pytest.mark.parametrize(("carrier_hz", "rate_hz"), list(PERIODS))
def test_an_exact_carrier_repeats_after_the_rate_over_the_gcd_samples(carrier_hz, rate_hz):
    carrier = Carrier(carrier_hz, rate_hz)
    assert carrier.period == PERIODS[carrier_hz, rate_hz]
    frames = min(carrier.period, 5000) + 7
    np.testing.assert_allclose(carrier.block(frames), expected_sine(carrier_hz, rate_hz, 0, frames), atol=1e-6)
    assert carrier.offset == frames % carrier.period


@pytest.mark.parametrize(("carrier_hz", "rate_hz"), [(25000.123456, 96000.0), (1.0, float(1 << 21))])
def test_a_carrier_without_a_short_exact_period_keeps_a_phase_accumulator(carrier_hz, rate_hz):
    """25000.123456 Hz is no fraction of denominator 1000 or less; 1 Hz at 2^21 Hz repeats only after
    2^21 samples, more than a 2^20-sample table."""
    carrier = Carrier(carrier_hz, rate_hz)
    assert carrier.period == 0
    out = np.full(3000, 9.0, dtype=np.float32)
    got = carrier.block(3000, out)
    assert got is out  # written into the caller's buffer
    np.testing.assert_allclose(out, expected_sine(carrier_hz, rate_hz, 0, 3000), atol=2e-6)
    fresh = carrier.block(500)  # without a buffer: a new one, continuing the phase
    np.testing.assert_allclose(fresh, expected_sine(carrier_hz, rate_hz, 3000, 500), atol=2e-6)
    assert carrier.phase == pytest.approx((3500 * carrier_hz / rate_hz) % 1.0, abs=1e-9)


@pytest.mark.parametrize("carrier_hz", [25000.0, 25000.123456])
def test_blocks_much_longer_than_the_period_continue_it_sample_for_sample(carrier_hz):
    carrier = Carrier(carrier_hz, 96000.0)
    start = 0
    for frames in (1, 95, 97, 200, 1000, 96, 5000, 13, 40000, 3):
        block = carrier.block(frames)
        assert block.shape == (frames,) and block.dtype == np.float32
        np.testing.assert_allclose(block, expected_sine(carrier_hz, 96000.0, start, frames), atol=2e-6)
        start += frames


def test_spans_of_an_exact_carrier_are_its_one_period_and_the_exact_offset_into_it():
    carrier = Carrier(25000.0, 96000.0)
    start = 0
    for frames in (10, 96, 1, 250, 31):
        table, offset = carrier.span(frames)
        assert len(table) == 96 and offset == start % 96
        k = np.arange(frames)
        np.testing.assert_allclose(table[(offset + k) % len(table)], expected_sine(25000.0, 96000.0, start, frames),
                                   atol=1e-6)
        start += frames
    assert carrier.offset == start % 96
    np.testing.assert_allclose(carrier.block(5), expected_sine(25000.0, 96000.0, start, 5), atol=1e-6)  # and on


def test_spans_of_an_accumulated_carrier_are_its_samples_from_offset_zero():
    carrier = Carrier(25000.123456, 96000.0)
    out = np.empty(700, dtype=np.float32)
    table, offset = carrier.span(700, out)
    assert table is out and offset == 0
    np.testing.assert_allclose(table, expected_sine(25000.123456, 96000.0, 0, 700), atol=2e-6)
    table, offset = carrier.span(300)
    assert offset == 0
    np.testing.assert_allclose(table, expected_sine(25000.123456, 96000.0, 700, 300), atol=2e-6)
