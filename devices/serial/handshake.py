"""The plate driver's handshake, as pure functions: the device's HELLO_REPLY checked against what the host will
send, the limits that bind once both sides have spoken, and the plate a device describes itself (its profile
where nobody named one: :func:`plate_of_hello`, carried between processes as a ``hello:`` spec)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.protocol.ranges import hello_out_of_range


@dataclass(frozen=True)
class Limits:
    """What binds the output (µm p-p): the amplitude limit, the drive ceiling, the full scale codes are scaled
    by, and the largest fraction of full scale a code may carry (the ceiling, rounded down to a code)."""

    limit_um_pp: float
    max_drive_um_pp: float
    full_scale_um_pp: float
    top_fraction: float = 1.0

    @classmethod
    def of(cls, profile: PlateProfile) -> Limits:
        """The profile's limits, before any device has spoken."""
        return cls(profile.max_amplitude_um_pp, profile.max_drive_um_pp, profile.full_scale_um_pp)


def check_device(port: str, raw: bytes, carrier_hz: float, rate_hz: int | None,
                 batch_s: float | None = None) -> p.HelloReply:
    """The device's HELLO_REPLY, if it speaks our version and can play what we will send (``rate_hz`` setpoints/s
    in frames of ``batch_s``; None: not chosen yet) over the link it says it has; DeviceError in one line
    otherwise."""
    try:
        version = p.hello_reply_version(raw)
        if version not in p.SUPPORTED_VERSIONS:
            speaks = " or ".join(f"v{v}" for v in p.SUPPORTED_VERSIONS)
            raise DeviceError(f"{port}: the plate driver speaks protocol v{version}; this ultraglide "
                              f"speaks {speaks}: update the firmware (see docs/protocol.md)")
        hello = p.parse_hello_reply(raw)
    except p.ProtocolError as error:
        raise DeviceError(f"{port}: the plate driver's handshake reply is malformed ({error})") from None
    impossible = hello_out_of_range(hello)  # every field within what it can be (devices/protocol/ranges.py)
    if impossible:
        raise DeviceError(f"{port}: the plate driver's handshake reply cannot be believed: {'; '.join(impossible)}")
    if not hello.carrier_min_hz <= carrier_hz <= hello.carrier_max_hz:
        raise DeviceError(f"{port}: carrier {carrier_hz:g} Hz is outside what the plate driver "
                          f"accepts, {hello.carrier_min_hz:g}-{hello.carrier_max_hz:g} Hz")
    if rate_hz is not None and not hello.min_setpoint_rate_hz <= rate_hz <= hello.max_setpoint_rate_hz:
        raise DeviceError(f"{port}: the plate driver plays {hello.min_setpoint_rate_hz}-"
                          f"{hello.max_setpoint_rate_hz} setpoints/s, not {rate_hz}")
    if rate_hz is not None and batch_s is not None and hello.states_link:
        needed = p.FRAME_OVERHEAD_BYTES / batch_s + 2.0 * rate_hz  # the byte budget (devices/serial/link.py)
        if needed > hello.link_bytes_per_s:
            raise DeviceError(f"serial:{port}: the plate driver's link carries {hello.link_bytes_per_s} bytes/s (its "
                              f"handshake says); a stream of {rate_hz} setpoints/s in {batch_s * 1000:g} ms frames "
                              f"needs {needed:.0f}: ask for less (rate=, frame_ms=), or leave both out and the host "
                              "fits the stream to the link")
    for name in ("full_scale_um_pp", "max_amplitude_um_pp"):
        value = getattr(hello, name)
        if not (math.isfinite(value) and value > 0):
            raise DeviceError(f"{port}: the plate driver reports {name} = {value:g}; it must be a "
                              "positive number of µm p-p")
    return hello


def bind_limits(profile: PlateProfile, before: Limits, hello: p.HelloReply) -> tuple[Limits, list[str]]:
    """The device's limits bind: the smaller limit and drive ceiling, codes scaled by its full scale. Narrowed
    at each handshake from ``before``, never widened over a run. Returns the limits and one note per place
    where the device's facts differ from the profile's."""
    device_limit = hello.max_amplitude_um_pp
    device_drive = getattr(hello, "max_drive_um_pp", None)  # v2 declares none: no overdrive (protocol.py)
    if device_drive is None:
        device_drive = max(device_limit, profile.max_drive_um_pp)
    limit = min(before.limit_um_pp, device_limit)
    overdrive = profile.max_drive_um_pp > profile.max_amplitude_um_pp and device_drive > device_limit
    drive = min(before.max_drive_um_pp, device_drive, hello.full_scale_um_pp) if overdrive else limit
    max_drive = max(limit, drive)
    # the largest code whose drive is not above the ceiling: rounding to nearest could add half a code
    top = min(1.0, math.floor(max_drive / hello.full_scale_um_pp * p.SETPOINT_SCALE) / p.SETPOINT_SCALE)
    limits = Limits(limit, max_drive, hello.full_scale_um_pp, top)
    return limits, limit_notes(profile, limits, hello, device_limit, device_drive)


def limit_notes(profile: PlateProfile, limits: Limits, hello: p.HelloReply, device_limit: float,
                device_drive: float) -> list[str]:
    """Where the device's limits, full scale or drive ceiling differ from the profile's, in words."""
    notes = []
    if device_limit < profile.max_amplitude_um_pp:
        notes.append(f"the plate driver's limit is {device_limit:g} µm p-p, below the profile's "
                     f"{profile.max_amplitude_um_pp:g}: using {limits.limit_um_pp:g}")
    elif device_limit > profile.max_amplitude_um_pp:
        notes.append(f"the plate driver's limit is {device_limit:g} µm p-p, above the profile's "
                     f"{profile.max_amplitude_um_pp:g}: using the profile's {limits.limit_um_pp:g}")
    if hello.full_scale_um_pp != profile.full_scale_um_pp:
        notes.append(f"the plate driver's full scale is {hello.full_scale_um_pp:g} µm p-p, not the profile's "
                     f"{profile.full_scale_um_pp:g}: setpoint codes are scaled to the driver's")
    if profile.max_drive_um_pp > profile.max_amplitude_um_pp and limits.max_drive_um_pp < profile.max_drive_um_pp:
        if device_drive <= device_limit:
            why = "speaks protocol v2, which declares no overdrive" if hello.version < 3 else "allows no overdrive"
            notes.append(f"the plate driver {why}: drive held at the limit, {limits.max_drive_um_pp:g} µm p-p "
                         f"(the profile allows {profile.max_drive_um_pp:g})")
        else:
            notes.append(f"the plate driver allows drive up to {device_drive:g} µm p-p, below the profile's "
                         f"{profile.max_drive_um_pp:g}: using {limits.max_drive_um_pp:g}")
    return notes


HELLO_PREFIX = "hello:"  # a plate spec (apps/commands/plate_choice.py): the plate a device's handshake describes
_PLATE_FIELDS = ("resonance_hz", "q", "full_scale_um_pp", "max_amplitude_um_pp", "max_drive_um_pp", "carrier_min_hz",
                 "carrier_max_hz")


def plate_of_hello(hello: p.HelloReply) -> PlateProfile | None:
    """The plate a device describes in its handshake, as a profile: its resonance, Q, full scale, limit, drive
    ceiling and carrier range (µm p-p, Hz); None for a device that does not state its plate's Q (it says nothing of
    its link either: ``FEATURE_LINK_STATED``). The device's values come as float32 and are kept to 6 significant
    digits; the device's own limit binds at every handshake whatever the profile says (:func:`bind_limits`).

    Raises
    ------
    DeviceError
        What the device states is not a plate a profile may describe (one line).

    Examples
    --------
    >>> hello = p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "board", 8.0,
    ...                      features=p.FEATURE_LINK_STATED, link_bytes_per_s=14000, q=200.0)
    >>> plate_of_hello(hello)
    PlateProfile('board', 25 kHz, Q 200, limit 6 µm p-p, drive up to 8)
    """
    if not hello.states_link or not (math.isfinite(hello.q) and hello.q > 0):
        return None
    values = {name: float(f"{getattr(hello, name):.6g}") for name in _PLATE_FIELDS}
    values["max_drive_um_pp"] = min(max(values["max_drive_um_pp"], values["max_amplitude_um_pp"]),
                                    values["full_scale_um_pp"])
    try:
        return PlateProfile(name=hello.name or "plate driver", description="as the plate driver's handshake states",
                            **values)
    except DeviceError as error:
        raise DeviceError(f"the plate the driver describes in its handshake is not one a profile may hold: {error}; "
                          "give --profile or --rig") from None


def hello_spec(profile: PlateProfile) -> str:
    """``profile`` (from :func:`plate_of_hello`) as a plate spec, ``hello:{...}``, which :func:`plate_of_spec` (and
    so ``devices.rig.load_plate``, in any process) reads back."""
    return HELLO_PREFIX + json.dumps({"name": profile.name, **{name: getattr(profile, name) for name in _PLATE_FIELDS}})


def plate_of_spec(spec: str) -> PlateProfile:
    """The profile a ``hello:`` spec carries (:func:`hello_spec`); DeviceError in one line if it is not one."""
    try:
        values = json.loads(spec[len(HELLO_PREFIX):])
        if not isinstance(values, dict) or set(values) != {"name", *_PLATE_FIELDS}:
            raise ValueError("not the fields of a plate")
    except ValueError as error:
        raise DeviceError(f"{spec[:60]!r} is not a plate a handshake described ({error})") from None
    return PlateProfile(description="as the plate driver's handshake states", **values)
