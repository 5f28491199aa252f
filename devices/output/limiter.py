"""The drive limiter: the last word on how hard a plate is driven, whatever asked for it.

It acts on the control-rate drive envelope (µm peak-to-peak of steady amplitude the drive
commands) just before any output: serial and simulated plates, the audio device, the WAV device
and offline export all pass through it (:mod:`ultraglide.devices.output.stage`). Two rules:

1. The drive stays within [0, ``max_drive_um_pp``]. Without granted overdrive (the default,
   ``max_drive_um_pp`` = ``max_amplitude_um_pp``) that alone keeps the plate within its limit L:
   a plate's envelope is a weighted average of past drive.
2. With overdrive granted, each sample is also clamped so that a first-order model of the
   FASTEST plausible plate stays at or below L. The plate's Q is known to a factor of two at best,
   so the model takes Q/2: tau_f = 0.5 Q / (pi f0), p[n] = p[n-1] + g (u[n] - p[n-1]) with
   g = 1 - exp(-dt / tau_f), and the clamp is u[n] <= p[n-1] + (L - p[n-1]) / g.

Why the fastest plate suffices: for first-order envelope dynamics with unit DC gain, the response
of a slower plate (tau_s >= tau_f) equals the fast plate's response filtered by
(1 + s tau_f) / (1 + s tau_s), whose impulse response (tau_f/tau_s) delta(t) +
(1 - tau_f/tau_s) exp(-t/tau_s) / tau_s is non-negative with unit integral: a weighted average of
the fast plate's past, so it never exceeds the fast plate's maximum, hence never L. The same holds
between control samples: with the drive held, a first-order envelope moves monotonically from one
sample's value to the next, and the audio path's linear interpolation is the held drive averaged
over one control period (a non-negative, unit-integral filter again). A plate whose resonance sits
off the carrier responds less, never more (its envelope's impulse response has the same decay and a
magnitude no larger).

Counted: samples limited (lowered by more than 0.1 % of the limit: with overdrive, a request
settling onto the limit is lowered by ever smaller amounts that nobody feels), and the worst
excess (how far a request went above what was let through, µm p-p of drive).

Examples
--------
>>> from ultraglide.devices.profiles import PlateProfile
>>> plate = PlateProfile("p", 25000.0, 200.0, 8.0, 2.0)       # full scale 8, limit 2
>>> limiter = DriveLimiter(plate, control_rate_hz=12000)
>>> limiter.process(np.array([1.0, 4.0, 8.0])).tolist()
[1.0, 2.0, 2.0]
>>> limiter.limited_samples, limiter.worst_excess_um_pp
(2, 6.0)
"""

from __future__ import annotations

import math

import numpy as np
from ultraglide.devices.output import kernels
from ultraglide.devices.profiles import PlateProfile

Q_UNCERTAINTY = 0.5  # the fastest plausible plate has this fraction of the profile's Q
COUNT_ABOVE = 1e-3  # a sample counts as limited when lowered by more than this fraction of the limit


def fastest_time_constant_s(profile: PlateProfile) -> float:
    """tau_f = 0.5 Q / (pi f0): the envelope time constant of the fastest plausible plate (s).

    Parameters
    ----------
    profile : PlateProfile

    Returns
    -------
    float
        Half the profile's own time constant (s): its Q may be half what it says.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> round(fastest_time_constant_s(load_profile("sim-plate")) * 1000, 4)   # ms: 0.5 × 200 / (pi 25 kHz)
    1.2732
    """
    return Q_UNCERTAINTY * profile.time_constant_s


class DriveLimiter:
    """Limits a drive envelope block by block (see the module docstring); amplitudes µm p-p.

    Parameters
    ----------
    profile : PlateProfile
        The plate: its limit and its largest drive, µm p-p, and its time constant.
    control_rate_hz : float
        The envelope's rate, Hz.

    Examples
    --------
    A drive within the 6 µm limit passes; 20 µm is lowered to the 8 µm the amplifier takes while the plate
    rises, then held at the limit:

    >>> import numpy as np
    >>> from ultraglide.devices.profiles import load_profile
    >>> limiter = DriveLimiter(load_profile("sim-plate"), 12000.0)
    >>> limiter.process(np.full(4, 3.0)).tolist()
    [3.0, 3.0, 3.0, 3.0]
    >>> drive = limiter.process(np.full(1000, 20.0))
    >>> float(drive.max()), float(drive[-1]), limiter.status()["worst_excess_um_pp"]
    (8.0, 6.0, 14.0)
    """

    def __init__(self, profile: PlateProfile, control_rate_hz: float):
        kernels.warm_up()
        self.profile = profile
        self.control_rate_hz = float(control_rate_hz)
        self.limit_um_pp = profile.max_amplitude_um_pp
        self.max_drive_um_pp = profile.max_drive_um_pp
        self.gain = 1.0 - math.exp(-1.0 / (self.control_rate_hz * fastest_time_constant_s(profile)))
        self.fast_plate_um_pp = 0.0  # the fastest plausible plate's amplitude
        self.samples = 0
        self.limited_samples = 0
        self.worst_excess_um_pp = 0.0

    def process(self, drive_um_pp: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The limited drive for one block, written to ``out`` (float64, same length) if given.

        Parameters
        ----------
        drive_um_pp : numpy.ndarray
            The drive asked, µm p-p.
        out : numpy.ndarray, optional
            float64, same length.

        Returns
        -------
        numpy.ndarray
            The drive sent, µm p-p.

        Examples
        --------
        A negative drive is no vibration; within the limit it passes as it is:

        >>> import numpy as np
        >>> from ultraglide.devices.profiles import load_profile
        >>> limiter = DriveLimiter(load_profile("sim-plate"), 12000.0)
        >>> limiter.process(np.array([-1.0, 0.0, 2.5, 6.0])).tolist()
        [0.0, 0.0, 2.5, 6.0]
        """
        drive = np.asarray(drive_um_pp, dtype=np.float64)
        if out is None:
            out = np.empty(len(drive))
        self.fast_plate_um_pp, limited, worst = kernels.limit_drive(
            drive, self.limit_um_pp, self.max_drive_um_pp, self.gain, self.fast_plate_um_pp,
            COUNT_ABOVE * self.limit_um_pp, out)
        self.samples += len(drive)
        self.limited_samples += limited
        self.worst_excess_um_pp = max(self.worst_excess_um_pp, worst)
        return out

    def bind(self, limit_um_pp: float, max_drive_um_pp: float) -> None:
        """Narrow the limit and the drive ceiling (µm p-p) to a device's own, where they are smaller; never widens
        (the smallest limit anyone declares holds). Call between blocks, from the thread that processes them.

        Parameters
        ----------
        limit_um_pp, max_drive_um_pp : float
            The device's own limit and drive ceiling, µm p-p.

        Examples
        --------
        A device declaring 4 µm narrows the plate's 6; one declaring 10 widens nothing:

        >>> from ultraglide.devices.profiles import load_profile
        >>> limiter = DriveLimiter(load_profile("sim-plate"), 12000.0)
        >>> limiter.bind(10.0, 12.0)
        >>> limiter.limit_um_pp, limiter.max_drive_um_pp
        (6.0, 8.0)
        >>> limiter.bind(4.0, 5.0)
        >>> limiter.limit_um_pp, limiter.max_drive_um_pp
        (4.0, 5.0)
        """
        self.limit_um_pp = min(self.limit_um_pp, float(limit_um_pp))
        self.max_drive_um_pp = max(self.limit_um_pp, min(self.max_drive_um_pp, float(max_drive_um_pp)))

    @property
    def limited_fraction(self) -> float:
        """The fraction of samples (of time) the limiter lowered by more than 0.1 % of the limit.

        Examples
        --------
        1000 samples at the limit (the plate settles there), then 100 asking 7 µm, each held at 6:

        >>> import numpy as np
        >>> from ultraglide.devices.profiles import load_profile
        >>> limiter = DriveLimiter(load_profile("sim-plate"), 12000.0)
        >>> _ = limiter.process(np.full(1000, 6.0))
        >>> _ = limiter.process(np.full(100, 7.0))
        >>> limiter.limited_fraction == 100 / 1100
        True
        """
        return self.limited_samples / self.samples if self.samples else 0.0

    def status(self) -> dict:
        """The limiter's counters for a status: ``limited_fraction`` (the share of samples lowered),
        ``worst_excess_um_pp`` (how far above the limit the worst was asked, µm p-p), ``limit_um_pp`` and
        ``max_drive_um_pp`` (µm p-p).

        Returns
        -------
        dict

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> DriveLimiter(load_profile("sim-plate"), 12000.0).status()
        {'limited_fraction': 0.0, 'worst_excess_um_pp': 0.0, 'limit_um_pp': 6.0, 'max_drive_um_pp': 8.0}
        """
        return {"limited_fraction": round(self.limited_fraction, 6),
                "worst_excess_um_pp": round(self.worst_excess_um_pp, 6),
                "limit_um_pp": self.limit_um_pp, "max_drive_um_pp": self.max_drive_um_pp}

    def summary(self) -> str:
        """One sentence for people.

        Returns
        -------
        str

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.devices.profiles import load_profile
        >>> limiter = DriveLimiter(load_profile("sim-plate"), 12000.0)
        >>> limiter.summary()
        'the limiter never acted (limit 6 µm p-p)'
        >>> _ = limiter.process(np.full(1000, 6.0)); _ = limiter.process(np.full(100, 7.0))
        >>> limiter.summary()                                  # 100 of 1100 samples; 7 asked, 6 allowed
        'the limiter lowered the drive 9.1 % of the time, by at most 1.00 µm p-p (limit 6 µm p-p, drive at most 8 ...'
        """
        if not self.limited_samples:
            return f"the limiter never acted (limit {self.limit_um_pp:g} µm p-p)"
        return (f"the limiter lowered the drive {100 * self.limited_fraction:.1f} % of the time, by at most "
                f"{self.worst_excess_um_pp:.2f} µm p-p (limit {self.limit_um_pp:g} µm p-p, drive at most "
                f"{self.max_drive_um_pp:g} µm p-p)")
