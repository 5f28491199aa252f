"""Plate profiles: what is true of one plate, from a TOML file.

A profile gives the plate's resonance f0 and quality factor Q, its amplitude at full-scale drive
(µm peak-to-peak), its safe maximum amplitude, and the carrier range it accepts. The envelope of a
resonator driven near f0 follows a first-order low-pass with time constant tau = Q / (pi f0).

Bundled: ``sim-plate`` (25 kHz, Q = 200) and ``audio-generic``; any other name is a file path.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ultraglide.devices.errors import DeviceError

PROFILE_DIR = Path(__file__).parent / "profiles"
DEFAULT_PROFILE = "sim-plate"


@dataclass(frozen=True)
class PlateProfile:
    """One plate's facts; amplitudes in µm peak-to-peak."""

    name: str
    resonance_hz: float
    q: float
    full_scale_um_pp: float
    max_amplitude_um_pp: float
    carrier_min_hz: float = 20000.0
    carrier_max_hz: float = 28000.0
    description: str = ""

    def __post_init__(self) -> None:
        for field_name in ("resonance_hz", "q", "full_scale_um_pp", "max_amplitude_um_pp",
                           "carrier_min_hz", "carrier_max_hz"):
            value = getattr(self, field_name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise DeviceError(f"profile {self.name}: {field_name} must be a positive number, got {value!r}")
        if self.max_amplitude_um_pp > self.full_scale_um_pp:
            raise DeviceError(f"profile {self.name}: max_amplitude_um_pp cannot exceed full_scale_um_pp")
        if not self.carrier_min_hz <= self.resonance_hz <= self.carrier_max_hz:
            raise DeviceError(f"profile {self.name}: the resonance must lie within the carrier range")

    @property
    def time_constant_s(self) -> float:
        """tau = Q / (pi f0): how slowly the vibration envelope follows the drive."""
        return self.q / (math.pi * self.resonance_hz)

    @property
    def corner_hz(self) -> float:
        """The envelope's -3 dB frequency, 1 / (2 pi tau) = f0 / (2 Q)."""
        return 1.0 / (2.0 * math.pi * self.time_constant_s)

    def check_carrier(self, carrier_hz: float) -> None:
        if not self.carrier_min_hz <= carrier_hz <= self.carrier_max_hz:
            raise DeviceError(f"carrier {carrier_hz:g} Hz is outside plate {self.name}'s range "
                              f"{self.carrier_min_hz:g}-{self.carrier_max_hz:g} Hz")


def bundled_profiles() -> list[str]:
    return sorted(path.stem for path in PROFILE_DIR.glob("*.toml"))


def load_profile(spec: str = DEFAULT_PROFILE) -> PlateProfile:
    """A profile by bundled name or TOML path."""
    path = Path(spec)
    if not path.is_file():
        bundled = PROFILE_DIR / f"{spec}.toml"
        if "/" in spec or not bundled.is_file():
            raise DeviceError(f"no plate profile file or bundled profile {spec!r}; bundled: "
                              f"{', '.join(bundled_profiles())}")
        path = bundled
    try:
        with path.open("rb") as stream:
            data = tomllib.load(stream)
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise DeviceError(f"{path}: not a readable plate profile ({error})") from None
    known = set(PlateProfile.__dataclass_fields__)
    unknown = sorted(set(data) - known)
    if unknown:
        raise DeviceError(f"{path}: unknown profile keys {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    missing = [key for key in ("resonance_hz", "q", "full_scale_um_pp", "max_amplitude_um_pp") if key not in data]
    if missing:
        raise DeviceError(f"{path}: profile lacks {', '.join(missing)}")
    data.setdefault("name", path.stem)
    return PlateProfile(**data)
