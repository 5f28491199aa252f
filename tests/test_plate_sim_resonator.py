"""The simulated plate's envelope model against the resonator it stands for, driven with a signed drive (the
carrier in antiphase: the firmware's brake).

The reference is the plate as a mass on a spring, x'' + (w0 / Q) x' + w0^2 x = K u(t) cos(w0 t), integrated by
scipy's lsim (state-space, the carrier itself sampled 38 times a cycle), and demodulated cycle by cycle into its
phasor: the envelope model knows nothing of it. Braking past zero must build vibration in the opposite phase (a
larger amplitude, not a smaller one), as the resonator does."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lsim
from ultraglide.devices.sim.plate import SAMPLE_RATE_HZ, resonator_phasor

F0_HZ, Q, FULL_SCALE_UM_PP = 25000.0, 200.0, 8.0
TAU_S = Q / (math.pi * F0_HZ)  # 2.55 ms
OVERSAMPLE = 20  # the resonator's samples per drive sample: 960 kHz, 38.4 a carrier cycle


def resonator_envelope(drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and signed phasor (µm p-p, along a positive drive's steady phase) of the mass-spring plate driven
    at its resonance by ``drive`` (fractions of full scale, one value a drive sample), one value a carrier cycle."""
    w0 = 2 * math.pi * F0_HZ
    k = w0 ** 2 / Q * FULL_SCALE_UM_PP / 2  # steady zero-to-peak at full drive: K Q / w0^2 = half the p-p
    rate = SAMPLE_RATE_HZ * OVERSAMPLE
    t = np.arange(len(drive) * OVERSAMPLE) / rate
    force = np.repeat(drive, OVERSAMPLE) * np.cos(w0 * t)
    _, x, _ = lsim(([k], [1.0, w0 / Q, w0 ** 2]), force, t)
    per_cycle = rate / F0_HZ  # 38.4 samples: demodulate over 5 cycles (192 samples) at a time
    window = int(round(5 * per_cycle))
    starts = np.arange(0, len(t) - window, window)
    phasor = np.array([2 / window * np.sum(x[s:s + window] * np.exp(-1j * w0 * t[s:s + window])) for s in starts])
    # driven on resonance the steady response is sin(w0 t) = the phasor -j: along the drive's phase is Re(j Z)
    return t[starts] + window / 2 / rate, 2 * np.real(1j * phasor)


def test_a_signed_drive_moves_the_phasor_as_the_resonator_does_and_braking_past_zero_reverses_its_phase():
    n = SAMPLE_RATE_HZ // 1000
    drive = np.concatenate([np.full(3 * n, 0.5), np.full(2 * n, -0.75), np.zeros(3 * n)])  # push, brake, let ring
    decay = math.exp(-1 / (SAMPLE_RATE_HZ * TAU_S))
    model = resonator_phasor(drive, 0.0, decay, FULL_SCALE_UM_PP)
    t_true, true = resonator_envelope(drive)
    at = np.interp(t_true, (np.arange(len(drive)) + 0.5) / SAMPLE_RATE_HZ, model)
    np.testing.assert_allclose(at, true, atol=0.06)  # µm p-p, all along (0.75 % of full scale)
    # by hand: 4 µm x (1 - e^(-3 ms / tau)) = 2.77 µm after the push; the brake pulls it towards -6 µm and
    # through zero at tau ln((2.77 + 6) / 6) = 0.97 ms; 1.03 ms later it has grown to 2.0 µm in antiphase
    pushed = 4.0 * (1 - math.exp(-3e-3 / TAU_S))
    assert abs(model[3 * n - 1] - pushed) < 0.01
    crossing_s = TAU_S * math.log((pushed + 6.0) / 6.0)
    crossed = (np.flatnonzero(model < 0)[0] + 1) / SAMPLE_RATE_HZ - 3e-3
    assert abs(crossed - crossing_s) < 2 / SAMPLE_RATE_HZ
    reversed_um_pp = -6.0 + (pushed + 6.0) * math.exp(-2e-3 / TAU_S)
    assert abs(model[5 * n - 1] - reversed_um_pp) < 0.01 and reversed_um_pp < -1.9
    true_crossed = t_true[np.flatnonzero(true < 0)[0]] - 3e-3
    assert abs(true_crossed - crossing_s) < 0.15e-3  # the resonator agrees (to its 5-cycle demodulation)
    # the amplitude (the magnitude) dips to zero and rises again: braking too long is not a smaller amplitude
    amplitude = np.abs(model)
    low = int(np.argmin(amplitude[3 * n:5 * n])) + 3 * n
    assert amplitude[low] < 0.05 and amplitude[5 * n - 1] > 1.9


def test_the_phasor_from_a_state_in_opposite_phase_decays_by_tau_whatever_its_sign():
    decay = math.exp(-1 / (SAMPLE_RATE_HZ * TAU_S))
    free = resonator_phasor(np.zeros(SAMPLE_RATE_HZ // 100), -3.0, decay, FULL_SCALE_UM_PP)
    t = np.arange(1, len(free) + 1) / SAMPLE_RATE_HZ
    np.testing.assert_allclose(free, -3.0 * np.exp(-t / TAU_S), rtol=1e-9)
