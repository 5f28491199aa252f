"""Normal vibration: intermittent contact of the ridges and the friction it leaves (section IV).

A plate vibrating normally, z(t) = (a_pp / 2) sin(theta), theta = 2 pi f t, compresses a bed of
ridge springs of stiffness E_e / h_e per unit area. The finger bulk cannot follow an ultrasonic
plate (its viscoelastic retardation is taken as infinitely long), so it sits at a fixed mean height
chosen by the equilibrium of eq. (7): the reaction averaged over a cycle equals the applied load.
Once the amplitude exceeds the static compression the springs lose contact for part of each cycle.

Friction follows the non-Coulombic law of Fig. 7, friction force = mu_1N F^n with n < 1, applied to
the instantaneous reaction. Because F^n is concave, a load that swings about its mean gives less
mean friction than a steady one: this is the paper's mechanism, and its relative coefficient of
friction (Fig. 8) is mean(F_reac(t)^n) / F_n^n.

Choices where the paper is ambiguous (each tested in ``tests/test_normal_contact.py``):

* Eq. (9) as printed has the area element ``pi^2 dr``; the area of an annulus is ``2 pi r dr``.
* With the Hertzian profile (8), each annulus of radius r keeps its own time-mean pressure P(r):
  the slow finger pad has settled to the mean load everywhere, while the ridges see the fast
  vibration. Annuli detach from the periphery inwards, as the paper's discussion describes.
* "mu_d(F_react)" in eq. (9) is read as the coefficient at the instantaneous *total* reaction,
  the quantity Fig. 7 is measured against, so the friction force at each instant is
  mu_1N F_reac(t)^n.

Everything depends on amplitude and force only through u = a_pp / detach_amplitude_um_pp(F), the
amplitude relative to the detachment amplitude of eq. (6); the functions below work in u so
that a table over u serves every force.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from ultraglide.render.physics.fingerprint import FingerParams, detach_amplitude_um_pp, friction_force_n

_HERTZ_PEAK = 1.5  # peak of the Hertzian profile relative to the mean pressure, eq. (8)


def _mean_compression(offset):
    """g(s): cycle-mean of max(s + sin(theta), 0), the bed's mean load in units of k * amplitude."""
    s = np.asarray(offset, dtype=float)
    inner = np.clip(s, -1.0, 1.0)
    beta = np.arcsin(inner)
    partial = (inner * (np.pi + 2.0 * beta) + 2.0 * np.sqrt(1.0 - inner * inner)) / (2.0 * np.pi)
    return np.where(s >= 1.0, s, np.where(s <= -1.0, 0.0, partial))


def contact_offset(relative_amplitude):
    """s(v): mean spring compression in units of the vibration amplitude, solving eq. (7).

    ``relative_amplitude`` v is the zero-to-peak amplitude over the static compression. For v <= 1
    the springs never detach and s = 1/v; beyond, g(s) = 1/v is solved by Newton's method, which
    converges monotonically from s = 1 because g is convex and increasing.

    Parameters
    ----------
    relative_amplitude : array_like
        v, >= 0.

    Returns
    -------
    numpy.ndarray
        s.

    Examples
    --------
    >>> contact_offset([0.5, 1.0]).tolist()                              # never detached: 1 / v
    [2.0, 1.0]
    >>> s = contact_offset(2.0)                                            # detached: g(s) = 1 / v
    >>> round(float(_mean_compression(s)), 9)
    0.5
    """
    v = np.asarray(relative_amplitude, dtype=float)
    target = 1.0 / np.maximum(v, 1e-300)
    s = np.where(v <= 1.0, target, 1.0)
    detached = v > 1.0
    if np.any(detached):
        t = target[detached] if target.ndim else target
        x = np.ones_like(t)
        for _ in range(80):
            slope = (np.pi + 2.0 * np.arcsin(np.clip(x, -1.0, 1.0))) / (2.0 * np.pi)
            step = (_mean_compression(x) - t) / np.maximum(slope, 1e-300)
            x = np.maximum(x - step, -1.0)
            if np.max(np.abs(step)) < 1e-13:
                break
        if s.ndim:
            s[detached] = x
        else:
            s = x
    return s


def bed_reaction(relative_amplitude, phase_rad):
    """Reaction of a uniform bed over a cycle, in units of its mean (the applied load).

    ``relative_amplitude`` and ``phase_rad`` broadcast; the result averages to 1 over a cycle.

    Parameters
    ----------
    relative_amplitude : array_like
        v: the zero-to-peak amplitude over the static compression.
    phase_rad : array_like
        Phases of the vibration (rad).

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> bed_reaction(0.5, np.array([np.pi / 2, 3 * np.pi / 2])).tolist()    # attached: 1 ± v
    [1.5, 0.5]
    >>> import numpy as np
    >>> phase = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    >>> round(float(bed_reaction(3.0, phase).mean()), 6)                 # the load, on average
    1.0
    """
    v = np.asarray(relative_amplitude, dtype=float)
    sin_phase = np.sin(phase_rad)
    s = contact_offset(v)
    attached = 1.0 + v * sin_phase
    detached = v * np.maximum(s + sin_phase, 0.0)
    return np.where(v <= 1.0, attached, detached)


@lru_cache(maxsize=8)
def _gauss_legendre(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [-1, 1], read-only: an eigenproblem worth solving once
    (it was two fifths of a calibration fit's time when solved at every evaluation)."""
    nodes, weights = np.polynomial.legendre.leggauss(order)
    nodes.flags.writeable = False
    weights.flags.writeable = False
    return nodes, weights


def hertz_reaction(u, phase_rad, ring_nodes: int = 48):
    """Total reaction over a cycle of a Hertzian contact, in units of the applied load.

    With m = sqrt(1 - r²/b²) the pressure of eq. (8) is 1.5 m times the mean, the annulus weight
    2 pi r dr / (pi b²) becomes 2 m dm, and the local relative amplitude is u / (1.5 m). Annuli with
    m > u / 1.5 stay attached and integrate in closed form; the detached rim is integrated by
    Gauss–Legendre quadrature. ``u`` must be a scalar or broadcast against ``phase_rad``.

    Parameters
    ----------
    u : array_like
        Amplitude over the detachment amplitude, a_pp / W_c (eq. 6).
    phase_rad : array_like
        Phases of the vibration (rad).
    ring_nodes : int
        Quadrature nodes over the detached rim.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> import numpy as np
    >>> phase = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    >>> round(float(hertz_reaction(2.0, phase).mean()), 6)               # the load, on average (eq. 7)
    1.0
    """
    u = np.asarray(u, dtype=float)[..., None]
    phase = np.asarray(phase_rad, dtype=float)[..., None]
    sin_phase = np.sin(phase)
    rim = np.minimum(u / _HERTZ_PEAK, 1.0)  # m below which annuli detach
    attached = (1.0 - rim**3) + u * sin_phase * (1.0 - rim**2)
    nodes, weights = _gauss_legendre(int(ring_nodes))
    m = 0.5 * rim * (nodes + 1.0)  # shape (..., ring_nodes)
    w = 0.5 * rim * weights
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(m > 0, u / (_HERTZ_PEAK * m), 0.0)
    local = v * np.maximum(contact_offset(v) + sin_phase, 0.0)
    detached = np.sum(w * 3.0 * m * m * local, axis=-1)
    return attached[..., 0] + detached


def normalised_reaction(u, phase_rad, contact: str = "hertz"):
    """Total reaction over a cycle relative to the load, for either pressure profile.

    Parameters
    ----------
    u : array_like
        Amplitude over the detachment amplitude, a_pp / W_c (eq. 6).
    phase_rad : array_like
        Phases of the vibration (rad).
    contact : {"hertz", "uniform"}
        The pressure profile.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> import numpy as np
    >>> phase = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    >>> round(float(normalised_reaction(2.0, phase, "uniform").mean()), 6)
    1.0
    """
    if contact == "uniform":
        return bed_reaction(u, phase_rad)
    return hertz_reaction(u, phase_rad)


def cycle_reaction_n(amplitude_um_pp, force_n, phase_rad, params: FingerParams = FingerParams()):
    """Figs. 5 (uniform) and its Hertzian counterpart: plate reaction force over a cycle, N.

    Parameters
    ----------
    amplitude_um_pp : array_like
        Vibration amplitude (µm p-p).
    force_n : float
        The applied load (N).
    phase_rad : array_like
        Phases of the vibration (rad).
    params : FingerParams
        The finger (its contact: ``hertz`` or ``uniform``); the paper's Table I by default.

    Returns
    -------
    numpy.ndarray
        N.

    Examples
    --------
    >>> import numpy as np
    >>> phase = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    >>> cycle_reaction_n(0.0, 0.5, phase[:2]).tolist()                  # at rest: the load
    [0.5, 0.5]
    >>> round(float(cycle_reaction_n(2.0, 0.5, phase).mean()), 6)
    0.5
    """
    u = np.asarray(amplitude_um_pp, dtype=float) / detach_amplitude_um_pp(force_n, params)
    return force_n * normalised_reaction(u, phase_rad, params.contact)


def relative_friction_of_u(
    u, params: FingerParams = FingerParams(), phase_points: int = 512, ring_nodes: int = 48
):
    """Fig. 8 in normalised form: mean friction with vibration over friction at rest, for each u.

    The reaction depends on the phase only through sin(theta), so the cycle mean is taken over
    the midpoints of half a cycle (-pi/2, pi/2), which is Gauss–Chebyshev quadrature in sin(theta).

    Parameters
    ----------
    u : array_like
        Amplitude over the detachment amplitude, a_pp / W_c (eq. 6).
    params : FingerParams
        The finger (its contact: ``hertz`` or ``uniform``); the paper's Table I by default.
    phase_points : int
        Phases the cycle mean is taken over.
    ring_nodes : int
        Quadrature nodes over a Hertzian contact's detached rim.

    Returns
    -------
    numpy.ndarray
        The friction ratio at each u.

    Examples
    --------
    >>> relative_friction_of_u(np.array([0.0, 1.0, 4.0])).round(3)
    array([1.   , 0.944, 0.759])
    """
    u = np.atleast_1d(np.asarray(u, dtype=float))
    phase = (np.arange(phase_points) + 0.5) / phase_points * np.pi - np.pi / 2.0
    if params.contact == "uniform":
        reaction = bed_reaction(u[:, None], phase[None, :])
    else:
        reaction = hertz_reaction(u[:, None], phase[None, :], ring_nodes)
    ratio = np.mean(np.power(np.maximum(reaction, 0.0), params.friction_exponent), axis=1)
    return np.minimum(ratio, 1.0)


def relative_friction(amplitude_um_pp, force_n, params: FingerParams = FingerParams()):
    """Fig. 8: relative coefficient of friction F_l(a) / F_l(0), by direct integration (slow).

    Parameters
    ----------
    amplitude_um_pp : array_like
        Vibration amplitude (µm p-p).
    force_n : float
        Normal force (N).
    params : FingerParams
        The finger (its contact: ``hertz`` or ``uniform``); the paper's Table I by default.

    Returns
    -------
    numpy.ndarray
        The friction ratio, shaped as ``amplitude_um_pp``.

    Examples
    --------
    >>> relative_friction([0.0, 10.0], 0.5).round(3)                    # the paper's modest reduction
    array([1.   , 0.724])
    """
    amplitude = np.asarray(amplitude_um_pp, dtype=float)
    u = amplitude / detach_amplitude_um_pp(force_n, params)
    return relative_friction_of_u(u.ravel(), params).reshape(amplitude.shape)


def cycle_friction_n(amplitude_um_pp, force_n, phase_rad, params: FingerParams = FingerParams()):
    """Instantaneous friction force over a cycle under the non-Coulombic law, N.

    Parameters
    ----------
    amplitude_um_pp : array_like
        Vibration amplitude (µm p-p).
    force_n : float
        Normal force (N).
    phase_rad : array_like
        Phases of the vibration (rad).
    params : FingerParams
        The finger (its contact: ``hertz`` or ``uniform``); the paper's Table I by default.

    Returns
    -------
    numpy.ndarray
        N.

    Examples
    --------
    >>> cycle_friction_n(0.0, 1.0, np.array([0.0])).tolist()             # at rest, 1 N: mu_1N × 1 N
    [0.8]
    """
    return friction_force_n(cycle_reaction_n(amplitude_um_pp, force_n, phase_rad, params), params)


def rigid_hertz_reaction(u, phase_rad, ring_nodes: int = 256):
    """The other reading of eq. (8): the pad moves as one rigid body at a single mean height.

    Annulus m = sqrt(1 - r²/b²) is compressed 1.5 m (in units of the mean static compression) at
    rest; under vibration every annulus shares one offset d, solved so that the cycle-mean total
    reaction equals the load (eq. 7). Used to quantify the choice in ``docs/physics.md``; the model
    itself uses :func:`hertz_reaction` (each annulus settles to its own mean pressure).
    ``u`` is a scalar; returns the total reaction at each phase in units of the load.

    Parameters
    ----------
    u : array_like
        Amplitude over the detachment amplitude, a_pp / W_c (eq. 6).
    phase_rad : array_like
        Phases of the vibration (rad).
    ring_nodes : int
        Annuli the pad is integrated over.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> import numpy as np
    >>> phase = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    >>> round(float(rigid_hertz_reaction(2.0, phase).mean()), 6)         # the load, on average
    1.0
    """
    from scipy.optimize import brentq

    nodes, weights = _gauss_legendre(int(ring_nodes))
    m = 0.5 * (nodes + 1.0)
    w = 0.5 * weights * 2.0 * m  # area weight 2 m dm
    sin_phase = np.sin(np.asarray(phase_rad, dtype=float))[..., None]
    cycle = np.sin((np.arange(512) + 0.5) / 512 * np.pi - np.pi / 2.0)[:, None]

    def total(offset, s):
        return np.sum(w * np.maximum(_HERTZ_PEAK * m + offset + u * s, 0.0), axis=-1)

    offset = 0.0 if u == 0 else brentq(lambda d: np.mean(total(d, cycle)) - 1.0, -_HERTZ_PEAK - u, 1.0 + u,
                                       xtol=1e-14)
    return total(offset, sin_phase)
