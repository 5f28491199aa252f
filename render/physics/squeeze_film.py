"""Intermittent contact cushioned by a squeeze film of air: the ``squeeze-film`` friction model.

The paper's bed of springs (eqs. 1, 3, 6-9) never takes friction below about 0.67 (our evaluation of it,
up to 20 µm): its only mechanism is the non-Coulombic law swinging about the load. Measured fingers fall
much further (to 0.10 on average at 6 µm p-p: Wiertlewski, Fenton Friesen and Colgate 2016). Those authors
(PNAS 113:9210, 2016, "Partial squeeze film levitation modulates fingertip friction") imaged the contact
and found the load at the interface shared between the elastic compression of the skin's asperities and
a squeeze film of air that has no time to escape: fewer asperities touch, and friction falls with them.
Fenton Friesen et al. (2018) measured friction reduction on an artificial finger in a 98 % vacuum (at
0.3 ± 0.05 N and amplitudes below about 1.8 µm, reporting the motor's current); no ratio of theirs is
used here.

This model puts the two together, with parameters that are physical:

* The film. Over a share ``film_fraction`` of the apparent contact area A(F) (eq. 3), the skin
  stands a mean gap ``gap_um`` off the glass (the air pockets its ridges and asperities leave).
  A plate moving by a_pp / 2 about that gap compresses the air faster than it can leak away when
  the squeeze number sigma = 12 eta omega L² / (p_a h²) is large (L the contact's radius: about
  90 at 27 kHz, 0.5 N and a 10 µm gap). In that limit the gas keeps p h constant through a cycle,
  and a zero net flow at the contact's edge gives the mean pressure
  p̄ = p_a sqrt((1 + 3/2 eps²) / (1 - eps²)), eps = (a_pp / 2) / h, the isothermal squeeze-film
  result that Biet, Giraud and Lemaire-Semail (IEEE TUFFC 54:2678, 2007) used for tactile plates.
  The film carries L(a, F) = film_fraction A(F) (p̄ - p_a).
* The contact. The ridges carry what the film does not, F_c = F - L (zero once the film carries
  all: levitation), and touch and leave the plate as in the paper's section IV at that load, with
  its non-Coulombic friction mu_1N F^n. Friction over friction at rest is then
  (F_c / F)^n R(a / W_c(F_c)), R the paper's relative friction (Fig. 8) and W_c its detachment
  amplitude (eq. 6) at the contact's own load.

With ``film_fraction`` 0 the film carries nothing and the model is the paper's, exactly. Because
A ∝ F^(2/3), the film's share of the load falls as F^(-1/3): lighter touches levitate more. That is
our model's consequence, not a measurement: the paper's ref. [8] (Vezzoli et al., WHC 2015, "Pressure
dependence of friction modulation") varied the ambient pressure (0.5 and 1 atm), not the force.
Frequency enters only through the condition sigma >> 1, which holds on ultrasonic plates
(:func:`squeeze_number`). Left out: the skin's compliance under the film (the gap is held), its
inertia and viscoelasticity, and the film's edge losses.

The inverse is exact: a compiled kernel bisects the forward model itself (closed forms and the
paper's table over u) for each sample, 40 halvings of the amplitude range, about a microsecond a
sample, with no table of its own to build.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from ultraglide.render.physics import kernels
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.fingerprint import MM2_TO_M2, FingerParams, contact_area_mm2
from ultraglide.render.physics.model_base import (
    CEILING_UM_PP,
    DEFAULT_FORCE_N,
    MAX_FORCE_N,
    MIN_FORCE_N,
    FrictionModel,
    check_amplitude,
    clip_force,
)
from ultraglide.render.physics.paper_model import PaperModel

AMBIENT_PRESSURE_PA = 101_325.0
AIR_VISCOSITY_PA_S = 1.81e-5  # at 20 °C
EPS_MAX = 0.95  # the film's law is held beyond this share of the gap (see film_overpressure_ratio)
GAP_RANGE_UM = (1.0, 100.0)
FILM_FRACTION_RANGE = (0.0, 1.0)
AMBIENT_RANGE_PA = (1.0e3, 2.0e5)  # down to a 99 % vacuum; no film: film_fraction 0


@dataclass(frozen=True)
class FilmParams:
    """The air film under the finger: ``gap_um``, the mean gap between skin and glass over the film's
    area at rest (µm); ``film_fraction``, the share of the apparent contact area (eq. 3) over which the
    film builds pressure (0: no film, the paper's model); ``ambient_pressure_pa``, the air's pressure
    (1 kPa, a 99 % vacuum, to 200 kPa).

    The defaults (a 10 µm gap over 40 % of the contact) are chosen, within what skin on glass
    allows, so that the model reaches the reductions measured fingers show (0.2 at 6 µm p-p and
    0.5 N); a calibration fits the gap and the share from a person's data.

    Parameters
    ----------
    gap_um : float
        The mean gap (µm) between skin and glass over the film's area at rest, in [1, 100].
    film_fraction : float
        The share of the apparent contact area over which the film builds pressure, in [0, 1].
    ambient_pressure_pa : float
        The air's pressure (Pa), in [1e3, 2e5].

    Raises
    ------
    ModelError
        A value outside its range.

    Examples
    --------
    >>> FilmParams().with_(gap_um=5.0)
    FilmParams(gap_um=5.0, film_fraction=0.4, ambient_pressure_pa=101325.0)
    """

    gap_um: float = 10.0
    film_fraction: float = 0.4
    ambient_pressure_pa: float = AMBIENT_PRESSURE_PA

    def __post_init__(self) -> None:
        for name, value, allowed in (("gap_um", self.gap_um, GAP_RANGE_UM),
                                     ("film_fraction", self.film_fraction, FILM_FRACTION_RANGE),
                                     ("ambient_pressure_pa", self.ambient_pressure_pa, AMBIENT_RANGE_PA)):
            if not (np.isfinite(value) and allowed[0] <= value <= allowed[1]):
                raise ModelError(f"{name} must lie in [{allowed[0]:g}, {allowed[1]:g}], got {value}")

    def with_(self, **changes: float) -> FilmParams:
        """A copy with some parameters changed.

        Parameters
        ----------
        **changes : float
            Fields and their new values (``gap_um`` in µm, ``film_fraction``, ``ambient_pressure_pa`` in Pa).

        Returns
        -------
        FilmParams

        Examples
        --------
        >>> FilmParams().with_(gap_um=3.0)
        FilmParams(gap_um=3.0, film_fraction=0.4, ambient_pressure_pa=101325.0)
        """
        return replace(self, **changes)


def film_overpressure_ratio(eps: ArrayLike) -> np.ndarray:
    """(p̄ - p_a) / p_a of an isothermal squeeze film at large squeeze number, for a plate moving by
    ``eps`` times the mean gap (zero-to-peak over gap): sqrt((1 + 1.5 eps²) / (1 - eps²)) - 1.
    Beyond eps = 0.95 the plate all but touches the skin, the film's law no longer holds, and its
    pressure is held at that value (3.9 p_a): the model stays continuous.

    Parameters
    ----------
    eps : array_like
        The plate's zero-to-peak excursion over the mean gap.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> film_overpressure_ratio([0.0, 0.5]).round(4).tolist()           # sqrt(1.375 / 0.75) - 1 at 0.5
    [0.0, 0.354]
    >>> round(float(film_overpressure_ratio(0.99)), 2)                   # held beyond 0.95
    3.91
    """
    square = np.square(np.minimum(np.asarray(eps, dtype=float), EPS_MAX))
    return np.sqrt((1.0 + 1.5 * square) / (1.0 - square)) - 1.0


def levitation_force_n(amplitude_um_pp: ArrayLike, force_n: ArrayLike, film: FilmParams = FilmParams(),
                       finger: FingerParams = FingerParams()) -> np.ndarray:
    """The mean load (N) the air film carries at this amplitude (µm p-p) and normal force (N).

    Parameters
    ----------
    amplitude_um_pp : array_like
        Vibration amplitude (µm p-p).
    force_n : array_like
        Normal force (N).
    film : FilmParams
        The air film.
    finger : FingerParams
        The finger (its contact area, eq. 3).

    Returns
    -------
    numpy.ndarray
        N.

    Examples
    --------
    >>> float(levitation_force_n(0.0, 0.5)), round(float(levitation_force_n(6.0, 0.5)), 3)   # at rest none
    (0.0, 0.412)
    """
    eps = np.asarray(amplitude_um_pp, dtype=float) / 2.0 / film.gap_um
    area_m2 = contact_area_mm2(np.asarray(force_n, dtype=float), finger) * MM2_TO_M2
    return film.film_fraction * area_m2 * film.ambient_pressure_pa * film_overpressure_ratio(eps)


def contact_share(amplitude_um_pp: ArrayLike, force_n: ArrayLike, film: FilmParams = FilmParams(),
                  finger: FingerParams = FingerParams()) -> np.ndarray:
    """F_c / F: the share of the load the ridges still carry, 1 at rest, 0 once the film carries it all.

    Parameters
    ----------
    amplitude_um_pp : array_like
        Vibration amplitude (µm p-p).
    force_n : array_like
        Normal force (N).
    film : FilmParams
        The air film.
    finger : FingerParams
        The finger (its contact area, eq. 3).

    Returns
    -------
    numpy.ndarray
        In [0, 1].

    Examples
    --------
    >>> contact_share([0.0, 6.0], 0.5).round(3)                        # 1 - 0.412 N / 0.5 N at 6 µm
    array([1.   , 0.176])
    """
    force = np.asarray(force_n, dtype=float)
    return np.clip(1.0 - levitation_force_n(amplitude_um_pp, force, film, finger) / force, 0.0, 1.0)


def squeeze_number(carrier_hz: float, force_n: float, film: FilmParams = FilmParams(),
                   finger: FingerParams = FingerParams()) -> float:
    """sigma = 12 eta omega L² / (p_a h²), L the radius of the apparent contact: the film's pressure
    follows the large-sigma law this model uses when sigma >> 1 (about 100 at 27 kHz, 0.5 N, 10 µm).

    Parameters
    ----------
    carrier_hz : float
        The vibration's frequency (Hz).
    force_n : float
        Normal force (N): the contact's radius.
    film : FilmParams
        The air film.
    finger : FingerParams
        The finger (its contact area, eq. 3).

    Returns
    -------
    float

    Examples
    --------
    >>> round(squeeze_number(27000.0, 0.5))                             # well above 1
    101
    """
    radius_m = np.sqrt(float(contact_area_mm2(force_n, finger)) * MM2_TO_M2 / np.pi)
    gap_m = film.gap_um * 1e-6
    if film.ambient_pressure_pa == 0:
        return float("inf")
    return float(12.0 * AIR_VISCOSITY_PA_S * 2.0 * np.pi * carrier_hz * radius_m**2
                 / (film.ambient_pressure_pa * gap_m**2))


def film_ratio(amplitude_um_pp: np.ndarray, force_n: np.ndarray, film: FilmParams, contact: PaperModel) -> np.ndarray:
    """Friction over friction at rest, (F_c / F)^n R(a / W_c(F_c)), with the paper's model ``contact``
    (its R table and detachment law) for the ridges; forces as given (not clipped).

    Parameters
    ----------
    amplitude_um_pp : numpy.ndarray
        Vibration amplitude (µm p-p).
    force_n : numpy.ndarray
        Normal force (N).
    film : FilmParams
        The air film.
    contact : PaperModel
        The ridges' model.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> from ultraglide.render.physics.paper_model import PaperModel
    >>> film_ratio(np.array([0.0, 6.0]), np.array([0.5, 0.5]), FilmParams(), PaperModel()).round(2)
    array([1.  , 0.23])
    """
    finger = contact.params
    amplitude = np.asarray(amplitude_um_pp, dtype=float)
    force = np.asarray(force_n, dtype=float)
    share = contact_share(amplitude, force, film, finger)
    detach = contact._detach_um_pp(share * force, clip=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(amplitude > 0, amplitude / detach, 0.0)
    rolling = np.interp(u, contact.u_nodes, contact.ratio_nodes)
    return np.power(share, finger.friction_exponent) * rolling


class SqueezeFilmModel(FrictionModel):
    """Intermittent contact of the paper's ridges, cushioned by a squeeze film of air (module docstring).

    Parameters
    ----------
    film : FilmParams
        The air film: its gap (µm), the share of the contact it covers, the ambient pressure (Pa).
    finger : FingerParams
        The paper's ridge model (Table I).

    Examples
    --------
    >>> model = SqueezeFilmModel()
    >>> model.relative_friction([0.0, 6.0], force_n=0.5).round(2)         # reaches lower than the paper's 0.77
    array([1.  , 0.23])
    >>> round(float(SqueezeFilmModel(FilmParams(film_fraction=0.0)).relative_friction(6.0, 0.5)), 3)  # no film
    0.773
    """

    name = "squeeze-film"

    def warm_up(self) -> None:
        """Load the film model's compiled inverse (numba's cache) before a real-time block needs it.

        Examples
        --------
        >>> import numpy as np
        >>> model = SqueezeFilmModel()
        >>> model.warm_up()
        >>> model.amplitude_um_pp(np.array([1.0]), 0.5).amplitude_um_pp.tolist()      # at rest: no vibration
        [0.0]
        """
        kernels.warm_up_film()

    def __init__(self, film: FilmParams = FilmParams(), finger: FingerParams = FingerParams()):
        self.film = film
        self.finger = finger
        self._contact = PaperModel(finger)  # the paper's R(u) table and its detachment law
        contact = self._contact
        packed = np.zeros(13)
        packed[[kernels.FILM_LIFT, kernels.FILM_GAP]] = film.film_fraction * film.ambient_pressure_pa, film.gap_um
        packed[[kernels.AREA_K, kernels.AREA_EXPONENT, kernels.AREA_MAX]] = (
            finger.area_coefficient_mm2, finger.area_exponent, finger.max_contact_area_mm2)
        packed[[kernels.DETACH_AT_1N, kernels.DETACH_EXPONENT, kernels.SATURATION]] = (
            contact._detach_at_1n, contact._detach_exponent, contact._saturation_n)
        packed[[kernels.FRICTION_N, kernels.U_MAX]] = finger.friction_exponent, contact.u_nodes[-1]
        packed[[kernels.MIN_F, kernels.MAX_F]] = MIN_FORCE_N, MAX_FORCE_N
        packed[kernels.EPS_MAX] = EPS_MAX
        self._packed = packed
        self._nodes = np.ascontiguousarray(contact.ratio_nodes)

    # ---- the forward model ------------------------------------------------------------------------
    def _ratio(self, amplitude: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The forward model at forces already clipped to the models' range (or at a table node)."""
        return film_ratio(amplitude, force, self.film, self._contact)

    def relative_friction(self, amplitude_um_pp: ArrayLike, force_n: ArrayLike = DEFAULT_FORCE_N) -> np.ndarray:
        """The ridges' ratio at the load the film leaves them; see :meth:`FrictionModel.relative_friction`.

        Parameters
        ----------
        amplitude_um_pp : array_like
            Vibration amplitude, µm p-p.
        force_n : array_like
            Normal force, N.

        Returns
        -------
        numpy.ndarray
            mu / mu0.

        Examples
        --------
        1 at rest, and falling as the film lifts more of the load:

        >>> import numpy as np
        >>> ratios = SqueezeFilmModel().relative_friction(np.arange(0.0, 7.0), 0.5)
        >>> float(ratios[0]), bool(np.all(np.diff(ratios) < 0))
        (1.0, True)
        """
        self._checked_force(force_n)
        amplitude = np.asarray(amplitude_um_pp, dtype=float)
        check_amplitude(amplitude)
        return self._ratio(amplitude, clip_force(force_n))

    # ---- the inverse ---------------------------------------------------------------------------------
    def _amplitude_in_reach(self, ratio, force_n):
        ratio = np.asarray(ratio, dtype=float)
        force = np.asarray(force_n, dtype=float)
        shape = np.broadcast(ratio, force).shape
        out = np.empty(int(np.prod(shape)))
        ratio = np.ascontiguousarray(np.broadcast_to(ratio, shape), dtype=float).ravel()
        force = np.ascontiguousarray(np.broadcast_to(force, shape), dtype=float).ravel()
        kernels.inverse_film_forces(ratio, force, CEILING_UM_PP, self._packed, self._nodes, out)
        return out.reshape(shape)

    compiled = True

    def _inverse_one_force(self, ratio, force_n, limit, out) -> int:
        return kernels.inverse_film_force(ratio, force_n, self._floor(force_n, limit), limit, self._packed,
                                          self._nodes, out)

    def _inverse_forces(self, ratio, force_n, limit, out) -> int:
        return kernels.inverse_film_forces(ratio, force_n, limit, self._packed, self._nodes, out)

    # ---- words ----------------------------------------------------------------------------------------
    def force_law(self) -> str:
        """The film's share of the load falls as F^(-1/3); the ridges detach as W_c ∝ F_c^(1/3) at theirs.

        Returns
        -------
        str

        Examples
        --------
        >>> SqueezeFilmModel().force_law().split(";")[0]
        "the film's share of the load falls as F^(-1/3) (its area A ∝ F^(2/3), eq. 3)"
        """
        return ("the film's share of the load falls as F^(-1/3) (its area A ∝ F^(2/3), eq. 3); the ridges' "
                "detachment W_c ∝ F_c^(1/3) at their own load (eq. 6)")

    def _own_force_range_n(self) -> tuple[float, float]:
        return self._contact._own_force_range_n()

    def _range_reason(self) -> str:
        return self._contact._range_reason()

    def describe(self) -> str:
        """One line: the ridges' finger, the film (gap in µm, share, pressure in kPa) and the sources.

        Returns
        -------
        str

        Examples
        --------
        >>> SqueezeFilmModel().describe().split(" sharing")[0]
        "squeeze-film: the paper's ridges (E = 1 MPa, n = 0.667, hertz contact)"
        """
        f, p = self.film, self.finger
        return (f"squeeze-film: the paper's ridges (E = {p.youngs_modulus_pa / 1e6:g} MPa, n = "
                f"{p.friction_exponent:.3g}, {p.contact} contact) sharing the load with an air film "
                f"(gap {f.gap_um:.3g} µm over {f.film_fraction:.3g} of the contact, {f.ambient_pressure_pa / 1e3:.4g} "
                f"kPa); after Wiertlewski et al. 2016 and Biet et al. 2007; reaches 0 where the film carries the "
                f"whole load (levitation), which no measured finger does")

    def __repr__(self) -> str:
        """``SqueezeFilmModel()``, or the constructor call with the parameters that differ from the defaults."""
        def call(value, default) -> str:
            changed = {k: v for k, v in vars(value).items() if v != getattr(default, k)}
            return f"{type(value).__name__}({', '.join(f'{k}={v!r}' for k, v in changed.items())})"
        film, finger = call(self.film, FilmParams()), call(self.finger, FingerParams())
        parts = [film, finger] if finger != "FingerParams()" else [film] if film != "FilmParams()" else []
        return f"SqueezeFilmModel({', '.join(parts)})"

    def parameters(self) -> dict[str, float | str]:
        """The film's ``gap_um`` (µm), ``film_fraction``, ``ambient_pressure_pa`` (Pa) and the finger's
        ``youngs_modulus_pa`` (Pa) and ``friction_exponent``.

        Returns
        -------
        dict

        Examples
        --------
        >>> params = SqueezeFilmModel().parameters()
        >>> params["gap_um"], params["film_fraction"], params["ambient_pressure_pa"]        # µm, share, Pa
        (10.0, 0.4, 101325.0)
        """
        return {"gap_um": self.film.gap_um, "film_fraction": self.film.film_fraction,
                "ambient_pressure_pa": self.film.ambient_pressure_pa,
                "youngs_modulus_pa": self.finger.youngs_modulus_pa,
                "friction_exponent": self.finger.friction_exponent}
