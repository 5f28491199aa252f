"""Lateral vibration: stick–slip of the ridge springs in the time domain (paper section III.C).

The finger bulk does not follow an ultrasonic plate, so the ridges (a tangential spring k_t) are
sheared by the plate's lateral motion x(t) = (a_pp / 2) sin(2 pi f t). The springs stick to the
plate until their force exceeds mu_s F_n (eq. 4), then slide at the kinetic force mu_d F_n until
the plate's velocity reverses (relative velocity zero, Fig. 2), where they stick again.
The springs are massless, as in the paper, so during a slide their force is exactly mu_d F_n.

The finger may hold a tangential preload T on the plate (the paper's "small tangential force",
left out there because it was not measured): the springs then start stretched to T, and slip
comes first on T's side. With T = 0.1 N at 0.4 N (:data:`PSYCHOPHYSICS_PRELOAD_N`) the model
reproduces the paper's psychophysics: no slip at 2 µm p-p, slip at 4 µm p-p.

The analysis is quasi-static: a frequency close to the ridge layer's shear resonance
(:func:`render.physics.fingerprint.ridge_shear_resonance_hz`) makes it an estimate, and
:func:`simulate_lateral` says so (a :class:`QuasiStaticWarning`, once per frequency).

This is offline physics for figures and checks, not the real-time path.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from ultraglide.render.physics.errors import QuasiStaticWarning
from ultraglide.render.physics.fingerprint import (
    M_TO_UM,
    FingerParams,
    quasi_static_warning,
    tangential_stiffness_n_per_m,
)

PSYCHOPHYSICS_FORCE_N = 0.4  # the paper's section III.D: "about 0.4 N"
PSYCHOPHYSICS_CARRIER_HZ = 27.83e3  # its Langevin actuator's resonance
PSYCHOPHYSICS_PRELOAD_N = 0.1  # the tangential preload we state: a quarter of mu_s F_n at 0.4 N


@dataclass(frozen=True)
class LateralCycle:
    """Time series of a lateral stick–slip simulation; SI units.

    Examples
    --------
    One cycle at 5 kHz, 6 µm p-p under 0.4 N: the finger slides, and the lateral force never passes the static
    limit mu_s F_n (0.4 N):

    >>> cycle = simulate_lateral(6.0, 0.4, frequency_hz=5000.0, cycles=1, steps_per_cycle=400)
    >>> cycle.time_s.shape, cycle.slid, bool(abs(cycle.lateral_force_n).max() <= 0.4)
    ((401,), True, True)
    """

    time_s: np.ndarray
    plate_position_m: np.ndarray
    plate_velocity_m_per_s: np.ndarray
    lateral_force_n: np.ndarray  # force of the ridge springs on the plate
    sliding: np.ndarray  # bool: ridges slide on the plate at this step

    @property
    def slid(self) -> bool:
        """True when the ridges slipped at least once.

        Examples
        --------
        0.01 µm p-p under 2 N: the ridges stick throughout:

        >>> simulate_lateral(0.01, 2.0, frequency_hz=5000.0, cycles=1, steps_per_cycle=400).slid
        False
        """
        return bool(self.sliding.any())


def simulate_lateral(
    amplitude_um_pp: float,
    force_n: float,
    frequency_hz: float = 20e3,
    cycles: int = 3,
    steps_per_cycle: int = 4000,
    params: FingerParams = FingerParams(),
    preload_n: float = 0.0,
) -> LateralCycle:
    """Simulate stick–slip from rest (springs holding the tangential preload ``preload_n``, N,
    plate at its centre) for ``cycles``.

    Parameters
    ----------
    amplitude_um_pp : float
        The plate's lateral amplitude (µm p-p), >= 0.
    force_n : float
        Normal force (N), > 0.
    frequency_hz : float
        The vibration's frequency (Hz); above the quasi-static limit a QuasiStaticWarning says so.
    cycles : int
        How many cycles, 1 or more.
    steps_per_cycle : int
        Time steps per cycle.
    params : FingerParams
        The finger; the paper's Table I by default.
    preload_n : float
        The tangential preload (N), below mu_s F_n.

    Returns
    -------
    LateralCycle

    Raises
    ------
    ValueError
        An amplitude, force, frequency, cycle count or preload out of range.

    Examples
    --------
    >>> simulate_lateral(3.0, 0.4, frequency_hz=5000.0).slid, simulate_lateral(6.0, 0.4, frequency_hz=5000.0).slid
    (False, True)
    """
    if amplitude_um_pp < 0 or force_n <= 0 or frequency_hz <= 0 or cycles < 1:
        raise ValueError("amplitude must be >= 0, force and frequency > 0, cycles >= 1")
    if not 0.0 <= abs(preload_n) < params.static_friction * force_n:
        raise ValueError(f"the tangential preload must be below mu_s F_n = {params.static_friction * force_n:g} N "
                         f"(beyond it the finger slides already), got {preload_n}")
    problem = quasi_static_warning(frequency_hz, params)
    if problem:
        warnings.warn(problem, QuasiStaticWarning, stacklevel=2)
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
    spring_force = float(preload_n)
    force[0] = spring_force
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
    preload_n: float = 0.0,
    frequency_hz: float = 20e3,
) -> float:
    """The smallest amplitude (µm p-p) whose simulation from rest slips at all, by bisection.

    This is the numerical route of Fig. 3a; it agrees with the closed form of eq. (5),
    :func:`render.physics.fingerprint.glide_threshold_um_pp` (with the same preload).

    Parameters
    ----------
    force_n : float
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.
    tolerance_um : float
        The bisection's tolerance (µm).
    preload_n : float
        The tangential preload (N).
    frequency_hz : float
        The vibration's frequency (Hz).

    Returns
    -------
    float
        µm p-p.

    Examples
    --------
    >>> from ultraglide.render.physics.fingerprint import glide_threshold_um_pp
    >>> round(simulated_glide_threshold_um_pp(0.4, frequency_hz=5000.0), 2), round(float(glide_threshold_um_pp(0.4)), 2)
    (4.48, 4.48)
    """
    def slips(amplitude: float) -> bool:
        return simulate_lateral(amplitude, force_n, frequency_hz, cycles=1, steps_per_cycle=2000, params=params,
                                preload_n=preload_n).slid

    low, high = 0.0, 1.0
    while not slips(high):
        high *= 2.0
        if high > 1e4:
            raise ValueError("no slip below 10 mm: check the parameters")
    while high - low > tolerance_um:
        middle = 0.5 * (low + high)
        if slips(middle):
            high = middle
        else:
            low = middle
    return 0.5 * (low + high)


def steady_glide_threshold_um_pp(force_n, params: FingerParams = FingerParams()):
    """Amplitude (µm p-p) that keeps slipping every half cycle once slip has begun.

    After a slide the springs hold mu_d F_n; the plate's return stroke of a_pp must then reach
    -mu_s F_n, so a_pp > (mu_s + mu_d) F_n / k_t.

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray or float
        µm p-p.

    Examples
    --------
    >>> from ultraglide.render.physics.fingerprint import glide_threshold_um_pp
    >>> ratio = float(steady_glide_threshold_um_pp(0.4) / glide_threshold_um_pp(0.4))   # (mu_s + mu_d) / (2 mu_s)
    >>> round(ratio, 6)
    0.85
    """
    force = np.asarray(force_n, dtype=float)
    k_t = tangential_stiffness_n_per_m(force, params)
    return (params.static_friction + params.dynamic_friction) * force / k_t * M_TO_UM
