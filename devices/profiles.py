"""Plate profiles: what is true of one plate, from a TOML file, typed and range-checked.

A profile gives the plate's resonance f0 and quality factor Q, its amplitude at full-scale drive
(µm peak-to-peak), its safe maximum amplitude, how far above that maximum the drive may go for a
moment (``max_drive_um_pp``, overdrive for pre-compensation; by default no overdrive), and the
carrier range it accepts. The envelope of a resonator driven near f0 follows a first-order low-pass
with time constant tau = Q / (pi f0).

Every value is checked when a profile is made: a wrong one is a :class:`DeviceError` naming the
key, the value and the allowed range. Resonances and carriers below 20 kHz are audible and refused
unless the profile says ``allow_audible = true``.

Bundled: ``sim-plate`` (25 kHz, Q = 200) and ``audio-generic``; any other name is a file path.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from ultraglide.devices.errors import CarrierError, DeviceError
from ultraglide.devices.protocol.spec import SETPOINT_SCALE

from ultraglide.inputs import parse_toml, read_input, some_of

PROFILE_DIR = Path(__file__).parent / "profiles"
DEFAULT_PROFILE = "sim-plate"

AUDIBLE_HZ = 20000.0  # below this a plate sings: refused unless allow_audible
LOWEST_HZ = 1000.0  # the lowest resonance or carrier even with allow_audible
HIGHEST_HZ = 100000.0
Q_RANGE = (5.0, 5000.0)
FULL_SCALE_RANGE_UM_PP = (0.01, 100.0)
REQUIRED = ("resonance_hz", "q", "full_scale_um_pp", "max_amplitude_um_pp")
NUMBERS = ("resonance_hz", "q", "full_scale_um_pp", "max_amplitude_um_pp", "carrier_min_hz", "carrier_max_hz",
           "max_drive_um_pp")


class ProfileError(DeviceError):
    """A plate profile that cannot be used (no such profile, a file that is not one, a value out of range); the
    message is one line naming the file and what to change. A ``DeviceError`` too.

    Examples
    --------
    >>> load_profile("no-such-plate")
    Traceback (most recent call last):
    ...
    ultraglide.devices.profiles.ProfileError: no plate profile file or bundled profile 'no-such-plate'; bundled: ...
    """


@dataclass(frozen=True)
class PlateProfile:
    """One plate's facts; amplitudes in µm peak-to-peak, frequencies in Hz.

    ``max_amplitude_um_pp`` is the plate's safe limit: the steady amplitude the drive commands
    never exceeds it. ``max_drive_um_pp`` (between the limit and full scale; None: the limit)
    is the overdrive granted for pre-compensation, see :mod:`ultraglide.devices.output.limiter`.

    Parameters
    ----------
    name : str
        The plate's name, not empty.
    resonance_hz : float
        The plate's resonance (Hz), within the carrier range.
    q : float
        Its quality factor: the vibration's envelope follows the drive with tau = Q / (pi f0).
    full_scale_um_pp : float
        The steady amplitude (µm p-p) at full-scale drive.
    max_amplitude_um_pp : float
        The safe limit (µm p-p), from one step of the 16-bit drive up to full scale.
    carrier_min_hz, carrier_max_hz : float
        The carriers (Hz) the plate may be driven at; 20-28 kHz by default.
    description : str
        A sentence for people.
    max_drive_um_pp : float or None
        The overdrive (µm p-p) granted for pre-compensation, from the limit to full scale; None: the limit.
    allow_audible : bool
        Allow a resonance or carrier below 20 kHz (the plate then sings).

    Raises
    ------
    DeviceError
        A value that is not a finite number or lies outside its range, in one line naming the key.

    Examples
    --------
    >>> plate = PlateProfile("bench", resonance_hz=24000.0, q=150.0, full_scale_um_pp=10.0, max_amplitude_um_pp=5.0)
    >>> plate
    PlateProfile('bench', 24 kHz, Q 150, limit 5 µm p-p)
    >>> plate.max_drive_um_pp                                # no overdrive given: the limit (µm p-p)
    5.0
    >>> round(plate.time_constant_s * 1000, 2), plate.corner_hz   # ms, Hz: f0 / 2Q
    (1.99, 80.0)
    """

    name: str
    resonance_hz: float
    q: float
    full_scale_um_pp: float
    max_amplitude_um_pp: float
    carrier_min_hz: float = 20000.0
    carrier_max_hz: float = 28000.0
    description: str = ""
    max_drive_um_pp: float | None = None
    allow_audible: bool = False

    def __repr__(self) -> str:
        """``PlateProfile('sim-plate', 25 kHz, Q 200, limit 6 µm p-p)``."""
        overdrive = "" if self.max_drive_um_pp in (None, self.max_amplitude_um_pp) else \
            f", drive up to {self.max_drive_um_pp:g}"
        return (f"PlateProfile({self.name!r}, {self.resonance_hz / 1000:g} kHz, Q {self.q:g}, "
                f"limit {self.max_amplitude_um_pp:g} µm p-p{overdrive})")

    @property
    def shown_name(self) -> str:
        r"""The name as a message shows it: as written, or quoted with its escapes when it holds a line break
        or another control character, so that a refusal stays one line whatever the file says.

        Examples
        --------
        >>> PlateProfile("bench", 24000.0, 150.0, full_scale_um_pp=10.0, max_amplitude_um_pp=5.0).shown_name
        'bench'
        >>> PlateProfile("bench\nrm -rf", 24000.0, 150.0, full_scale_um_pp=10.0, max_amplitude_um_pp=5.0).shown_name
        "'bench\\nrm -rf'"
        """
        return self.name if self.name.isprintable() else repr(self.name)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise DeviceError(f"profile name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.description, str):
            raise DeviceError(f"profile {self.shown_name}: description must be a string, got {self.description!r}")
        if not isinstance(self.allow_audible, bool):
            raise DeviceError(f"profile {self.shown_name}: allow_audible must be true or false, "
                              f"got {self.allow_audible!r}")
        if self.max_drive_um_pp is None:
            object.__setattr__(self, "max_drive_um_pp", self.max_amplitude_um_pp)
        for key in NUMBERS:
            object.__setattr__(self, key, self._number(key))
        lowest = LOWEST_HZ if self.allow_audible else AUDIBLE_HZ
        for key in ("resonance_hz", "carrier_min_hz", "carrier_max_hz"):
            value = getattr(self, key)
            if value < AUDIBLE_HZ and not self.allow_audible:
                raise DeviceError(f"profile {self.shown_name}: {key} = {value:g} Hz is audible (below 20000 Hz); "
                                  "a plate there sings: set allow_audible = true in the profile if you mean it")
            self._within(key, value, lowest, HIGHEST_HZ, "Hz")
        self._within("q", self.q, *Q_RANGE)
        self._within("full_scale_um_pp", self.full_scale_um_pp, *FULL_SCALE_RANGE_UM_PP, "µm p-p")
        # a limit finer than one step of the drive's 16-bit setpoints could only be kept by never driving the plate
        self._within("max_amplitude_um_pp", self.max_amplitude_um_pp, self.full_scale_um_pp / SETPOINT_SCALE,
                     self.full_scale_um_pp, "µm p-p (from one step of the 16-bit drive to full_scale_um_pp)")
        self._within("max_drive_um_pp", self.max_drive_um_pp, self.max_amplitude_um_pp, self.full_scale_um_pp,
                     "µm p-p (from max_amplitude_um_pp to full_scale_um_pp)")
        self._within("carrier_max_hz", self.carrier_max_hz, self.carrier_min_hz, HIGHEST_HZ,
                     "Hz (from carrier_min_hz)")
        self._within("resonance_hz", self.resonance_hz, self.carrier_min_hz, self.carrier_max_hz,
                     "Hz (the resonance must lie within the carrier range)")

    def _number(self, key: str) -> float:
        value = getattr(self, key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise DeviceError(f"profile {self.shown_name}: {key} must be a number, got {value!r}")
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            raise DeviceError(f"profile {self.shown_name}: {key} must be a finite number, got {value!r}")
        return number

    def _within(self, key: str, value: float, low: float, high: float, unit: str = "", open_low: bool = False):
        if value < low or value > high or (open_low and value == low):
            raise DeviceError(f"profile {self.shown_name}: {key} = {value:g} is outside {low:g}..{high:g} "
                              f"{unit}".rstrip())

    @property
    def time_constant_s(self) -> float:
        """tau = Q / (pi f0) (s): how slowly the vibration envelope follows the drive.

        Examples
        --------
        >>> round(load_profile("sim-plate").time_constant_s * 1000, 3)    # ms: Q 200 at 25 kHz
        2.546
        """
        return self.q / (math.pi * self.resonance_hz)

    @property
    def corner_hz(self) -> float:
        """The envelope's -3 dB frequency (Hz), 1 / (2 pi tau) = f0 / (2 Q).

        Examples
        --------
        >>> round(load_profile("sim-plate").corner_hz, 6)                 # 25 kHz / (2 × 200)
        62.5
        """
        return 1.0 / (2.0 * math.pi * self.time_constant_s)

    def check_carrier(self, carrier_hz: float, audio_rate_hz: float | None = None) -> None:
        """Refuse a carrier outside the plate's range, or one an audio rate cannot carry.

        Parameters
        ----------
        carrier_hz : float
            The carrier (Hz).
        audio_rate_hz : float, optional
            The audio rate (Hz) that is to carry it.

        Raises
        ------
        CarrierError
            The carrier is outside ``carrier_min_hz``..``carrier_max_hz``, or the rate cannot carry it.

        Examples
        --------
        >>> load_profile("sim-plate").check_carrier(30000.0)
        Traceback (most recent call last):
        ...
        ultraglide.devices.errors.CarrierError: carrier 30000 Hz is outside plate sim-plate's range 20000-28000 Hz
        """
        if not self.carrier_min_hz <= carrier_hz <= self.carrier_max_hz:
            raise CarrierError(f"carrier {carrier_hz:g} Hz is outside plate {self.shown_name}'s range "
                              f"{self.carrier_min_hz:g}-{self.carrier_max_hz:g} Hz")
        if audio_rate_hz is not None:
            from ultraglide.devices.output.carrier import check_carrier

            check_carrier(carrier_hz, audio_rate_hz)


def bundled_profiles() -> list[str]:
    """The names of the plate profiles that come with ultraglide.

    Returns
    -------
    list of str
        Sorted; each loads with :func:`load_profile`.

    Examples
    --------
    >>> "sim-plate" in bundled_profiles()
    True
    """
    return sorted(path.stem for path in PROFILE_DIR.glob("*.toml"))


def load_profile(spec: str = DEFAULT_PROFILE) -> PlateProfile:
    """A plate profile by bundled name or TOML file: the plate's resonance, Q, full scale and limits.

    A path that is not a regular file (a pipe, a device, a directory) is refused without being read.

    Parameters
    ----------
    spec : str
        A bundled profile's name (``sim-plate``, the default) or a ``.toml`` file.

    Returns
    -------
    PlateProfile

    Raises
    ------
    ProfileError
        No such profile, or what is wrong with the file, in one line (a :class:`DeviceError`).

    Examples
    --------
    >>> plate = load_profile("sim-plate")
    >>> plate.resonance_hz, plate.max_amplitude_um_pp, plate.full_scale_um_pp
    (25000.0, 6.0, 8.0)
    """
    spec = os.fspath(spec)
    path = Path(spec)
    bundled = PROFILE_DIR / f"{spec}.toml"
    if not os.path.lexists(path) or ("/" not in spec and bundled.is_file() and not path.is_file()):
        if "/" in spec or not bundled.is_file():
            raise ProfileError(f"no plate profile file or bundled profile {spec!r}; bundled: "
                                f"{', '.join(bundled_profiles())}")
        path = bundled
    data = parse_toml(read_input(path, "plate profile", ProfileError), f"{path}", ProfileError, what="plate profile")
    known = set(PlateProfile.__dataclass_fields__)
    unknown = sorted(set(data) - known)
    if unknown:
        raise ProfileError(f"{path}: unknown profile keys {some_of(unknown)}; known: {', '.join(sorted(known))}")
    missing = [key for key in REQUIRED if key not in data]
    if missing:
        raise ProfileError(f"{path}: profile lacks {', '.join(missing)}")
    data.setdefault("name", path.stem)
    try:
        return PlateProfile(**data)
    except DeviceError as error:  # name the file the value came from
        raise ProfileError(f"{path}: {error}") from None
