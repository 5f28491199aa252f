"""The fingerprint-ridge model of Vezzoli et al. (World Haptics 2015), equations (1)–(6).

The finger-pad ridges are a bed of elastic springs whose contact area grows with the normal
force. Everything here is a pure function of a normal force and one immutable
:class:`FingerParams`; forces in newtons, stiffness in N/m, areas in m² unless a name says mm²,
and amplitudes in micrometres **peak-to-peak** (see ``docs/physics.md``).

Example::

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
    """Parameters of the finger model; defaults are the paper's Table I and its fits.

    ``density_kg_m3`` is listed in Table I but the paper's quasi-static model (and so ours)
    never uses it: ridge inertia is neglected, as the paper says in its introduction.
    """

    youngs_modulus_pa: float = 1.0e6  # E_e, stratum corneum (Table I, i)
    poisson_ratio: float = 0.4  # nu (Table I, ii)
    ridge_height_m: float = 150e-6  # h_e (Table I, iii)
    density_kg_m3: float = 900.0  # rho (Table I, iv); unused, see above
    area_coefficient_mm2: float = 138.1  # k in A = k F^(2/3), mm²/N^(2/3), eq. (3)
    area_exponent: float = 2.0 / 3.0  # the 2/3 of eq. (3)
    static_friction: float = 1.0  # mu_s, section III.C
    dynamic_friction: float = 0.7  # mu_d, section III.C
    # Non-Coulombic law mu(F) = mu_1N * F^(n-1) (Fig. 7, after Adams et al. 2013 and
    # Dzidek et al. 2014): friction force grows as F^n with n = 2/3 for Hertzian asperities.
    friction_exponent: float = 2.0 / 3.0  # n
    friction_coefficient_at_1n: float = 0.8  # mu at 1 N; 1.0 at 0.5 N, typical of moist fingers
    contact: str = "hertz"  # pressure profile for eq. (9): "hertz" (eq. 8) or "uniform"

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
        """A copy with some parameters changed."""
        return replace(self, **changes)


def contact_area_mm2(force_n, params: FingerParams = FingerParams()):
    """Eq. (3): apparent contact area A = k F^(2/3) of the ridges, mm²."""
    return params.area_coefficient_mm2 * np.power(force_n, params.area_exponent)


def shear_modulus_pa(params: FingerParams = FingerParams()) -> float:
    """Eq. (2): G_e = E_e / (2 (1 + nu)), Pa."""
    return params.youngs_modulus_pa / (2.0 * (1.0 + params.poisson_ratio))


def normal_stiffness_n_per_m(force_n, params: FingerParams = FingerParams()):
    """Eq. (1): k_n = E_e A / h_e, N/m, with A from eq. (3)."""
    area_m2 = contact_area_mm2(force_n, params) * MM2_TO_M2
    return params.youngs_modulus_pa * area_m2 / params.ridge_height_m


def tangential_stiffness_n_per_m(force_n, params: FingerParams = FingerParams()):
    """Eq. (2): k_t = G_e A / h_e, N/m."""
    area_m2 = contact_area_mm2(force_n, params) * MM2_TO_M2
    return shear_modulus_pa(params) * area_m2 / params.ridge_height_m


def detach_amplitude_um_pp(force_n, params: FingerParams = FingerParams()):
    """Eq. (6): vibration amplitude at which the ridges start to detach, µm peak-to-peak.

    The paper's W_c = F_n / k_n is the static compression of the ridges, i.e. the zero-to-peak
    excursion that just unloads them; peak-to-peak is twice that. This reading reproduces the
    paper's worked example (0.15 N needs about 1.2 µm).
    """
    force = np.asarray(force_n, dtype=float)
    return 2.0 * force / normal_stiffness_n_per_m(force, params) * M_TO_UM


def glide_threshold_um_pp(force_n, params: FingerParams = FingerParams()):
    """Eq. (5): lateral vibration amplitude at which the ridges start to slip, µm peak-to-peak.

    Delta x_t = mu_s F_n / k_t is the largest spring extension that static friction can hold.
    A plate oscillating about the finger's rest position stretches the springs by its
    zero-to-peak amplitude, so the peak-to-peak threshold is twice Delta x_t. At 0.4 N this is
    4.5 µm, the "about 4 µm at about 0.4 N" of the paper's psychophysics; the steady-state
    threshold after the first slip, see :func:`render.physics.lateral.steady_glide_threshold_um_pp`, is 3.8 µm.
    """
    force = np.asarray(force_n, dtype=float)
    return 2.0 * params.static_friction * force / tangential_stiffness_n_per_m(force, params) * M_TO_UM


def friction_coefficient(force_n, params: FingerParams = FingerParams()):
    """Fig. 7: non-Coulombic coefficient of friction mu(F) = mu_1N F^(n-1) of a finger pad on glass."""
    return params.friction_coefficient_at_1n * np.power(force_n, params.friction_exponent - 1.0)


def friction_force_n(force_n, params: FingerParams = FingerParams()):
    """Friction force mu(F) F = mu_1N F^n, N; zero where the load is zero."""
    force = np.maximum(np.asarray(force_n, dtype=float), 0.0)
    return params.friction_coefficient_at_1n * np.power(force, params.friction_exponent)
