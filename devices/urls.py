"""Devices by URL: ``sim``, ``serial:PORT[?baud=N]``, ``wav:PATH``, ``null``, and
``audio[:NAME_OR_INDEX][?rate=N&latency=SECONDS|low|high&blocksize=FRAMES]``."""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile

KINDS = ("sim", "serial", "audio", "wav", "null")


@dataclass(frozen=True)
class DeviceUrl:
    kind: str
    target: str = ""
    options: dict = field(default_factory=dict)


def parse_device_url(url: str) -> DeviceUrl:
    """Split a device URL; DeviceError says what forms there are."""
    body, _, query = url.partition("?")
    kind, _, target = body.partition(":")
    if kind not in KINDS:
        raise DeviceError(f"unknown device {url!r}; use sim, serial:PORT, audio[:NAME], wav:PATH or null")
    options = dict(parse_qsl(query))
    if kind in ("serial", "wav") and not target:
        raise DeviceError(f"{kind} needs a {'port' if kind == 'serial' else 'path'}: {kind}:...")
    for key in ("baud", "rate", "blocksize"):
        if key in options:
            try:
                options[key] = int(options[key])
            except ValueError:
                raise DeviceError(f"{key} must be a whole number in {url!r}") from None
    if "latency" in options and options["latency"] not in ("low", "high"):
        try:
            options["latency"] = float(options["latency"])
        except ValueError:
            raise DeviceError(f"latency is seconds, low or high in {url!r}") from None
    return DeviceUrl(kind, target, options)


class SimPlate:
    """``sim``: the simulated plate on an in-process pty, driven by the real serial driver."""

    signal = "control"

    def __init__(self, profile: PlateProfile, control_rate_hz: int, carrier_hz: float | None, tracker=None):
        from ultraglide.devices.plate_sim import PtyPlate
        from ultraglide.devices.serial_plate import SerialPlate

        self.plate = PtyPlate(profile).start()
        self.driver = SerialPlate(self.plate.path, profile, control_rate_hz, carrier_hz, tracker=tracker)
        self.rate_hz = control_rate_hz

    @property
    def telemetry(self):
        return self.driver.telemetry

    def fault_counts(self) -> dict[str, int]:
        return self.driver.fault_counts()

    def start(self, source) -> None:
        try:
            self.driver.start(source)
        except Exception:
            self.plate.stop()
            raise

    def stop(self) -> None:
        try:
            self.driver.stop()
        finally:
            self.plate.stop()

    def status(self) -> dict:
        return {**self.driver.status(), "device": "sim", "pty": self.plate.pty_name}


def open_device(url: str, profile: PlateProfile, control_rate_hz: int = 12000, carrier_hz: float | None = None,
                track_resonance: bool = False):
    """A device ready to ``start(source)``; its ``signal`` says whether it wants control or audio blocks.

    ``track_resonance``: a plate driver (sim, serial) follows its plate's drifting resonance from
    telemetry, starting from ``carrier_hz`` or the profile's; other devices report no amplitude, so
    asking them is a DeviceError."""
    spec = parse_device_url(url)
    carrier = carrier_hz or profile.resonance_hz
    tracker = None
    if track_resonance:
        if spec.kind not in ("sim", "serial"):
            raise DeviceError(f"{spec.kind} reports no measured amplitude, so it cannot track the resonance; "
                              "use a plate driver (sim or serial:PORT) or leave out resonance tracking")
        from ultraglide.devices.resonance import ResonanceTracker

        profile.check_carrier(carrier)
        tracker = ResonanceTracker(carrier, profile.q, profile.max_amplitude_um_pp, profile.carrier_min_hz,
                                   profile.carrier_max_hz)
    if spec.kind == "sim":
        return SimPlate(profile, control_rate_hz, carrier_hz, tracker)
    if spec.kind == "serial":
        from ultraglide.devices.serial_plate import SerialPlate

        return SerialPlate(spec.target, profile, control_rate_hz, carrier_hz, baudrate=spec.options.get("baud", 921600),
                           tracker=tracker)
    if spec.kind == "audio":
        from ultraglide.devices.audio import AudioPlate

        target = int(spec.target) if spec.target.isdigit() else (spec.target or None)
        return AudioPlate(target, profile, carrier, spec.options.get("rate"), spec.options.get("latency", "low"),
                          spec.options.get("blocksize", 0))
    from ultraglide.devices.paced import PacedSink, WavRecorder

    rate = spec.options.get("rate", 96000)
    if spec.kind == "wav":
        return WavRecorder(spec.target, profile, rate, carrier)
    return PacedSink(profile, rate, "null", carrier)
