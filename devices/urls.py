"""Devices by URL: ``sim``, ``serial:PORT[?baud=N&rate=SETPOINTS_PER_S&frame_ms=MS]``, ``wav:PATH``, ``null``,
and ``audio[:NAME_OR_INDEX][?rate=N&latency=SECONDS|low|high&blocksize=FRAMES]``.

A serial plate driver takes the control rate (12 000 setpoints/s) in frames of 1 or 2 ms by default; ``rate``
(a whole fraction of the control rate, each setpoint the mean of those it stands for) and ``frame_ms`` make the
stream fit a slower link, such as the board image under QEMU (``plate-sim --board qemu``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING
from urllib.parse import parse_qsl

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.source import Device
from ultraglide.devices.profiles import PlateProfile

if TYPE_CHECKING:
    from ultraglide.devices.sim.finger import SimulatedFinger

KINDS = ("sim", "serial", "audio", "wav", "null")
USAGE = ("use sim, serial:PORT[?baud=N&rate=N&frame_ms=N], audio[:NAME_OR_INDEX][?rate=N&latency=S&blocksize=N], "
         "wav:PATH[?rate=N] or null")


@dataclass(frozen=True)
class Whole:
    """A whole-number option and its range."""

    low: int
    high: int
    unit: str = ""

    def parse(self, key: str, text: str, url: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not self.low <= value <= self.high:
            raise DeviceError(f"{key} must be a whole number in {self.low}..{self.high}{self.unit} in {url!r}, "
                              f"got {text!r}")
        return value


@dataclass(frozen=True)
class Seconds:
    """A duration in seconds (or one of ``words``) and its range, ``low`` excluded."""

    low: float
    high: float
    words: tuple[str, ...] = ()

    def parse(self, key: str, text: str, url: str) -> float | str:
        if text in self.words:
            return text
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not self.low < value <= self.high:  # NaN fails too
            either = f" or {' or '.join(self.words)}" if self.words else ""
            raise DeviceError(f"{key} is seconds, more than {self.low:g} and up to {self.high:g}{either}, "
                              f"in {url!r}, got {text!r}")
        return value


SAMPLE_RATE = Whole(12_000, 768_000, " Hz")  # a whole multiple of the 12 kHz control rate carries the carrier
OPTIONS = {  # the keys each kind of device takes, and their ranges
    "sim": {},
    "serial": {"baud": Whole(50, 12_000_000, " baud"), "rate": Whole(1000, 12_000, " setpoints/s"),
               "frame_ms": Whole(1, 20, " ms")},
    "audio": {"rate": Whole(8_000, 768_000, " Hz"), "latency": Seconds(0.0, 10.0, ("low", "high")),
              "blocksize": Whole(0, 65_536, " frames")},
    "wav": {"rate": SAMPLE_RATE},
    "null": {"rate": SAMPLE_RATE},
}
TARGETS = {"sim": None, "serial": "a port", "audio": "", "wav": "a path", "null": None}  # None: takes none


@dataclass(frozen=True)
class DeviceUrl:
    kind: str
    target: str = ""
    options: dict = field(default_factory=dict)


def parse_device_url(url: str) -> DeviceUrl:
    """Split a device URL and check it: the kind, its target, and each option's key and range.
    :class:`DeviceError` says what forms there are."""
    body, _, query = url.partition("?")
    kind, colon, target = body.partition(":")
    if kind not in KINDS:
        raise DeviceError(f"unknown device {url!r}; {USAGE}")
    wants = TARGETS[kind]
    if wants is None and (colon or target):
        raise DeviceError(f"{kind} takes no port or path, got {url!r}; {USAGE}")
    if wants and not target:
        raise DeviceError(f"{kind} needs {wants}: {kind}:{'PORT' if kind == 'serial' else 'PATH'}")
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise DeviceError(f"options are KEY=VALUE joined by &, got {query!r} in {url!r}") from None
    known = OPTIONS[kind]
    options: dict = {}
    for key, text in pairs:
        if key not in known:
            takes = f"takes {', '.join(known)}" if known else "takes no options"
            raise DeviceError(f"unknown option {key!r} for {kind} in {url!r}; {kind} {takes}")
        if key in options:
            raise DeviceError(f"option {key} is given twice in {url!r}")
        options[key] = known[key].parse(key, text, url)
    return DeviceUrl(kind, target, options)


# The simulated plate is a thread of this process: on a loaded machine it answers late, but it answers. The
# driver waits this long for its answers and its telemetry (a plate driver on a port gets the protocol's 2 s
# and 0.5 s): a silence of the simulated plate is this machine being busy, not a plate lost.
SIM_ANSWER_TIMEOUT_S = 60.0


class SimPlate:
    """``sim``: the simulated plate on an in-process pty, driven by the real serial driver."""

    signal = "control"

    def __init__(self, profile: PlateProfile, control_rate_hz: int, carrier_hz: float | None, tracker=None,
                 finger=None, amplitude_loop: bool = False):
        from ultraglide.devices.serial.plate import SerialPlate
        from ultraglide.devices.sim.pty_plate import PtyPlate

        self.finger = finger
        self.plate = PtyPlate(profile, finger=finger).start()
        self.driver = SerialPlate(self.plate.path, profile, control_rate_hz, carrier_hz, tracker=tracker,
                                  ack_timeout_s=SIM_ANSWER_TIMEOUT_S, silence_s=SIM_ANSWER_TIMEOUT_S,
                                  amplitude_loop=amplitude_loop)
        self.rate_hz = control_rate_hz

    def add_sensor_listener(self, listener) -> None:
        self.driver.add_sensor_listener(listener)

    def add_clock_listener(self, listener) -> None:
        self.driver.add_clock_listener(listener)

    def hello(self):
        return self.driver.hello()

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
            if self.finger is not None:
                self.finger.close()  # its log appears whole

    def status(self) -> dict:
        return {**self.driver.status(), "device": "sim", "pty": self.plate.pty_name}


def open_device(url: str, profile: PlateProfile, control_rate_hz: int = 12000, carrier_hz: float | None = None,
                track_resonance: bool = False, finger: SimulatedFinger | None = None,
                amplitude_loop: bool = False) -> Device:
    """A device ready to ``start(source)``, by URL; its ``signal`` says whether it wants control or audio.

    ``track_resonance``: a plate driver (sim, serial) follows its plate's drifting resonance from
    telemetry, starting from ``carrier_hz`` or the profile's; other devices report no amplitude, so
    asking them is a DeviceError.

    Parameters
    ----------
    url : str
        ``sim`` (the simulated plate: the real serial driver and the simulated firmware on a pty),
        ``serial:PORT[?baud=N&rate=N]``, ``audio[:NAME_OR_INDEX][?rate=N]``, ``wav:PATH`` or ``null``.
    profile : PlateProfile
        The plate driven (:func:`load_profile`): its limits hold on whatever leaves.
    control_rate_hz : int
        The envelope's rate (Hz).
    carrier_hz : float, optional
        The carrier (Hz); the profile's resonance by default.
    track_resonance : bool
        Follow the plate's resonance from telemetry (plate drivers only).
    finger : SimulatedFinger, optional
        A simulated finger (and force sensors) on the ``sim`` plate.
    amplitude_loop : bool
        Turn the firmware's amplitude loop on, where the plate driver has one.

    Returns
    -------
    Device
        Not started: ``device.start(ultraglide.renderer_source(device, renderer))`` plays a renderer;
        ``device.stop()`` ramps to rest and rests the hardware.

    Raises
    ------
    DeviceError
        A URL or option the device refuses, in one line.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> device = open_device("null", load_profile("sim-plate"))   # takes audio and discards it
    >>> device.signal, device.rate_hz
    ('audio', 96000)
    """
    spec = parse_device_url(url)
    carrier = carrier_hz or profile.resonance_hz
    tracker = None
    if track_resonance:
        if spec.kind not in ("sim", "serial"):
            raise DeviceError(f"{spec.kind} reports no measured amplitude, so it cannot track the resonance; "
                              "use a plate driver (sim or serial:PORT) or leave out resonance tracking")
        from ultraglide.devices.characterisation.resonance import ResonanceTracker

        profile.check_carrier(carrier)
        tracker = ResonanceTracker(carrier, profile.q, profile.max_amplitude_um_pp, profile.carrier_min_hz,
                                   profile.carrier_max_hz)
    if spec.kind == "sim":
        return SimPlate(profile, control_rate_hz, carrier_hz, tracker, finger, amplitude_loop)
    if spec.kind == "serial":
        from ultraglide.devices.serial.handshake import check_device
        from ultraglide.devices.serial.link import StreamPlan, choose_stream, probe_hello
        from ultraglide.devices.serial.plate import SerialPlate

        rate = spec.options.get("rate")
        if rate is not None and control_rate_hz % rate:
            raise DeviceError(f"rate must divide the control rate, {control_rate_hz} setpoints/s (e.g. 1000, 2000, "
                              f"3000, 4000, 6000), in {url!r}, got {rate}")
        frame_s = spec.options["frame_ms"] / 1000.0 if "frame_ms" in spec.options else None
        baud = spec.options.get("baud", 921600)
        # the link decides the stream: the device's handshake says what its link carries (a first HELLO, which
        # changes nothing on the device), and the stream is fitted to it; the URL's rate or frame_ms win where
        # they fit. A device that says nothing gets the default stream, and the run says so.
        if rate is not None and frame_s is not None:  # the URL says it all: checked at the handshake, where the
            asked = StreamPlan(rate, frame_s, 0, "url")  # device says what its link carries
            return SerialPlate(spec.target, profile, rate, carrier_hz, baudrate=baud, batch_s=frame_s,
                               tracker=tracker, amplitude_loop=amplitude_loop, stream=asked)
        raw = probe_hello(spec.target, baud)
        hello = check_device(spec.target, raw, carrier, None)
        stream = choose_stream(spec.target, hello, control_rate_hz, baud, rate, frame_s)
        check_device(spec.target, raw, carrier, stream.rate_hz)  # the device plays that rate
        return SerialPlate(spec.target, profile, stream.rate_hz, carrier_hz, baudrate=baud, batch_s=stream.batch_s,
                           tracker=tracker, amplitude_loop=amplitude_loop, stream=stream)
    if spec.kind == "audio":
        from ultraglide.devices.sinks.audio import AudioPlate

        target = int(spec.target) if spec.target.isdigit() else (spec.target or None)
        return AudioPlate(target, profile, carrier, spec.options.get("rate"), spec.options.get("latency", "low"),
                          spec.options.get("blocksize", 0))
    from ultraglide.devices.sinks.paced import PacedSink, WavRecorder

    rate = spec.options.get("rate", 96000)
    if spec.kind == "wav":
        return WavRecorder(spec.target, profile, rate, carrier)
    return PacedSink(profile, rate, "null", carrier)
