"""What drive headroom buys: the -3 dB corner of the plate following a sine target, by max_drive / limit.

Run: .venv/bin/python bench/bench_headroom.py
A target amplitude swinging sinusoidally by ±10 % of the limit around a mean level goes through
the renderer's pre-compensation (drive clipped to [0, max_drive]) and the output stage's limiter
(which keeps a plate with half the profile's Q within the limit), then a first-order plate with the
profile's own Q (scipy.signal.lfilter). The gain is the plate's swing at the target's frequency over
the target's; the corner is where it falls to -3 dB. Without pre-compensation the corner is f0 / 2Q.

The drive can push the envelope up only as far as its ceiling and pull it down no faster than the
plate's free decay (drive 0), and the limiter stops a Q/2 plate at the limit: so headroom helps
targets in the upper part of the range, and a target touching the limit is barely helped at all.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal
from ultraglide.devices.output.limiter import DriveLimiter
from ultraglide.devices.profiles import PlateProfile
from ultraglide.render.envelope import EnvelopeChain

CONTROL_HZ = 12000.0
LIMIT_UM_PP = 6.0
FREQUENCIES_HZ = np.geomspace(10.0, 3000.0, 60)


def gain(profile: PlateProfile, frequency_hz: float, mean_um_pp: float, precompensate: bool) -> float:
    """The plate's swing at ``frequency_hz`` over the target's, for a target of ``mean_um_pp`` ± 10 % of the limit."""
    cycles = max(8, math.ceil(frequency_hz * 0.1))
    n = int(round(cycles / frequency_hz * CONTROL_HZ))
    t = np.arange(n) / CONTROL_HZ
    target = mean_um_pp - 0.1 * profile.max_amplitude_um_pp * np.cos(2 * np.pi * frequency_hz * t)
    chain = EnvelopeChain(CONTROL_HZ, 1e-4, 1e-4, 5000.0, 1e6, profile.max_amplitude_um_pp, profile.time_constant_s,
                          profile.max_drive_um_pp, precompensate)
    settle = np.full(int(0.05 * CONTROL_HZ), mean_um_pp - 0.1 * profile.max_amplitude_um_pp)
    chain.process(settle, True)
    limiter = DriveLimiter(profile, CONTROL_HZ)
    limiter.process(settle)  # the same history as the chain's
    drive = limiter.process(chain.process(target, True).drive_um_pp)
    alpha = math.exp(-1 / (CONTROL_HZ * profile.time_constant_s))
    plate = signal.lfilter([1 - alpha], [1, -alpha], drive, zi=[alpha * settle[-1]])[0]
    half = slice(n // 2, n)  # the second half: settled
    probe = np.exp(-2j * np.pi * frequency_hz * t[half])
    return abs(np.sum(plate[half] * probe)) / abs(np.sum(target[half] * probe))


def corner_hz(profile: PlateProfile, mean_um_pp: float, precompensate: bool = True) -> float:
    gains = np.array([gain(profile, f, mean_um_pp, precompensate) for f in FREQUENCIES_HZ])
    below = np.flatnonzero(gains < 1 / math.sqrt(2))
    if not len(below):
        return math.inf
    i = below[0]
    if i == 0:
        return FREQUENCIES_HZ[0]
    # interpolate in log frequency between the last point above and the first below
    g0, g1 = 20 * np.log10(gains[i - 1]), 20 * np.log10(gains[i])
    f0, f1 = np.log10(FREQUENCIES_HZ[i - 1]), np.log10(FREQUENCIES_HZ[i])
    return float(10 ** (f0 + (-3.0103 - g0) * (f1 - f0) / (g1 - g0)))


MEANS = (0.3, 0.5, 0.7, 0.9)  # of the limit


def main() -> None:
    print(f"{'max_drive / limit':>17} " + " ".join(f"{f'target {m:.1f}±0.1 L':>17}" for m in MEANS))
    plain = PlateProfile("bench", 25000.0, 200.0, 4 * LIMIT_UM_PP, LIMIT_UM_PP)
    print(f"{'no pre-comp':>17} " + " ".join(f"{corner_hz(plain, m * LIMIT_UM_PP, False):14.0f} Hz" for m in MEANS))
    for ratio in (1.0, 4 / 3, 2.0, 4.0):
        profile = PlateProfile("bench", 25000.0, 200.0, 4 * LIMIT_UM_PP, LIMIT_UM_PP,
                               max_drive_um_pp=ratio * LIMIT_UM_PP)
        print(f"{ratio:17.2f} " + " ".join(f"{corner_hz(profile, m * LIMIT_UM_PP):14.0f} Hz" for m in MEANS))
    print(f"(f0 = 25 kHz, Q = 200: tau = {plain.time_constant_s * 1e3:.2f} ms, plain corner f0/2Q = "
          f"{plain.corner_hz:.1f} Hz; limit L = {LIMIT_UM_PP:g} µm p-p; the limiter guards a plate of Q/2)")


if __name__ == "__main__":
    main()
