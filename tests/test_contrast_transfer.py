"""``render.planning.contrast_transfer`` against a first-order lag worked out by hand."""

import cmath
import math

import pytest
from ultraglide.render.physics.dynamics import FrictionDynamics
from ultraglide.render.planning import contrast_transfer

RATE_HZ = 12000.0


@pytest.mark.parametrize("tau_s, period_mm, speed_mm_s", [(0.010, 1.0, 20.0), (0.005, 1.0, 100.0),
                                                          (0.020, 2.0, 50.0)])
def test_a_symmetric_lag_keeps_the_contrast_and_errs_as_a_first_order_low_pass(tau_s, period_mm, speed_mm_s):
    # onset = recovery, no speed law: the instantaneous renderer's felt ratio is the grating through one first-order
    # lag, each sample's value held for the sample and felt at its end: y[k] = a y[k-1] + (1 - a) u[k],
    # H(w) = (1 - a) e^{jwT} / (e^{jwT} - a), a = e^{-T/tau}. Its gain is 1 / sqrt(1 + (w tau)^2) to 4 digits here
    # (the continuous lag's: 0.623 for 20 Hz and 10 ms); the error is the grating's amplitude times |1 - H| / sqrt 2.
    floor = 0.2
    kept = contrast_transfer(FrictionDynamics(onset_s=tau_s, recovery_s=tau_s, speed_exponent=0.0), period_mm,
                             speed_mm_s, floor, RATE_HZ)
    omega = 2.0 * math.pi * speed_mm_s / period_mm
    step = 1.0 / RATE_HZ
    a = math.exp(-step / tau_s)
    z = cmath.exp(1j * omega * step)
    response = (1.0 - a) * z / (z - a)
    assert kept.instantaneous == pytest.approx(abs(response), abs=5e-4)
    assert kept.instantaneous == pytest.approx(1.0 / math.sqrt(1.0 + (omega * tau_s) ** 2), abs=2e-3)
    amplitude = (1.0 - floor) / 2.0
    assert kept.instantaneous_rms == pytest.approx(amplitude * abs(1.0 - response) / math.sqrt(2.0), abs=5e-4)
