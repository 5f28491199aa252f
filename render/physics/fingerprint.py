"""The fingerprint-ridge model of Vezzoli et al. (World Haptics 2015), equations (1)–(6).

The finger-pad ridges are a bed of elastic springs whose contact area grows with the normal
force. Everything here is a pure function of a normal force and one immutable
:class:`FingerParams`; forces in newtons, stiffness in N/m, areas in m² unless a name says mm²,
and amplitudes in micrometres **peak-to-peak** (see ``docs/physics.md``).

Examples
--------
>>> from ultraglide.render.physics.fingerprint import FingerParams, detach_amplitude_um_pp
>>> round(float(detach_amplitude_um_pp(0.15, FingerParams())), 2)
1.15
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

MM2_TO_M2 = 1e-6
M_TO_UM = 1e6


@dataclass(frozen=True)
class FingerParams:
    """Parameters of the finger model; defaults are the paper's Table I, its eq. (3) fit and its mu_s, mu_d
    (section III.C). The friction exponent n and mu at 1 N are ours: the paper's text gives Fig. 7 as a curve, no n.

    ``density_kg_m3`` (Table I) does not enter the paper's quasi-static model, which neglects ridge
    inertia; it sets the ridge layer's shear resonance (:func:`ridge_shear_resonance_hz`), which
    says at which carriers that quasi-static reading fails. ``max_contact_area_mm2`` caps eq. (3):
    k F^(2/3) passes an adult index fingertip's pad (about 20 × 16 mm, 250 mm²) at 2.4 N, and a
    pad cannot touch more than itself.

    Examples
    --------
    >>> params = FingerParams()
    >>> params.youngs_modulus_pa, params.static_friction, params.dynamic_friction
    (1000000.0, 1.0, 0.7)
    """

    youngs_modulus_pa: float = 1.0e6  # E_e, stratum corneum (Table I, i)
    poisson_ratio: float = 0.4  # nu (Table I, ii)
    ridge_height_m: float = 150e-6  # h_e (Table I, iii)
    density_kg_m3: float = 900.0  # rho (Table I, iv); the ridge layer's shear resonance
    area_coefficient_mm2: float = 138.1  # k in A = k F^(2/3), mm²/N^(2/3), eq. (3)
    area_exponent: float = 2.0 / 3.0  # the 2/3 of eq. (3)
    static_friction: float = 1.0  # mu_s, section III.C
    dynamic_friction: float = 0.7  # mu_d, section III.C
    # Non-Coulombic law mu(F) = mu_1N * F^(n-1), our power-law reading of Fig. 7 (whose caption cites the
    # paper's ref. [11]; its text cites ref. [12], Dzidek et al. 2014, for mu falling with force). n = 2/3,
    # friction growing as F^n as for Hertzian asperities, is our choice (after Adams et al. 2013 and Dzidek
    # et al. 2014, not checked against them): the paper's text states no n.
    friction_exponent: float = 2.0 / 3.0  # n
    friction_coefficient_at_1n: float = 0.8  # mu at 1 N; 1.0 at 0.5 N, typical of moist fingers
    contact: str = "hertz"  # pressure profile for eq. (9): "hertz" (eq. 8) or "uniform"
    max_contact_area_mm2: float = 250.0  # a fingertip's pad; eq. (3) is held here (see above)

    def __post_init__(self) -> None:
        positive = {
            "youngs_modulus_pa": self.youngs_modulus_pa,
            "ridge_height_m": self.ridge_height_m,
            "area_coefficient_mm2": self.area_coefficient_mm2,
            "area_exponent": self.area_exponent,
            "static_friction": self.static_friction,
            "dynamic_friction": self.dynamic_friction,
            "friction_exponent": self.friction_exponent,
            "friction_coefficient_at_1n": self.friction_coefficient_at_1n,
            "density_kg_m3": self.density_kg_m3,
            "max_contact_area_mm2": self.max_contact_area_mm2,
        }
        for name, value in positive.items():
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"finger parameter {name} must be a positive number, got {value}")
        if not -1.0 < self.poisson_ratio < 0.5:
            raise ValueError(f"poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio}")
        if self.friction_exponent > 1:
            raise ValueError("friction_exponent n must be <= 1 (n = 1 is Coulomb friction)")
        if self.dynamic_friction > self.static_friction:
            raise ValueError("dynamic_friction must not exceed static_friction")
        if self.contact not in ("hertz", "uniform"):
            raise ValueError(f"contact must be 'hertz' or 'uniform', got {self.contact!r}")

    def with_(self, **changes: float | str) -> FingerParams:
        """A copy with some parameters changed.

        Parameters
        ----------
        **changes : float or str
            Fields and their new values (SI units, as the fields are named).

        Returns
        -------
        FingerParams

        Examples
        --------
        >>> stiffer = FingerParams().with_(youngs_modulus_pa=2e6)
        >>> stiffer.youngs_modulus_pa, stiffer.poisson_ratio == FingerParams().poisson_ratio
        (2000000.0, True)
        """
        return replace(self, **changes)


def contact_area_mm2(force_n, params: FingerParams = FingerParams()):
    """Eq. (3): apparent contact area A = k F^(2/3) of the ridges, mm², at most a fingertip's
    (``max_contact_area_mm2``).

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray or float
        mm².

    Examples
    --------
    >>> float(contact_area_mm2(1.0)), float(contact_area_mm2(10.0))       # k at 1 N; a whole pad at 10 N
    (138.1, 250.0)
    """
    area = params.area_coefficient_mm2 * np.power(force_n, params.area_exponent)
    return np.minimum(area, params.max_contact_area_mm2)


def area_saturation_force_n(params: FingerParams = FingerParams()) -> float:
    """The force (N) at which eq. (3) reaches a fingertip's whole pad; above it the area is held.

    Parameters
    ----------
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    float
        N: (A_max / k)^(1 / area exponent).

    Examples
    --------
    >>> round(area_saturation_force_n(), 3)                             # (250 / 138.1)^1.5
    2.436
    """
    return float((params.max_contact_area_mm2 / params.area_coefficient_mm2) ** (1.0 / params.area_exponent))


def shear_modulus_pa(params: FingerParams = FingerParams()) -> float:
    """Eq. (2): G_e = E_e / (2 (1 + nu)), Pa.

    Parameters
    ----------
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    float
        Pa.

    Examples
    --------
    >>> round(shear_modulus_pa())                                       # 1 MPa / 2.8
    357143
    """
    return params.youngs_modulus_pa / (2.0 * (1.0 + params.poisson_ratio))


def normal_stiffness_n_per_m(force_n, params: FingerParams = FingerParams()):
    """Eq. (1): k_n = E_e A / h_e, N/m, with A from eq. (3).

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray or float
        N/m.

    Examples
    --------
    >>> round(float(normal_stiffness_n_per_m(1.0)))                     # 1 MPa × 138.1 mm² / 150 µm
    920667
    """
    area_m2 = contact_area_mm2(force_n, params) * MM2_TO_M2
    return params.youngs_modulus_pa * area_m2 / params.ridge_height_m


def tangential_stiffness_n_per_m(force_n, params: FingerParams = FingerParams()):
    """Eq. (2): k_t = G_e A / h_e, N/m.

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray or float
        N/m.

    Examples
    --------
    >>> round(float(tangential_stiffness_n_per_m(1.0)))                 # k_n / 2.8
    328810
    """
    area_m2 = contact_area_mm2(force_n, params) * MM2_TO_M2
    return shear_modulus_pa(params) * area_m2 / params.ridge_height_m


def detach_amplitude_um_pp(force_n, params: FingerParams = FingerParams()):
    """Eq. (6): vibration amplitude at which the ridges start to detach, µm peak-to-peak.

    The paper's W_c = F_n / k_n is the static compression of the ridges, i.e. the zero-to-peak
    excursion that just unloads them; peak-to-peak is twice that. This reading reproduces the
    paper's worked example (0.15 N needs about 1.2 µm).

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray or float
        µm peak-to-peak.

    Examples
    --------
    >>> round(float(detach_amplitude_um_pp(0.15)), 2)                   # the paper's worked example: about 1.2
    1.15
    """
    force = np.asarray(force_n, dtype=float)
    return 2.0 * force / normal_stiffness_n_per_m(force, params) * M_TO_UM


def glide_threshold_um_pp(force_n, params: FingerParams = FingerParams(), preload_n=0.0):
    """Eq. (5): lateral vibration amplitude at which the ridges start to slip, µm peak-to-peak.

    Delta x_t = mu_s F_n / k_t is the largest spring extension that static friction can hold.
    A plate oscillating about the finger's rest position stretches the springs by its
    zero-to-peak amplitude, so the peak-to-peak threshold is twice Delta x_t: 4.48 µm at 0.4 N.

    ``preload_n`` is the tangential force T (N) the finger already holds on the plate (the
    paper's "small tangential force", which it could not measure and left out). The springs then
    start at T and slip on the side of T once T + k_t x exceeds mu_s F_n: the threshold is
    2 (mu_s F_n - T) / k_t. With T = 0.1 N at 0.4 N it is 3.36 µm, between the paper's 2 µm
    (not felt) and 4 µm (felt); any T from 0.043 to 0.22 N puts it there. A preload at or above
    mu_s F_n is gross slip already (threshold 0).

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.
    preload_n : float
        A lateral preload (N) the springs already hold.

    Returns
    -------
    numpy.ndarray or float
        µm peak-to-peak.

    Examples
    --------
    >>> round(float(glide_threshold_um_pp(0.4)), 2)
    4.48
    """
    force = np.asarray(force_n, dtype=float)
    margin = np.maximum(params.static_friction * force - np.abs(np.asarray(preload_n, dtype=float)), 0.0)
    return 2.0 * margin / tangential_stiffness_n_per_m(force, params) * M_TO_UM


def shear_wave_speed_m_per_s(params: FingerParams = FingerParams()) -> float:
    """sqrt(G_e / rho): the speed of shear waves in the ridge layer, m/s (about 20 m/s for Table I).

    Parameters
    ----------
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    float
        m/s.

    Examples
    --------
    >>> round(shear_wave_speed_m_per_s(), 2)                            # sqrt(357143 Pa / 900 kg/m³)
    19.92
    """
    return float(np.sqrt(shear_modulus_pa(params) / params.density_kg_m3))


def ridge_shear_resonance_hz(params: FingerParams = FingerParams(), lumped: bool = False) -> float:
    """The ridge layer's first shear resonance, Hz, from Table I's density.

    The layer (thickness h_e, shear modulus G_e, density rho) is held by the finger's bulk on one
    face and driven by the plate on the other. Its dynamic stiffness seen from the plate,
    k_t (kh) cot(kh) with k = 2 pi f / c_s, falls to zero at kh = pi/2: f = c_s / (4 h_e),
    33.2 kHz for Table I. ``lumped`` gives the single spring-mass estimate with the layer's whole
    mass at the plate, c_s / (2 pi h_e) = 21.1 kHz, a lower bound.

    Parameters
    ----------
    params : FingerParams
        The finger; the paper's Table I by default.
    lumped : bool
        The single spring-mass estimate instead of the layer's.

    Returns
    -------
    float
        Hz.

    Examples
    --------
    >>> round(ridge_shear_resonance_hz())                               # c_s / (4 h_e) = 19.92 / 0.6 mm
    33201
    """
    speed = shear_wave_speed_m_per_s(params)
    if lumped:
        return speed / (2.0 * np.pi * params.ridge_height_m)
    return speed / (4.0 * params.ridge_height_m)


def dynamic_stiffness_ratio(frequency_hz, params: FingerParams = FingerParams()):
    """k_t(f) / k_t(0) of the ridge layer: (kh) cot(kh), 1 at low frequency, 0 at the resonance,
    negative above it (the layer's inertia wins). The quasi-static analysis of section III assumes 1.

    Parameters
    ----------
    frequency_hz : array_like
        Lateral frequency (Hz).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> dynamic_stiffness_ratio([0.0, ridge_shear_resonance_hz()]).round(6)   # 1 at rest, 0 at the resonance
    array([1., 0.])
    """
    kh = 0.5 * np.pi * np.asarray(frequency_hz, dtype=float) / ridge_shear_resonance_hz(params)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(kh == 0, 1.0, kh / np.tan(kh))


QUASI_STATIC_TOLERANCE = 0.1  # the quasi-static stiffness may be off by this share before we warn


def quasi_static_limit_hz(params: FingerParams = FingerParams(), tolerance: float = QUASI_STATIC_TOLERANCE) -> float:
    """The highest lateral frequency (Hz) at which the ridges' quasi-static stiffness is within
    ``tolerance`` of their dynamic one (11.5 kHz for Table I at 10 %).

    Parameters
    ----------
    params : FingerParams
        The finger; the paper's Table I by default.
    tolerance : float
        How far (a fraction) the stiffness may be off.

    Returns
    -------
    float
        Hz.

    Examples
    --------
    >>> round(quasi_static_limit_hz() / 1000, 1)                        # kHz
    11.5
    """
    from scipy.optimize import brentq

    resonance = ridge_shear_resonance_hz(params)
    return float(brentq(lambda f: 1.0 - float(dynamic_stiffness_ratio(f, params)) - tolerance, 1e-6 * resonance,
                        resonance))


def quasi_static_warning(frequency_hz: float, params: FingerParams = FingerParams()) -> str | None:
    """One line when the lateral quasi-static reading fails at this frequency (its stiffness off by
    more than 10 %), else None.

    Parameters
    ----------
    frequency_hz : float
        Lateral frequency (Hz).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    str or None

    Examples
    --------
    >>> quasi_static_warning(5000.0) is None                            # Hz
    True
    >>> quasi_static_warning(25000.0)                                   # doctest: +ELLIPSIS
    "25 kHz is 0.75 of the ridge layer's shear resonance (33.2 kHz ...): the ridges' dynamic stiffness there is 0.48..."
    """
    ratio = float(dynamic_stiffness_ratio(frequency_hz, params))
    if abs(1.0 - ratio) <= QUASI_STATIC_TOLERANCE:
        return None
    resonance = ridge_shear_resonance_hz(params)
    return (f"{frequency_hz / 1e3:.4g} kHz is {frequency_hz / resonance:.2f} of the ridge layer's shear resonance "
            f"({resonance / 1e3:.3g} kHz from rho = {params.density_kg_m3:g} kg/m³, G = "
            f"{shear_modulus_pa(params) / 1e6:.3g} MPa, h = {params.ridge_height_m * 1e6:g} µm): the ridges' "
            f"dynamic stiffness there is {ratio:.2f} of the quasi-static k_t, so the lateral analysis "
            f"(eqs. 4-5) is only a quasi-static estimate")


def friction_coefficient(force_n, params: FingerParams = FingerParams()):
    """Fig. 7: non-Coulombic coefficient of friction mu(F) = mu_1N F^(n-1) of a finger pad on glass.

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray or float

    Examples
    --------
    >>> float(friction_coefficient(1.0)), round(float(friction_coefficient(0.125)), 6)   # 0.8 × 0.125^(-1/3)
    (0.8, 1.6)
    """
    return params.friction_coefficient_at_1n * np.power(force_n, params.friction_exponent - 1.0)


def friction_force_n(force_n, params: FingerParams = FingerParams()):
    """Friction force mu(F) F = mu_1N F^n, N; zero where the load is zero.

    Parameters
    ----------
    force_n : array_like
        Normal force (N).
    params : FingerParams
        The finger; the paper's Table I by default.

    Returns
    -------
    numpy.ndarray
        N.

    Examples
    --------
    >>> friction_force_n([0.0, 1.0]).tolist()
    [0.0, 0.8]
    """
    force = np.maximum(np.asarray(force_n, dtype=float), 0.0)
    return params.friction_coefficient_at_1n * np.power(force, params.friction_exponent)
