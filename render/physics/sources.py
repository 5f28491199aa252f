"""What the papers ultraglide cites actually state: every published figure a model, a default or a page uses.

Each :class:`Figure` is one number (or range) as its paper states it, with the paper and where in it
(section, figure, table, abstract). ``checked`` says whether that place was read for this project (the
project's ``data/README.md`` notes, kept with its shared data and not in this repository, or the paper's own
text); a figure taken from a summary whose place in the paper was not located says so (``checked=False``)
instead of inventing a section. Model outputs are
never listed here: they are ours, and the pages label them so.

``tests/test_attribution.py`` reads this table and the physics pages and docstrings: a number written
beside a cited author's name must be a figure listed here for that author (or be marked as ours), and
every figure here must name its place. So a new attributed number cannot be added without a source.

Examples
--------
>>> from ultraglide.render.physics.sources import FIGURES
>>> meyer = [f for f in FIGURES if f.key == "recovery_s"][0]
>>> meyer.value, meyer.author
('70 ms', 'Meyer')
"""

from __future__ import annotations

from dataclasses import dataclass

PAPERS = {
    "Vezzoli2015": "E. Vezzoli, B. Dzidek, T. Sednaoui, F. Giraud, M. Adams, B. Lemaire-Semail, \"Role of fingerprint "
                   "mechanics and non-Coulombic friction in ultrasonic devices\", IEEE World Haptics Conference 2015, "
                   "HAL hal-01253582 (the seed paper, read whole for this project)",
    "Monnoyer2018": "J. Monnoyer, E. Diaz, C. Bourdin, M. Wiertlewski, \"Perception of ultrasonic switches involves "
                    "large discontinuity of the mechanical impedance\", IEEE Trans. Haptics 11(4):579-589, 2018",
    "Huloux2018": "N. Huloux, J. Monnoyer, M. Boyron, M. Wiertlewski, \"Overcoming the variability of fingertip "
                  "friction with surface-haptic force-feedback\", EuroHaptics 2018, LNCS 10893:326-337",
    "Wiertlewski2016": "M. Wiertlewski, R. Fenton Friesen, J. E. Colgate, \"Partial squeeze film levitation "
                       "modulates fingertip friction\", PNAS 113(33):9210-9215, 2016",
    "Meyer2014": "D. J. Meyer, M. Wiertlewski, M. A. Peshkin, J. E. Colgate, \"Dynamics of ultrasonic and "
                 "electrostatic friction modulation for rendering texture on haptic surfaces\", IEEE Haptics "
                 "Symposium 2014",
    "Monnoyer2023": "J. Monnoyer, L. Willemet, M. Wiertlewski, \"Rapid change of friction causes the illusion of "
                    "touching a receding surface\", J. R. Soc. Interface 20(199):20220718, 2023",
    "Friesen2018": "R. Fenton Friesen, M. Wiertlewski, M. A. Peshkin, J. E. Colgate, \"The contribution of air to "
                   "ultrasonic friction reduction\", conference paper, HAL hal-01771782 (an artificial finger in a "
                   "vacuum chamber; the year 2018 as issue 43 cites it, not checked)",
    "Bernard2018": "C. Bernard, J. Monnoyer, M. Wiertlewski, \"Harmonious textures\", EuroHaptics 2018",
    "Gueorguiev2017": "D. Gueorguiev et al., J. R. Soc. Interface 2017",
    "Gueorguiev2019": "D. Gueorguiev et al., IEEE Trans. Haptics 2019",
}

#: The surname each paper is cited by in running text ("Meyer et al. 2014").
AUTHORS = {"Vezzoli2015": "Vezzoli", "Monnoyer2018": "Monnoyer", "Huloux2018": "Huloux",
           "Wiertlewski2016": "Wiertlewski", "Meyer2014": "Meyer", "Monnoyer2023": "Monnoyer",
           "Friesen2018": "Friesen", "Bernard2018": "Bernard", "Gueorguiev2017": "Gueorguiev",
           "Gueorguiev2019": "Gueorguiev"}

UNLOCATED = "place in the paper not located here (figure as summarised in issue 43)"
#: data/README.md names these places for the whole of its Monnoyer et al. notes, not one place per figure.
MONNOYER_PLACES = "§3.1.4, §3.2.1, Figs. 4 and 6, as data/README.md cites them (not per figure)"
#: data/README.md gives these figures without a section, figure or table.
README_ONLY = "as data/README.md states it (no section, figure or table given)"


@dataclass(frozen=True)
class Figure:
    """One published figure: ``value`` as written in our pages (units and all), ``what`` it measures, the
    ``paper`` (a key of :data:`PAPERS`), ``where`` in it, and whether that place was ``checked``.

    Examples
    --------
    >>> figure = next(f for f in FIGURES if f.key == "monnoyer_carrier")
    >>> figure.value, figure.paper, figure.checked
    ('34 590 Hz', 'Monnoyer2018', True)
    """

    key: str
    value: str
    what: str
    paper: str
    where: str
    checked: bool

    @property
    def author(self) -> str:
        """The paper's authors and year, as cited.

        Examples
        --------
        >>> next(f for f in FIGURES if f.key == "monnoyer_carrier").author
        'Monnoyer'
        """
        return AUTHORS[self.paper]


FIGURES: tuple[Figure, ...] = (
    Figure("vezzoli_modulus", "1 MPa", "Young's modulus of the ridges (stratum corneum)", "Vezzoli2015", "Table I (i)",
           True),
    Figure("vezzoli_poisson", "0.4", "Poisson's ratio of the ridges", "Vezzoli2015", "Table I (ii)", True),
    Figure("vezzoli_height", "150 µm", "undeformed height of the ridges", "Vezzoli2015", "Table I (iii)", True),
    Figure("vezzoli_density", "900 kg/m³", "density of the ridges (enters no equation of the paper)", "Vezzoli2015",
           "Table I (iv)", True),
    Figure("vezzoli_area", "138.1 mm²/N^(2/3)", "k of A = k F^(2/3), a best fit to its ref. [15]'s data",
           "Vezzoli2015", "eq. (3), §III.B", True),
    Figure("vezzoli_friction", "1 and 0.7", "mu_s and mu_d of the lateral analysis", "Vezzoli2015", "§III.C", True),
    Figure("vezzoli_fig2", "5 µm at 20 kHz and 0.5 N", "the vibration and force of Fig. 2", "Vezzoli2015", "§III.C",
           True),
    Figure("vezzoli_actuator", "27.83 kHz", "the lateral actuator's resonance, the stimulation frequency",
           "Vezzoli2015", "§III.D.1-2", True),
    Figure("vezzoli_levels", "0, 2 and 4 µm", "amplitudes felt by four participants: 2 µm not told from rest, slip "
           "reported at 4 µm (peak-to-peak or not is not stated)", "Vezzoli2015", "§III.D.2", True),
    Figure("vezzoli_glide_force", "0.4 N", "the force at which its model's glide threshold is 4 µm (\"about 0.4 N\", "
           "typical of touch; not a measured force)", "Vezzoli2015", "§III.D.2", True),
    Figure("vezzoli_detach", "1.2 µm at 0.15 N", "the detachment example", "Vezzoli2015", "Fig. 4 caption", True),
    Figure("vezzoli_valid", "20 kHz", "the normal analysis holds above this frequency", "Vezzoli2015", "§IV.B", True),
    Figure("vezzoli_cycle", "0.1 to 8 µm, 0.5 N, 20 kHz (50 µs)", "the amplitudes, force and frequency of Figs. 5-6",
           "Vezzoli2015", "§IV.C, Figs. 5-6 captions", True),
    Figure("vezzoli_fig9", "0.35 N, 25 kHz", "the force of Fig. 9's three measured fingers (its ref. [16]) and the "
           "frequency", "Vezzoli2015", "§IV.D, Fig. 9 caption", True),
    Figure("vezzoli_repin", "200 µs", "repinning time of molecular junctions in thin aqueous layers, from its ref. "
           "[19]", "Vezzoli2015", "§V", True),
    Figure("monnoyer_tau", "1.32 µm", "tau of mu = mu0 exp(-a²/2tau²), zero-to-peak, fitted over 14 participants "
           "(± 0.45 µm)", "Monnoyer2018", MONNOYER_PLACES, True),
    Figure("monnoyer_tau_spread", "0.45 µm", "spread of tau across participants", "Monnoyer2018", MONNOYER_PLACES,
           True),
    Figure("monnoyer_mu0", "1.2", "friction coefficient at rest (± 0.67)", "Monnoyer2018", MONNOYER_PLACES, True),
    Figure("monnoyer_wording", "64 %", "the decrease at a = tau by the text's wording of tau (its printed law, "
           "exp(-a²/2tau²), gives 39 %: the paper is inconsistent)", "Monnoyer2018",
           "as data/README.md states it (no section given)", True),
    Figure("monnoyer_carrier", "34 590 Hz", "the plate's frequency", "Monnoyer2018", MONNOYER_PLACES, True),
    Figure("huloux_f0", "0.8 N", "f0 of f = f0 exp(-a² tau) + d", "Huloux2018", README_ONLY, True),
    Figure("huloux_tau", "0.38 µm⁻²", "tau of the same law", "Huloux2018", README_ONLY, True),
    Figure("huloux_carrier", "30 kHz", "the plate's frequency", "Huloux2018", README_ONLY, True),
    Figure("huloux_amplitude", "2.5 µm", "the largest amplitude of its modulation", "Huloux2018", README_ONLY,
           True),
    Figure("huloux_settling", "32-37 ms", "time for friction to settle after a change of vibration", "Huloux2018",
           UNLOCATED, False),
    Figure("floor_mean", "0.10", "friction ratio at 6 µm p-p, 29 kHz, mean over people", "Wiertlewski2016",
           UNLOCATED, False),
    Figure("floor_range", "0.02-0.30", "the same ratio's range across people", "Wiertlewski2016", UNLOCATED, False),
    Figure("floor_amplitude", "6 µm", "the amplitude (p-p) of that ratio", "Wiertlewski2016", UNLOCATED, False),
    Figure("floor_carrier", "29 kHz", "the plate's frequency for that ratio", "Wiertlewski2016", UNLOCATED, False),
    Figure("onset_s", "5 ms", "time for friction to fall when the vibration starts", "Meyer2014", UNLOCATED, False),
    Figure("recovery_s", "70 ms", "time for friction to recover when it stops, at 22 mm/s (slower when sliding "
           "slower)", "Meyer2014", UNLOCATED, False),
    Figure("recovery_speed", "22 mm/s", "the sliding speed of that recovery", "Meyer2014", UNLOCATED, False),
    Figure("release_s", "20 ms", "release of the skin's latent elastic strain after the friction reduction is "
           "switched on, a finger pressing (not sliding)", "Monnoyer2023",
           "abstract (PMC9905974, read for this project)", True),
    Figure("friesen_force", "0.3 ± 0.05 N", "the normal force of its measurements", "Friesen2018", UNLOCATED, False),
    Figure("friesen_amplitude", "1.8 µm", "its amplitudes lay below about this", "Friesen2018", UNLOCATED, False),
    Figure("friesen_vacuum", "98 %", "the vacuum of its reduced-pressure condition, against atmospheric pressure, "
           "with an artificial finger", "Friesen2018", "abstract (HAL hal-01771782, read for this project)", True),
    Figure("bernard_carrier", "39 kHz", "the plate's frequency", "Bernard2018", README_ONLY, True),
    Figure("bernard_amplitude", "4 µm", "its largest amplitude, p-p", "Bernard2018", README_ONLY, True),
    Figure("bernard_ratio", "0.25", "ratio near full amplitude (mu about 0.8 to about 0.2)", "Bernard2018",
           README_ONLY, True),
    Figure("gueorguiev_weber", "0.11", "Weber fraction for a friction decrease", "Gueorguiev2017", README_ONLY,
           True),
    Figure("gueorguiev_transition", "2.3-2.4 ms", "transitions discriminated", "Gueorguiev2019", README_ONLY,
           True),
)


def figure(key: str) -> Figure:
    """The published figure named ``key`` (a :class:`Figure`); KeyError if there is none.

    Parameters
    ----------
    key : str
        The figure's key in :data:`FIGURES`.

    Returns
    -------
    Figure

    Raises
    ------
    KeyError
        No figure of that key.

    Examples
    --------
    >>> figure("monnoyer_tau").value
    '1.32 µm'
    """
    for item in FIGURES:
        if item.key == key:
            return item
    raise KeyError(key)


def cite(key: str) -> str:
    """``"70 ms (Meyer2014, place in the paper not located here ...)"``: a figure with its source, for
    descriptions.

    Parameters
    ----------
    key : str
        The figure's key in :data:`FIGURES`.

    Returns
    -------
    str

    Raises
    ------
    KeyError
        No figure of that key.

    Examples
    --------
    >>> cite("monnoyer_tau")
    '1.32 µm (Monnoyer2018, §3.1.4, §3.2.1, Figs. 4 and 6, as data/README.md cites them (not per figure))'
    """
    item = figure(key)
    return f"{item.value} ({item.paper}, {item.where})"
