"""The plate-driver wire protocol, version 3 (and the layouts of version 2): framing, messages, codecs.

A frame is ``COBS(type u8 | seq u16 | payload | crc32 u32) 0x00``: COBS removes every zero
byte from the body, so 0x00 only ever ends a frame and a receiver resynchronises at the next one
after any garbage. The CRC-32 (IEEE 802.3, zlib's) covers type, seq and payload; all integers
and floats are little-endian. ``docs/protocol.md`` is the normative specification firmware authors
follow; the constants below are the ones it names (a test checks the two against each other).
Version 3 keeps version 2's framing and commands; HELLO_REPLY and TELEMETRY grew fields at their ends,
and SET_LOOP and SENSORS are new. The codecs read and write both versions' layouts: a HELLO_REPLY by its
version byte, a TELEMETRY by its length.

A 12 kHz stream is sent as one SETPOINTS frame of 12 values every 1 ms on a link with room for it
(921 600 baud), else of 24 values every 2 ms:

>>> batch_s_for(921600, 12000), batch_s_for(460800, 12000)
(0.001, 0.002)
>>> len(encode_frame(SETPOINTS, 1, setpoints_payload(0, 12000, np.zeros(12))))
43
>>> setpoint_codes(np.array([0.0, 0.5, 1.0, 1.2]))
array([    0, 32768, 65535, 65535], dtype=uint16)
"""

from __future__ import annotations

import binascii
import math
import struct
from dataclasses import dataclass

import numpy as np
from cobs import cobs

from ultraglide.errors import UltraglideError

PROTOCOL_VERSION = 3  # the version docs/protocol.md describes, and the highest ultraglide speaks
SUPPORTED_VERSIONS = (2, 3)
MAX_BODY = 1024  # bytes of a decoded frame (type, seq, payload, CRC)
MAX_ENCODED = 1030  # MAX_BODY + ceil(MAX_BODY / 254) + 1: a longer run without a 0x00 is dropped
SETPOINT_SCALE = 65535  # a setpoint of 65535 is the plate's full-scale drive (or, with the loop on, amplitude)
MAX_SETPOINTS_PER_FRAME = 240
FAST_BATCH_S = 0.001  # the host sends one SETPOINTS frame every 1 ms where the link has room (batch_s_for)
BATCH_S = 0.002  # and every 2 ms where it has not: fewer frames, less framing overhead
FRAME_OVERHEAD_BYTES = 19  # a SETPOINTS frame of n <= 118 values is 19 + 2n bytes on the wire
TELEMETRY_HZ = 50
TELEMETRY_TOLERANCE = 0.1  # the telemetry rate a device keeps, within ±10 % of TELEMETRY_HZ over a second
WATCHDOG_MS = 100  # no valid frame for this long while enabled: the device ramps to zero
WATCHDOG_LATE_MS = 10  # ... and fires at most this much after watchdog_ms
WATCHDOG_RAMP_MS = 20
BUFFER_MS = 250  # setpoints beyond this much playing time are dropped (overrun)
PREFILL_MS = 10  # the device plays once ceil(PREFILL_MS * rate / 1000) values are buffered (jitter buffer)
ACK_DEADLINE_MS = 50  # the device answers a command within this long
HOST_ACK_TIMEOUT_S = 2.0  # the host gives up on an answer after this long
HOST_SILENCE_MS = 500  # no telemetry for this long: the host treats the device as gone
MAX_SIM_FAULT_MS = 5000
TRIP_MARGIN = 0.01  # the device trips above max_amplitude_um_pp × (1 + margin)
OVER_LIMIT_REARM = 0.98  # over-limit is raised again only after the amplitude fell below this × the limit
SENSORS_PERIOD_MS = 10  # a SENSORS frame at least this often while the output is enabled
SENSORS_REST_PERIOD_MS = 50  # ... and at least this often while it is disabled
MIN_SENSOR_RATE_HZ = 1000  # sensor samples a second, at least, on a device that has a sensor
MAX_SENSOR_SAMPLES = 80  # samples in one SENSORS frame, at most
MAX_NAME_BYTES = 64  # the device's name in HELLO_REPLY, UTF-8, at most
NOT_PLAYING = 0xFFFFFFFF  # SENSORS.setpoint_index while no stream value plays


def batch_s_for(baud: int, rate_hz: int) -> float:
    """The host's frame period (s): 1 ms where a stream of ``rate_hz`` setpoints/s in 1 ms frames takes at most
    half of a ``baud`` link (8N1, ten bits a byte), so a touch waits less for the next frame; else 2 ms."""
    fast_bytes_per_s = FRAME_OVERHEAD_BYTES / FAST_BATCH_S + 2 * rate_hz
    return FAST_BATCH_S if fast_bytes_per_s <= 0.5 * baud / 10 else BATCH_S


# host → device
HELLO = 0x01
SET_CARRIER = 0x02
ENABLE = 0x03
SETPOINTS = 0x04
HEARTBEAT = 0x05
CLEAR_FAULTS = 0x06
SET_LOOP = 0x07  # v3: open loop (0) or the firmware's amplitude loop (1)
SIM_FAULT = 0x7E  # simulator only: inject a fault for tests
HOST_COMMANDS = (HELLO, SET_CARRIER, ENABLE, SETPOINTS, HEARTBEAT, CLEAR_FAULTS, SET_LOOP, SIM_FAULT)
V3_COMMANDS = (SET_LOOP,)  # refused with NAK 4 in a session negotiated as v2
# device → host
HELLO_REPLY = 0x81
ACK = 0x82
NAK = 0x83
TELEMETRY = 0x90
SENSORS = 0x91  # v3: sensor samples, sent while the device has any sensor

# HELLO_REPLY v3: the sensors a device has (bits of ``sensors``) and what its firmware does (``features``)
SENSOR_AMPLITUDE = 1 << 0  # the vibration amplitude, from a sensing piezo
SENSOR_NORMAL_FORCE = 1 << 1
SENSOR_LATERAL_FORCE = 1 << 2
SENSOR_NAMES = {SENSOR_AMPLITUDE: "vibration amplitude", SENSOR_NORMAL_FORCE: "normal force",
                SENSOR_LATERAL_FORCE: "lateral force"}
FEATURE_AMPLITUDE_LOOP = 1 << 0  # the firmware's amplitude loop (SET_LOOP 1)
LOOP_OPEN, LOOP_AMPLITUDE = 0, 1

# TELEMETRY v3: what the output is doing
PLAYBACK_OFF, PLAYBACK_PREFILL, PLAYBACK_PLAYING, PLAYBACK_DRY, PLAYBACK_RAMP = 0, 1, 2, 3, 4
PLAYBACK_NAMES = {PLAYBACK_OFF: "off", PLAYBACK_PREFILL: "prefill", PLAYBACK_PLAYING: "playing",
                  PLAYBACK_DRY: "dry", PLAYBACK_RAMP: "watchdog ramp"}

# NAK reasons
NAK_UNKNOWN_TYPE = 1  # no such command
NAK_BAD_LENGTH = 2  # the payload's length is wrong for the command
NAK_BAD_VALUE = 3  # a field is out of range (carrier, enable flag, rate, count, loop mode, fault kind)
NAK_UNSUPPORTED = 4  # a known command this device or session does not do (SIM_FAULT on firmware, v3 in v2)
NAK_INTERNAL = 5  # the device could not carry the command out (a handler failed; enabling while hot)
NAK_REASONS = {NAK_UNKNOWN_TYPE: "unknown command", NAK_BAD_LENGTH: "wrong payload length",
               NAK_BAD_VALUE: "value out of range", NAK_UNSUPPORTED: "not supported by this device",
               NAK_INTERNAL: "internal error on the device"}

# Fault bits: each latches in TELEMETRY.faults until CLEAR_FAULTS clears it; each has a counter.
FAULT_WATCHDOG = 1 << 0  # no valid frame for WATCHDOG_MS while enabled: output ramped to zero
FAULT_TRIP = 1 << 1  # measured amplitude above the plate's safe maximum: output cut, disabled
FAULT_OVER_LIMIT = 1 << 2  # measured amplitude rose above the safe maximum (by less than the trip margin)
FAULT_OVERRUN = 1 << 3  # setpoints arrived faster than they play: some were dropped
FAULT_UNDERRUN = 1 << 4  # the setpoint buffer ran dry: last value held
FAULT_BAD_COMMAND = 1 << 5  # a frame was refused with a NAK
FAULT_OVERHEAT = 1 << 6  # the driver stage is too hot: output cut, disabled
FAULT_BITS = 8  # TELEMETRY carries one counter per bit; bit 7 is reserved
FAULT_NAMES = {FAULT_WATCHDOG: "watchdog", FAULT_TRIP: "trip", FAULT_OVER_LIMIT: "over-limit",
               FAULT_OVERRUN: "overrun", FAULT_UNDERRUN: "underrun", FAULT_BAD_COMMAND: "bad-command",
               FAULT_OVERHEAT: "overheat"}
FAULT_WORDS = {
    "watchdog": "watchdog trip (no valid frame for 100 ms; output ramped to zero)",
    "trip": "over-amplitude trip (measured amplitude above the plate's limit; output cut and disabled)",
    "over-limit": "excursion above the plate's amplitude limit (within the trip margin)",
    "overrun": "buffer overrun (setpoints dropped)",
    "underrun": "buffer underrun (last value held)",
    "bad-command": "frame refused by the device (NAK)",
    "overheat": "overheat (output cut and disabled)",
}

SIM_DROP, SIM_CORRUPT, SIM_HANG, SIM_DISCONNECT, SIM_OVERHEAT = 1, 2, 3, 4, 5
SIM_FAULT_KINDS = {SIM_DROP: "drop", SIM_CORRUPT: "corrupt", SIM_HANG: "hang", SIM_DISCONNECT: "disconnect",
                   SIM_OVERHEAT: "overheat"}

_HEADER = struct.Struct("<BH")
_CRC = struct.Struct("<I")
_SETPOINT_HEADER = struct.Struct("<IIH")
_HELLO_REPLY_V2 = struct.Struct("<BfffIIffHH")
# v2's fields, then max_drive_um_pp, sensors, sensor_rate_hz, features
_HELLO_REPLY_V3 = struct.Struct("<BfffIIffHHfBHB")
_ACK = struct.Struct("<H")
_NAK = struct.Struct("<HB")
_TELEMETRY_V2 = struct.Struct(f"<ffHB7I{FAULT_BITS}I")
# v2's fields, then overrun_setpoints, expected_index, stream_rate_hz, buffered_setpoints, drive_code, playback, loop
_TELEMETRY_V3 = struct.Struct(f"<ffHB7I{FAULT_BITS}IIIIHHBB")
_SENSORS_HEADER = struct.Struct("<IIB")
_SENSOR_SAMPLE = np.dtype([("amplitude_um_pp", "<f4"), ("normal_force_n", "<f4"), ("lateral_force_n", "<f4")])
_CARRIER = struct.Struct("<f")
_CLEAR = struct.Struct("<H")
_SIM_FAULT = struct.Struct("<BH")

# exact payload lengths, where a command has one
PAYLOAD_LENGTHS = {HELLO: 1, SET_CARRIER: _CARRIER.size, ENABLE: 1, HEARTBEAT: 0, CLEAR_FAULTS: _CLEAR.size,
                   SET_LOOP: 1, SIM_FAULT: _SIM_FAULT.size}


class ProtocolError(UltraglideError, ValueError):
    """A frame that cannot be decoded."""


@dataclass(frozen=True)
class Frame:
    kind: int
    seq: int
    payload: bytes


def encode_frame(kind: int, seq: int, payload: bytes = b"") -> bytes:
    body = _HEADER.pack(kind, seq & 0xFFFF) + payload
    body += _CRC.pack(binascii.crc32(body))
    if len(body) > MAX_BODY:
        raise ValueError(f"frame body of {len(body)} bytes exceeds {MAX_BODY}")
    return cobs.encode(body) + b"\x00"


def decode_frame(packet: bytes) -> Frame:
    """Decode one frame's bytes (without its 0x00 terminator)."""
    if not packet:
        raise ProtocolError("empty frame")
    try:
        body = cobs.decode(bytes(packet))
    except cobs.DecodeError as error:
        raise ProtocolError(f"bad COBS encoding: {error}") from None
    if len(body) < _HEADER.size + _CRC.size:
        raise ProtocolError(f"frame of {len(body)} bytes is too short")
    if len(body) > MAX_BODY:
        raise ProtocolError(f"frame of {len(body)} bytes is too long")
    (crc,) = _CRC.unpack_from(body, len(body) - _CRC.size)
    if binascii.crc32(body[:-_CRC.size]) != crc:
        raise ProtocolError("CRC mismatch")
    kind, seq = _HEADER.unpack_from(body)
    return Frame(kind, seq, body[_HEADER.size:-_CRC.size])


def frame_bytes_on_wire(payload_bytes: int) -> int:
    """Bytes one frame takes on the wire: COBS adds one byte per started 254 of body, plus the 0x00."""
    body = _HEADER.size + payload_bytes + _CRC.size
    return body + max(1, math.ceil(body / 254)) + 1


class FrameDecoder:
    """Bytes in, frames out, whatever the chunking; counts what it had to throw away.

    An over-long run without a terminator is discarded (at most ``MAX_BODY`` plus COBS overhead
    is ever buffered), and decoding resumes at the next 0x00.
    """

    MAX_ENCODED = MAX_ENCODED

    def __init__(self):
        self._buffer = bytearray()
        self._discarding = False
        self.frames = 0
        self.crc_errors = 0
        self.framing_errors = 0

    def feed(self, data: bytes) -> list[Frame]:
        frames = []
        self._buffer.extend(data)
        while True:
            end = self._buffer.find(0)
            if end < 0:
                if len(self._buffer) > self.MAX_ENCODED:
                    self._buffer.clear()
                    if not self._discarding:
                        self.framing_errors += 1
                    self._discarding = True
                break
            packet = bytes(self._buffer[:end])
            del self._buffer[:end + 1]
            if self._discarding:  # the tail of an over-long run: already counted
                self._discarding = False
                continue
            if not packet:
                continue  # consecutive terminators: idle line or resync padding
            try:
                frames.append(decode_frame(packet))
                self.frames += 1
            except ProtocolError as error:
                if "CRC" in str(error):
                    self.crc_errors += 1
                else:
                    self.framing_errors += 1
        return frames


# ---- messages ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class HelloReply:
    """What the device says about itself; amplitudes in µm peak-to-peak.

    The last four fields are v3's; a v2 reply reads as no overdrive (``max_drive_um_pp`` = the limit), no
    sensors and no features."""

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

    def __post_init__(self) -> None:
        if self.max_drive_um_pp is None:
            object.__setattr__(self, "max_drive_um_pp", self.max_amplitude_um_pp)

    @property
    def has_amplitude_loop(self) -> bool:
        return bool(self.features & FEATURE_AMPLITUDE_LOOP)


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


def hello_payload(version: int = PROTOCOL_VERSION) -> bytes:
    return bytes([version])


def carrier_payload(carrier_hz: float) -> bytes:
    return _CARRIER.pack(carrier_hz)


def parse_carrier(payload: bytes) -> float:
    if len(payload) != _CARRIER.size:
        raise ProtocolError("SET_CARRIER payload is not 4 bytes")
    return _CARRIER.unpack(payload)[0]


def enable_payload(enabled: bool) -> bytes:
    return bytes([1 if enabled else 0])


def setpoint_codes(fractions: np.ndarray) -> np.ndarray:
    """Fractions of full scale → u16 codes: clipped to [0, 1], times 65535, rounded to nearest (ties to even)."""
    return np.round(np.clip(np.asarray(fractions, dtype=float), 0.0, 1.0) * SETPOINT_SCALE).astype("<u2")


def setpoints_payload(first_index: int, rate_hz: int, fractions: np.ndarray) -> bytes:
    """Amplitude setpoints as fractions of full scale, quantised by :func:`setpoint_codes`."""
    values = setpoint_codes(fractions)
    return _SETPOINT_HEADER.pack(first_index & 0xFFFFFFFF, rate_hz, len(values)) + values.tobytes()


class SetpointFramer:
    """SETPOINTS frames of one stream, built in buffers made once: the serial writer's path makes no array.

    ``frame(seq, first_index, fractions)`` gives the same bytes as
    ``encode_frame(SETPOINTS, seq, setpoints_payload(first_index, rate_hz, fractions))`` for at most
    :data:`MAX_SETPOINTS_PER_FRAME` values. What it allocates is bytes of the frame's own size (the body
    handed to COBS, COBS's output, the terminator added), no array, whatever the number of values."""

    _CODES_AT = _HEADER.size + _SETPOINT_HEADER.size

    def __init__(self, rate_hz: int):
        self.rate_hz = rate_hz
        self._body = bytearray(MAX_BODY)
        self._body_view = memoryview(self._body)
        self._scaled = np.empty(MAX_SETPOINTS_PER_FRAME)
        self._codes = np.empty(MAX_SETPOINTS_PER_FRAME, dtype="<u2")
        self._code_bytes = memoryview(self._codes).cast("B")

    def frame(self, seq: int, first_index: int, fractions: np.ndarray) -> bytes:
        count = len(fractions)
        if count > MAX_SETPOINTS_PER_FRAME:
            raise ValueError(f"{count} setpoints do not fit one frame (at most {MAX_SETPOINTS_PER_FRAME})")
        scaled = self._scaled[:count]
        np.clip(fractions, 0.0, 1.0, out=scaled)  # as setpoint_codes: clipped, scaled, rounded (ties to even)
        np.multiply(scaled, SETPOINT_SCALE, out=scaled)
        np.rint(scaled, out=scaled)
        np.copyto(self._codes[:count], scaled, casting="unsafe")
        body = self._body
        _HEADER.pack_into(body, 0, SETPOINTS, seq & 0xFFFF)
        _SETPOINT_HEADER.pack_into(body, _HEADER.size, first_index & 0xFFFFFFFF, self.rate_hz, count)
        end = self._CODES_AT + 2 * count
        body[self._CODES_AT:end] = self._code_bytes[:2 * count]
        _CRC.pack_into(body, end, binascii.crc32(self._body_view[:end]))
        return cobs.encode(bytes(self._body_view[:end + _CRC.size])) + b"\x00"  # its C code takes no memoryview


def parse_setpoint_codes(payload: bytes) -> tuple[int, int, np.ndarray]:
    """``(first_index, rate_hz, codes u16)``; ProtocolError if the lengths disagree."""
    if len(payload) < _SETPOINT_HEADER.size:
        raise ProtocolError("setpoint frame too short")
    first, rate, count = _SETPOINT_HEADER.unpack_from(payload)
    data = payload[_SETPOINT_HEADER.size:]
    if len(data) != 2 * count:
        raise ProtocolError(f"setpoint frame says {count} values but carries {len(data) / 2:g}")
    return first, rate, np.frombuffer(data, dtype="<u2")


def parse_setpoints(payload: bytes) -> tuple[int, int, np.ndarray]:
    """``(first_index, rate_hz, fractions of full scale)``."""
    first, rate, codes = parse_setpoint_codes(payload)
    return first, rate, codes.astype(float) / SETPOINT_SCALE


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
    return head + reply.name.encode()[:MAX_NAME_BYTES].decode("utf-8", "ignore").encode()  # whole characters


def hello_reply_version(payload: bytes) -> int:
    """The version a HELLO_REPLY speaks: its first byte, the same in every version."""
    if not payload:
        raise ProtocolError("empty hello reply")
    return payload[0]


def parse_hello_reply(payload: bytes) -> HelloReply:
    """A v2 or v3 reply, by its version byte (v3's layout for any version above 3: fields are only ever added
    at the end). The name: at most 64 bytes taken, invalid UTF-8 replaced."""
    layout = _HELLO_REPLY_V2 if hello_reply_version(payload) <= 2 else _HELLO_REPLY_V3
    if len(payload) < layout.size:
        raise ProtocolError(f"hello reply of {len(payload)} bytes is shorter than "
                            f"v{min(payload[0], 3)}'s {layout.size}")
    fields = layout.unpack_from(payload)
    name = payload[layout.size:layout.size + MAX_NAME_BYTES].decode("utf-8", "replace")
    if layout is _HELLO_REPLY_V2:
        return HelloReply(*fields, name)
    return HelloReply(*fields[:10], name, *fields[10:])


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


def clear_faults_payload(mask: int) -> bytes:
    return _CLEAR.pack(mask & 0xFFFF)


def parse_clear_faults(payload: bytes) -> int:
    if len(payload) != _CLEAR.size:
        raise ProtocolError("CLEAR_FAULTS payload is not 2 bytes")
    return _CLEAR.unpack(payload)[0]


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


def set_loop_payload(mode: int) -> bytes:
    return bytes([mode])


def sim_fault_payload(kind: int, duration_ms: int = 0) -> bytes:
    return _SIM_FAULT.pack(kind, duration_ms)


def parse_sim_fault(payload: bytes) -> tuple[int, int]:
    if len(payload) != _SIM_FAULT.size:
        raise ProtocolError("SIM_FAULT payload is not 3 bytes")
    return _SIM_FAULT.unpack(payload)


# fixed parts of payloads (v3), by the names docs/protocol.md's tables use
PAYLOAD_SIZES = {"HELLO_REPLY": _HELLO_REPLY_V3.size, "ACK": _ACK.size, "NAK": _NAK.size,
                 "TELEMETRY": _TELEMETRY_V3.size, "SENSORS": _SENSORS_HEADER.size,
                 "SETPOINTS header": _SETPOINT_HEADER.size, "SENSORS sample": _SENSOR_SAMPLE.itemsize}
V2_PAYLOAD_SIZES = {"HELLO_REPLY": _HELLO_REPLY_V2.size, "TELEMETRY": _TELEMETRY_V2.size}
