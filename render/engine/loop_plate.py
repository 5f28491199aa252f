"""The plate as the renderer sees it through the firmware's amplitude loop.

With the amplitude loop on (``SET_LOOP 1``) setpoints are amplitude targets, which the firmware follows
far faster than the plate's own envelope (docs/design.md, "The amplitude loop": 10-90 % of a step in
0.82 ms on sim-plate, where the plate alone takes 5.6 ms) and caps at the limit. Pre-compensating the plate's
own slow envelope would then overshoot every target; what is left to pre-compensate is the loop's lag,
about a first-order lag of ``time_constant_s``, within targets up to the limit (no overdrive: the firmware
decides the drive). Steps down are as quick where the firmware brakes (``features`` bit 1: the carrier in
antiphase, as the reference firmware does); on a device without the brake they stay bounded by the plate's free
decay, which no target can hasten.

:class:`AmplitudeLoopPlate` is the profile with those two facts changed, for the renderer only: the output
stage and its limiter keep the real profile.
"""

from __future__ import annotations

from dataclasses import dataclass

LOOP_SHARE = 0.145  # the loop's equivalent first-order lag over the plate's own tau: 0.37 ms / 2.55 ms on sim-plate


@dataclass(frozen=True)
class AmplitudeLoopPlate:
    """A plate profile (``devices.profiles.PlateProfile``) seen through an amplitude loop of ``time_constant_s``.

    Parameters
    ----------
    profile : PlateProfile
        The plate.
    time_constant_s : float
        The amplitude loop's equivalent first-order lag, s.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> profile = load_profile("sim-plate")
    >>> seen = AmplitudeLoopPlate.of(profile)
    >>> seen.name, seen.max_amplitude_um_pp, round(seen.time_constant_s / profile.time_constant_s, 6)
    ('sim-plate', 6.0, 0.145)
    """

    profile: object
    time_constant_s: float

    @classmethod
    def of(cls, profile, time_constant_s: float | None = None) -> AmplitudeLoopPlate:
        """The loop's lag as given, else the share of the plate's own that the reference firmware's loop has.

        Parameters
        ----------
        profile : PlateProfile
        time_constant_s : float, optional
            The loop's lag, s.

        Returns
        -------
        AmplitudeLoopPlate

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> profile = load_profile("sim-plate")
        >>> AmplitudeLoopPlate.of(profile, 0.001).time_constant_s
        0.001
        >>> round(AmplitudeLoopPlate.of(profile).time_constant_s, 9) == round(LOOP_SHARE * profile.time_constant_s, 9)
        True
        """
        return cls(profile, time_constant_s if time_constant_s is not None else LOOP_SHARE * profile.time_constant_s)

    @property
    def name(self) -> str:
        """The plate's name.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> AmplitudeLoopPlate.of(load_profile("sim-plate")).name
        'sim-plate'
        """
        return self.profile.name

    @property
    def resonance_hz(self) -> float:
        """The plate's resonance (Hz).

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> AmplitudeLoopPlate.of(load_profile("sim-plate")).resonance_hz
        25000.0
        """
        return self.profile.resonance_hz

    @property
    def max_amplitude_um_pp(self) -> float:
        """The plate's safe limit (µm p-p).

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> AmplitudeLoopPlate.of(load_profile("sim-plate")).max_amplitude_um_pp
        6.0
        """
        return self.profile.max_amplitude_um_pp

    @property
    def max_drive_um_pp(self) -> float:
        """The limit (µm p-p): the targets sent are amplitudes, and the firmware caps them there (no overdrive).

        Examples
        --------
        The plate's own ceiling is 8 µm p-p; through the loop, the limit:

        >>> from ultraglide.devices.profiles import load_profile
        >>> profile = load_profile("sim-plate")
        >>> profile.max_drive_um_pp, AmplitudeLoopPlate.of(profile).max_drive_um_pp
        (8.0, 6.0)
        """
        return self.profile.max_amplitude_um_pp  # targets: the firmware caps them at the limit

    @property
    def full_scale_um_pp(self) -> float:
        """The plate's amplitude at full-scale drive (µm p-p).

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> AmplitudeLoopPlate.of(load_profile("sim-plate")).full_scale_um_pp
        8.0
        """
        return self.profile.full_scale_um_pp

    def check_carrier(self, carrier_hz: float, audio_rate_hz: float | None = None) -> None:
        """The plate profile's carrier check (Hz): DeviceError outside its range.

        Parameters
        ----------
        carrier_hz : float
            Hz.
        audio_rate_hz : float, optional
            Hz.

        Raises
        ------
        DeviceError
            A carrier outside the plate's range.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> AmplitudeLoopPlate.of(load_profile("sim-plate")).check_carrier(30000.0)
        Traceback (most recent call last):
        ...
        ultraglide.devices.errors.CarrierError: carrier 30000 Hz is outside plate sim-plate's range 20000-28000 Hz
        """
        self.profile.check_carrier(carrier_hz, audio_rate_hz)

    def __repr__(self) -> str:
        return f"AmplitudeLoopPlate({self.profile.name!r}, loop lag {1000 * self.time_constant_s:.2f} ms)"
