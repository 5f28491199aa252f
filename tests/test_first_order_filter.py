"""The first-order filter the simulated plate and the friction estimator use, against scipy.signal.lfilter
(an independent implementation) and against the closed form of its step response."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter
from ultraglide.devices.output.kernels import first_order_filter


def test_a_step_rises_as_the_closed_form_says():
    alpha = 0.9
    y, zf = first_order_filter([1 - alpha], [1.0, -alpha], np.ones(50), zi=[0.0])
    n = np.arange(50)
    assert np.allclose(y, 1 - alpha ** (n + 1), rtol=0, atol=1e-12)
    assert zf[0] == pytest.approx(alpha * y[-1])  # the state carried: alpha y[n], the next output's memory


@pytest.mark.parametrize("b, a", [([0.3], [1.0, -0.7]), ([0.2, 0.2], [1.0, -0.6]), ([1.0, 0.0], [1.0, 0.0]),
                                  ([0.5, -0.25], [1.0, 0.4])])
def test_it_matches_lfilter_in_one_and_two_dimensions_and_across_blocks(b, a):
    rng = np.random.default_rng(3)
    x = rng.normal(size=(3, 400))
    zi = rng.normal(size=(3, 1))
    expected, expected_zf = lfilter(b, a, x, axis=1, zi=zi)
    got, zf = first_order_filter(b, a, x, zi=zi)
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12) and np.allclose(zf, expected_zf, rtol=1e-12, atol=1e-12)
    # one row in two blocks, the state carried between them, is the whole row at once
    first, state = first_order_filter(b, a, x[0, :150], zi=zi[0])
    second, _ = first_order_filter(b, a, x[0, 150:], zi=state)
    assert np.allclose(np.concatenate((first, second)), expected[0], rtol=1e-12, atol=1e-12)
    # one row with its state as a list of one (the simulated plate's blocks): the same, the state as a list's array
    row, state = first_order_filter(b, a, x[1], zi=[float(zi[1, 0])])
    assert np.allclose(row, expected[1], rtol=1e-12, atol=1e-12) and state.shape == (1,)
    assert state[0] == pytest.approx(expected_zf[1, 0], rel=1e-12, abs=1e-12)
