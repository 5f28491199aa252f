"""Protocol v3's replies and reports, device → host: HELLO_REPLY, ACK, NAK, TELEMETRY and SENSORS as values
and payloads, in v3's layouts and v2's. Re-exported by :mod:`ultraglide.devices.protocol`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np
from ultraglide.devices.protocol.commands import FORCE_REFERENCE_LAYOUT, SETPOINT_HEADER_LAYOUT
from ultraglide.devices.protocol.frames import ProtocolError
from ultraglide.devices.protocol.spec import (
    FAULT_BITS,
    FAULT_NAMES,
    FEATURE_AMPLITUDE_LOOP,
    FEATURE_CLOCK_STATED,
    FEATURE_FORCE_CORRECTION,
    FEATURE_LINK_STATED,
    FEATURE_RESET_STATED,
    LOOP_OPEN,
    MAX_NAME_BYTES,
    MAX_SENSOR_SAMPLES,
    PLAYBACK_OFF,
    PROTOCOL_VERSION,
    RESTART_DETAIL_FROM_RAM,
    RESTART_FAULT,
    RESTART_PIN,
    RESTART_POWER_ON,
    RESTART_WATCHDOG,
    RESTART_WORDS,
)

_HELLO_REPLY_V2 = struct.Struct("<BfffIIffHH")
# v2's fields, then max_drive_um_pp, sensors, sensor_rate_hz, features
_HELLO_REPLY_V3 = struct.Struct("<BfffIIffHHfBHB")
# v3's, then (with FEATURE_LINK_STATED) link_bytes_per_s and q, before the name
_HELLO_REPLY_LINK = struct.Struct("<BfffIIffHHfBHBIf")
_LINK_FIELDS = struct.Struct("<If")  # FEATURE_LINK_STATED's, after v3's
_RESET_FIELDS = struct.Struct("<BI")  # FEATURE_RESET_STATED's restart_reason and restart_detail, after those
_ACK = struct.Struct("<H")
_NAK = struct.Struct("<HB")
_TELEMETRY_V2 = struct.Struct(f"<ffHB7I{FAULT_BITS}I")
# v2's fields, then overrun_setpoints, expected_index, stream_rate_hz, buffered_setpoints, drive_code, playback, loop
_TELEMETRY_V3 = struct.Struct(f"<ffHB7I{FAULT_BITS}IIIIHHBB")
_SENSORS_HEADER = struct.Struct("<IIB")
_CLOCK_REPLY = struct.Struct("<HIH")  # asked_seq, sample, fraction (of a sample, / 65536)
_SENSOR_SAMPLE = np.dtype([("amplitude_um_pp", "<f4"), ("normal_force_n", "<f4"), ("lateral_force_n", "<f4")])


@dataclass(frozen=True)
class HelloReply:
    """What the device says about itself; amplitudes in µm peak-to-peak.

    The last six fields are v3's; a v2 reply reads as no overdrive (``max_drive_um_pp`` = the limit), no
    sensors and no features. ``link_bytes_per_s`` and ``q`` come with ``FEATURE_LINK_STATED`` only (0: not
    stated): what the device's link carries from the host, sustained (bytes/s), and its plate's quality factor."""

    version: int
    resonance_hz: float  # the resonance the firmware was configured with (nominal)
    full_scale_um_pp: float
    max_amplitude_um_pp: float
    min_setpoint_rate_hz: int
    max_setpoint_rate_hz: int
    carrier_min_hz: float
    carrier_max_hz: float
    watchdog_ms: int
    buffer_ms: int
    name: str
    max_drive_um_pp: float | None = None  # v3: the drive ceiling for brief overdrive (None: the limit)
    sensors: int = 0  # v3: SENSOR_* bits
    sensor_rate_hz: int = 0  # v3: sensor samples a second (0 without sensors)
    features: int = 0  # v3: FEATURE_* bits
    link_bytes_per_s: int = 0  # v3 with FEATURE_LINK_STATED: host-to-device bytes a second it takes (0: unstated)
    q: float = 0.0  # v3 with FEATURE_LINK_STATED: the plate's nominal quality factor (0: unstated)
    restart_reason: int | None = None  # v3 with FEATURE_RESET_STATED: why the board last started (RESTART_*)
    restart_detail: int = 0  # ... the watchdog's marks seen (bits 0-1) or the fault's status (CFSR); else 0

    def __post_init__(self) -> None:
        if self.max_drive_um_pp is None:
            object.__setattr__(self, "max_drive_um_pp", self.max_amplitude_um_pp)

    @property
    def has_amplitude_loop(self) -> bool:
        return bool(self.features & FEATURE_AMPLITUDE_LOOP)

    @property
    def states_link(self) -> bool:
        """The device states what its link carries (and its plate's Q) in this reply."""
        return self.version >= 3 and bool(self.features & FEATURE_LINK_STATED) and self.link_bytes_per_s > 0

    def restart_words(self) -> str | None:
        """Why the board last started, in words (None: not stated).

        After a watchdog, the marks that were missing; after a fault, its status; after a power-on or a reset
        with power kept that the board told from its RAM (``restart_detail`` bit 0, ``RESTART_DETAIL_FROM_RAM``:
        it has no reset-cause register, only a mark in RAM that a power-on clears), that it was so told, and
        for the reset pin that a debugger's reset or a watchdog's own hardware reset look the same there.

        Returns
        -------
        str or None
            E.g. ``its watchdog expired (the block interrupt's mark missing)``; None when the reply states no
            reason (no ``FEATURE_RESET_STATED``).

        Examples
        --------
        >>> from ultraglide.devices import protocol as p
        >>> def said(reason, detail):
        ...     return p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "board",
        ...                         features=p.FEATURE_RESET_STATED, restart_reason=reason,
        ...                         restart_detail=detail).restart_words()
        >>> said(p.RESTART_WATCHDOG, 2)
        "its watchdog expired (the block interrupt's mark missing)"
        >>> said(p.RESTART_POWER_ON, p.RESTART_DETAIL_FROM_RAM)
        'power-on (told from its RAM: the board has no reset-cause register)'
        """
        if self.restart_reason is None:
            return None
        words = RESTART_WORDS.get(self.restart_reason, f"reason {self.restart_reason}")
        from_ram = bool(self.restart_detail & RESTART_DETAIL_FROM_RAM)
        if self.restart_reason == RESTART_PIN and from_ram:
            words = ("its reset pin or another reset with power kept (told from its RAM: the board has no "
                     "reset-cause register, so a debugger's reset or its watchdog's own reset looks the same)")
        elif self.restart_reason == RESTART_POWER_ON and from_ram:
            words += " (told from its RAM: the board has no reset-cause register)"
        elif self.restart_reason == RESTART_WATCHDOG:
            missing = [name for bit, name in ((1, "the block interrupt's"), (2, "the main loop's"))
                       if not self.restart_detail & bit]
            if missing:
                words += f" ({' and '.join(missing)} mark{'s' if len(missing) > 1 else ''} missing)"
        elif self.restart_reason == RESTART_FAULT and self.restart_detail:
            words += f" (fault status {self.restart_detail:#010x})"
        return words

    @property
    def states_clock(self) -> bool:
        """v3's CLOCK: the device answers it at once with its sensor clock (a device with sensors)."""
        return self.version >= 3 and bool(self.features & FEATURE_CLOCK_STATED) and self.sensor_rate_hz > 0

    @property
    def has_force_correction(self) -> bool:
        """v3's SETPOINTS_FORCE: the device rescales values by the normal force it measures at play."""
        return self.version >= 3 and bool(self.features & FEATURE_FORCE_CORRECTION)


@dataclass(frozen=True)
class Telemetry:
    """One TELEMETRY frame. The fields after ``fault_counts`` are v3's (zero in a v2 frame)."""

    measured_um_pp: float
    carrier_hz: float
    faults: int  # latched fault bits
    enabled: bool
    frames_ok: int
    crc_errors: int
    framing_errors: int
    setpoints: int  # put in the buffer
    lost_setpoints: int  # skipped over by a forward jump of first_index
    late_setpoints: int  # arrived behind the stream (index already passed): dropped
    discarded_setpoints: int  # arrived while the output was disabled: dropped
    fault_counts: tuple[int, ...]  # one counter per fault bit, since power-up
    overrun_setpoints: int = 0  # v3: dropped because the buffer was full
    expected_index: int = 0  # v3: the stream index the device expects next (0 while no stream)
    stream_rate_hz: int = 0  # v3: the stream's rate (0: no stream; the next SETPOINTS after ENABLE 1 sets it)
    buffered_setpoints: int = 0  # v3: values waiting in the buffer
    drive_code: int = 0  # v3: the drive now, after the device's limiter, as a fraction of full scale × 65535
    playback: int = PLAYBACK_OFF  # v3: PLAYBACK_*
    loop: int = LOOP_OPEN  # v3: the loop mode in force
    version: int = PROTOCOL_VERSION  # the layout it came in (not on the wire: its length tells)

    def fault_names(self) -> list[str]:
        """The latched faults by name."""
        return [name for bit, name in FAULT_NAMES.items() if self.faults & bit]

    def counts_by_name(self) -> dict[str, int]:
        return {name: self.fault_counts[bit.bit_length() - 1] for bit, name in FAULT_NAMES.items()}


@dataclass(frozen=True, eq=False)
class Sensors:
    """One SENSORS frame: ``samples`` consecutive sensor samples from sample number ``first_sample``;
    ``setpoint_index`` is the stream index playing at the first one (NOT_PLAYING when none plays).
    ``samples`` is a structured array of amplitude_um_pp, normal_force_n and lateral_force_n (float32;
    NaN where the device lacks that sensor)."""

    first_sample: int
    setpoint_index: int
    samples: np.ndarray

    def __eq__(self, other) -> bool:
        return (isinstance(other, Sensors) and (self.first_sample, self.setpoint_index)
                == (other.first_sample, other.setpoint_index)
                and self.samples.tobytes() == np.asarray(other.samples, _SENSOR_SAMPLE).tobytes())

    def __repr__(self) -> str:
        return (f"Sensors(first_sample={self.first_sample}, setpoint_index={self.setpoint_index}, "
                f"{len(self.samples)} samples)")

def hello_reply_payload(reply: HelloReply) -> bytes:
    """The reply in its version's layout (v2's for version 2, v3's otherwise); the name cut to 64 bytes."""
    fields = (reply.version, reply.resonance_hz, reply.full_scale_um_pp, reply.max_amplitude_um_pp,
              reply.min_setpoint_rate_hz, reply.max_setpoint_rate_hz, reply.carrier_min_hz, reply.carrier_max_hz,
              reply.watchdog_ms, reply.buffer_ms)
    if reply.version <= 2:
        head = _HELLO_REPLY_V2.pack(*fields)
    else:
        head = _HELLO_REPLY_V3.pack(*fields, reply.max_drive_um_pp, reply.sensors, reply.sensor_rate_hz,
                                    reply.features)
        if reply.features & FEATURE_LINK_STATED:
            head += _LINK_FIELDS.pack(reply.link_bytes_per_s, reply.q)
        if reply.features & FEATURE_RESET_STATED:
            head += _RESET_FIELDS.pack(reply.restart_reason or 0, reply.restart_detail)
    return head + reply.name.encode()[:MAX_NAME_BYTES].decode("utf-8", "ignore").encode()  # whole characters


def hello_reply_version(payload: bytes) -> int:
    """The version a HELLO_REPLY speaks: its first byte, the same in every version."""
    if not payload:
        raise ProtocolError("empty hello reply")
    return payload[0]


def parse_hello_reply(payload: bytes) -> HelloReply:
    """A v2 or v3 reply, by its version byte (v3's layout for any version above 3: fields are only ever added
    at the end; v3's link fields before the name where its features say so). The name: at most 64 bytes taken,
    invalid UTF-8 replaced."""
    layout = _HELLO_REPLY_V2 if hello_reply_version(payload) <= 2 else _HELLO_REPLY_V3
    if len(payload) < layout.size:
        raise ProtocolError(f"hello reply of {len(payload)} bytes is shorter than "
                            f"v{min(payload[0], 3)}'s {layout.size}")
    fields = layout.unpack_from(payload)
    if layout is _HELLO_REPLY_V2:
        return HelloReply(*fields, payload[layout.size:layout.size + MAX_NAME_BYTES].decode("utf-8", "replace"))
    features, at, extra = fields[-1], layout.size, {}
    for bit, part, names in ((FEATURE_LINK_STATED, _LINK_FIELDS, ("link_bytes_per_s", "q")),
                             (FEATURE_RESET_STATED, _RESET_FIELDS, ("restart_reason", "restart_detail"))):
        if features & bit:
            if len(payload) < at + part.size:
                raise ProtocolError(f"hello reply of {len(payload)} bytes is shorter than the {at + part.size} "
                                    "its features say")
            extra.update(zip(names, part.unpack_from(payload, at), strict=True))
            at += part.size
    name = payload[at:at + MAX_NAME_BYTES].decode("utf-8", "replace")
    return HelloReply(*fields[:10], name, *fields[10:], **extra)


def ack_payload(seq: int) -> bytes:
    return _ACK.pack(seq & 0xFFFF)


def parse_ack(payload: bytes) -> int:
    if len(payload) != _ACK.size:
        raise ProtocolError("bad ack")
    return _ACK.unpack(payload)[0]


def nak_payload(seq: int, reason: int) -> bytes:
    return _NAK.pack(seq & 0xFFFF, reason)


def parse_nak(payload: bytes) -> tuple[int, int]:
    if len(payload) != _NAK.size:
        raise ProtocolError("bad nak")
    return _NAK.unpack(payload)


def telemetry_payload(t: Telemetry, version: int = PROTOCOL_VERSION) -> bytes:
    """TELEMETRY in the layout of ``version`` (2 or 3)."""
    counters = (t.frames_ok, t.crc_errors, t.framing_errors, t.setpoints, t.lost_setpoints, t.late_setpoints,
                t.discarded_setpoints)
    fields = (t.measured_um_pp, t.carrier_hz, t.faults, 1 if t.enabled else 0,
              *(c & 0xFFFFFFFF for c in counters), *(c & 0xFFFFFFFF for c in t.fault_counts))
    if version <= 2:
        return _TELEMETRY_V2.pack(*fields)
    return _TELEMETRY_V3.pack(*fields, t.overrun_setpoints & 0xFFFFFFFF, t.expected_index & 0xFFFFFFFF,
                              t.stream_rate_hz, t.buffered_setpoints, t.drive_code, t.playback, t.loop)


def parse_telemetry(payload: bytes) -> Telemetry:
    """A v2 (71 bytes) or v3 (89 bytes) TELEMETRY payload."""
    if len(payload) == _TELEMETRY_V3.size:
        values = _TELEMETRY_V3.unpack(payload)
        return Telemetry(values[0], values[1], values[2], bool(values[3]), *values[4:11], tuple(values[11:19]),
                         *values[19:], version=3)
    if len(payload) == _TELEMETRY_V2.size:
        values = _TELEMETRY_V2.unpack(payload)
        return Telemetry(values[0], values[1], values[2], bool(values[3]), *values[4:11], tuple(values[11:]),
                         version=2)
    raise ProtocolError(f"telemetry of {len(payload)} bytes, not {_TELEMETRY_V3.size} (v3) "
                        f"or {_TELEMETRY_V2.size} (v2)")


def sensor_samples(amplitude_um_pp, normal_force_n=None, lateral_force_n=None) -> np.ndarray:
    """Sensor samples as SENSORS carries them (absent channels NaN)."""
    amplitude = np.asarray(amplitude_um_pp, dtype=np.float32)
    samples = np.full(amplitude.shape, np.nan, dtype=_SENSOR_SAMPLE)
    samples["amplitude_um_pp"] = amplitude
    if normal_force_n is not None:
        samples["normal_force_n"] = normal_force_n
    if lateral_force_n is not None:
        samples["lateral_force_n"] = lateral_force_n
    return samples


def sensors_payload(first_sample: int, setpoint_index: int, samples: np.ndarray) -> bytes:
    samples = np.asarray(samples, dtype=_SENSOR_SAMPLE)
    if not 1 <= len(samples) <= MAX_SENSOR_SAMPLES:
        raise ValueError(f"a SENSORS frame carries 1 to {MAX_SENSOR_SAMPLES} samples, not {len(samples)}")
    return _SENSORS_HEADER.pack(first_sample & 0xFFFFFFFF, setpoint_index & 0xFFFFFFFF, len(samples)) + \
        samples.tobytes()


def parse_sensors(payload: bytes) -> Sensors:
    if len(payload) < _SENSORS_HEADER.size:
        raise ProtocolError("SENSORS frame too short")
    first, index, count = _SENSORS_HEADER.unpack_from(payload)
    data = payload[_SENSORS_HEADER.size:]
    if len(data) != count * _SENSOR_SAMPLE.itemsize or not 1 <= count <= MAX_SENSOR_SAMPLES:
        raise ProtocolError(f"SENSORS frame says {count} samples but carries {len(data)} bytes of them")
    return Sensors(first, index, np.frombuffer(data, dtype=_SENSOR_SAMPLE).copy())


@dataclass(frozen=True)
class ClockReply:
    """One CLOCK_REPLY: the device's sensor clock when it took the CLOCK request whose seq was ``asked_seq``, as
    ``sample`` (numbered as SENSORS' ``first_sample``, wrapping at 2**32) and ``fraction`` / 65536 of a sample;
    never ahead of its clock then, at most ``MAX_CLOCK_LAG_MS`` behind."""

    asked_seq: int
    sample: int
    fraction: int = 0

    @property
    def samples(self) -> float:
        """The clock in sensor samples, the fraction included (not unwrapped)."""
        return self.sample + self.fraction / 65536.0


def clock_reply_payload(reply: ClockReply) -> bytes:
    return _CLOCK_REPLY.pack(reply.asked_seq & 0xFFFF, reply.sample & 0xFFFFFFFF, reply.fraction & 0xFFFF)


def parse_clock_reply(payload: bytes) -> ClockReply:
    if len(payload) != _CLOCK_REPLY.size:
        raise ProtocolError(f"CLOCK_REPLY of {len(payload)} bytes, not {_CLOCK_REPLY.size}")
    return ClockReply(*_CLOCK_REPLY.unpack(payload))


# fixed parts of payloads (v3), by the names docs/protocol.md's tables use
PAYLOAD_SIZES = {"HELLO_REPLY": _HELLO_REPLY_V3.size, "HELLO_REPLY with link": _HELLO_REPLY_LINK.size,
                 "HELLO_REPLY restart fields": _RESET_FIELDS.size,
                 "ACK": _ACK.size, "NAK": _NAK.size,
                 "TELEMETRY": _TELEMETRY_V3.size, "SENSORS": _SENSORS_HEADER.size, "CLOCK_REPLY": _CLOCK_REPLY.size,
                 "SETPOINTS header": SETPOINT_HEADER_LAYOUT.size, "SENSORS sample": _SENSOR_SAMPLE.itemsize,
                 "SETPOINTS_FORCE header": SETPOINT_HEADER_LAYOUT.size + FORCE_REFERENCE_LAYOUT.size}
V2_PAYLOAD_SIZES = {"HELLO_REPLY": _HELLO_REPLY_V2.size, "TELEMETRY": _TELEMETRY_V2.size}
