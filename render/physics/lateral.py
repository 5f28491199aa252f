"""Lateral vibration: stick–slip of the ridge springs in the time domain (paper section III.C).

The finger bulk does not follow an ultrasonic plate, so the ridges (a tangential spring k_t) are
sheared by the plate's lateral motion x(t) = (a_pp / 2) sin(2 pi f t). The springs stick to the
plate until their force exceeds mu_s F_n (eq. 4), then slide at the kinetic force mu_d F_n until
the plate's velocity reverses (relative velocity zero, Fig. 2), where they stick again.
The springs are massless, as in the paper, so during a slide their force is exactly mu_d F_n.

This is offline physics for figures and checks, not the real-time path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ultraglide.render.physics.fingerprint import M_TO_UM, FingerParams, tangential_stiffness_n_per_m


@dataclass(frozen=True)
class LateralCycle:
    """Time series of a lateral stick–slip simulation; SI units."""

    time_s: np.ndarray
    plate_position_m: np.ndarray
    plate_velocity_m_per_s: np.ndarray
    lateral_force_n: np.ndarray  # force of the ridge springs on the plate
    sliding: np.ndarray  # bool: ridges slide on the plate at this step

    @property
    def slid(self) -> bool:
        """True when the ridges slipped at least once."""
        return bool(self.sliding.any())


def simulate_lateral(
    amplitude_um_pp: float,
    force_n: float,
    frequency_hz: float = 20e3,
    cycles: int = 3,
    steps_per_cycle: int = 4000,
    params: FingerParams = FingerParams(),
) -> LateralCycle:
    """Simulate stick–slip from rest (springs unstretched, plate at its centre) for ``cycles``."""
    if amplitude_um_pp < 0 or force_n <= 0 or frequency_hz <= 0 or cycles < 1:
        raise ValueError("amplitude must be >= 0, force and frequency > 0, cycles >= 1")
    k_t = float(tangential_stiffness_n_per_m(force_n, params))
    stick_limit = params.static_friction * force_n
    slide_force = params.dynamic_friction * force_n
    n = cycles * steps_per_cycle + 1
    time_s = np.arange(n) / (steps_per_cycle * frequency_hz)
    omega = 2.0 * np.pi * frequency_hz
    amplitude_m = amplitude_um_pp / 2.0 / M_TO_UM
    position = amplitude_m * np.sin(omega * time_s)
    velocity = amplitude_m * omega * np.cos(omega * time_s)

    force = np.zeros(n)
    sliding = np.zeros(n, dtype=bool)
    spring_force = 0.0
    slide_direction = 0.0  # sign of the force while sliding, 0 while stuck
    for i in range(1, n):  # an event-driven state machine; inherently sequential
        if slide_direction != 0.0 and np.sign(velocity[i]) == slide_direction:
            sliding[i] = True  # still sliding: the plate keeps moving away
        else:
            slide_direction = 0.0
            spring_force += k_t * (position[i] - position[i - 1])
            if abs(spring_force) > stick_limit:
                slide_direction = float(np.sign(spring_force))
                spring_force = slide_direction * slide_force
                sliding[i] = True
        force[i] = spring_force
    return LateralCycle(time_s, position, velocity, force, sliding)


def simulated_glide_threshold_um_pp(
    force_n: float,
    params: FingerParams = FingerParams(),
    tolerance_um: float = 1e-3,
) -> float:
    """The smallest amplitude (µm p-p) whose simulation from rest slips at all, by bisection.

    This is the numerical route of Fig. 3a; it agrees with the closed form of eq. (5),
    :func:`render.physics.fingerprint.glide_threshold_um_pp`.
    """
    low, high = 0.0, 1.0
    while simulate_lateral(high, force_n, cycles=1, steps_per_cycle=2000, params=params).slid is False:
        high *= 2.0
        if high > 1e4:
            raise ValueError("no slip below 10 mm: check the parameters")
    while high - low > tolerance_um:
        middle = 0.5 * (low + high)
        if simulate_lateral(middle, force_n, cycles=1, steps_per_cycle=2000, params=params).slid:
            high = middle
        else:
            low = middle
    return 0.5 * (low + high)


def steady_glide_threshold_um_pp(force_n, params: FingerParams = FingerParams()):
    """Amplitude (µm p-p) that keeps slipping every half cycle once slip has begun.

    After a slide the springs hold mu_d F_n; the plate's return stroke of a_pp must then reach
    -mu_s F_n, so a_pp > (mu_s + mu_d) F_n / k_t.
    """
    force = np.asarray(force_n, dtype=float)
    k_t = tangential_stiffness_n_per_m(force, params)
    return (params.static_friction + params.dynamic_friction) * force / k_t * M_TO_UM
