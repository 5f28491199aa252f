"""The plate-driver wire protocol, version 1: framing, messages, encoding and decoding.

A frame is ``COBS(type u8 | seq u16 | payload | crc32 u32) 0x00``: COBS removes every zero
byte from the body, so 0x00 only ever ends a frame and a receiver resynchronises at the next one
after any garbage. The CRC-32 (IEEE 802.3, zlib's) covers type, seq and payload; all integers
and floats are little-endian. ``docs/protocol.md`` is the specification firmware authors follow.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass

import numpy as np
from cobs import cobs

PROTOCOL_VERSION = 1
MAX_BODY = 1024  # bytes of a decoded frame, header and CRC included
SETPOINT_SCALE = 65535  # a setpoint of 65535 is the plate's full-scale drive

# host → device
HELLO = 0x01
SET_CARRIER = 0x02
ENABLE = 0x03
SETPOINTS = 0x04
HEARTBEAT = 0x05
SIM_FAULT = 0x7E  # simulator only: inject a fault for tests
# device → host
HELLO_REPLY = 0x81
ACK = 0x82
TELEMETRY = 0x90

ACK_OK, ACK_BAD_VALUE, ACK_UNSUPPORTED = 0, 1, 2

FAULT_WATCHDOG = 1 << 0  # nothing heard for 100 ms: output ramped to zero
FAULT_OVER_AMPLITUDE = 1 << 1  # measured amplitude above the plate's safe maximum
FAULT_OVERRUN = 1 << 2  # setpoints arrived faster than they play: some were dropped
FAULT_UNDERRUN = 1 << 3  # the setpoint buffer ran dry: last value held
FAULT_BAD_COMMAND = 1 << 4
FAULT_NAMES = {FAULT_WATCHDOG: "watchdog", FAULT_OVER_AMPLITUDE: "over-amplitude", FAULT_OVERRUN: "overrun",
               FAULT_UNDERRUN: "underrun", FAULT_BAD_COMMAND: "bad-command"}

SIM_DROP, SIM_CORRUPT, SIM_HANG, SIM_DISCONNECT = 1, 2, 3, 4

_HEADER = struct.Struct("<BH")
_CRC = struct.Struct("<I")
_SETPOINT_HEADER = struct.Struct("<IIH")
_HELLO_REPLY = struct.Struct("<BfffI")
_ACK = struct.Struct("<HB")
_TELEMETRY = struct.Struct("<ffHIIIIIB")


class ProtocolError(ValueError):
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


class FrameDecoder:
    """Bytes in, frames out, whatever the chunking; counts what it had to throw away.

    An over-long run without a terminator is discarded (at most ``MAX_BODY`` plus COBS overhead
    is ever buffered), and decoding resumes at the next 0x00.
    """

    MAX_ENCODED = MAX_BODY + MAX_BODY // 254 + 2

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
    version: int
    resonance_hz: float
    full_scale_um_pp: float
    max_amplitude_um_pp: float
    max_setpoint_rate_hz: int
    name: str


@dataclass(frozen=True)
class Telemetry:
    measured_um_pp: float
    resonance_hz: float
    faults: int
    frames_ok: int
    crc_errors: int
    framing_errors: int
    underruns: int
    setpoints: int
    enabled: bool

    def fault_names(self) -> list[str]:
        return [name for bit, name in FAULT_NAMES.items() if self.faults & bit]


def hello_payload(version: int = PROTOCOL_VERSION) -> bytes:
    return bytes([version])


def carrier_payload(carrier_hz: float) -> bytes:
    return struct.pack("<f", carrier_hz)


def enable_payload(enabled: bool) -> bytes:
    return bytes([1 if enabled else 0])


def setpoints_payload(first_index: int, rate_hz: int, fractions: np.ndarray) -> bytes:
    """Amplitude setpoints as fractions of full scale (clipped to 0..1), quantised to u16."""
    values = np.round(np.clip(fractions, 0.0, 1.0) * SETPOINT_SCALE).astype("<u2")
    return _SETPOINT_HEADER.pack(first_index & 0xFFFFFFFF, rate_hz, len(values)) + values.tobytes()


def parse_setpoints(payload: bytes) -> tuple[int, int, np.ndarray]:
    if len(payload) < _SETPOINT_HEADER.size:
        raise ProtocolError("setpoint frame too short")
    first, rate, count = _SETPOINT_HEADER.unpack_from(payload)
    data = payload[_SETPOINT_HEADER.size:]
    if len(data) != 2 * count:
        raise ProtocolError(f"setpoint frame says {count} values but carries {len(data) // 2}")
    return first, rate, np.frombuffer(data, dtype="<u2").astype(float) / SETPOINT_SCALE


def hello_reply_payload(reply: HelloReply) -> bytes:
    return _HELLO_REPLY.pack(reply.version, reply.resonance_hz, reply.full_scale_um_pp,
                             reply.max_amplitude_um_pp, reply.max_setpoint_rate_hz) + reply.name.encode()


def parse_hello_reply(payload: bytes) -> HelloReply:
    if len(payload) < _HELLO_REPLY.size:
        raise ProtocolError("hello reply too short")
    fields = _HELLO_REPLY.unpack_from(payload)
    return HelloReply(*fields, payload[_HELLO_REPLY.size:].decode("utf-8", "replace"))


def ack_payload(seq: int, status: int) -> bytes:
    return _ACK.pack(seq & 0xFFFF, status)


def parse_ack(payload: bytes) -> tuple[int, int]:
    if len(payload) != _ACK.size:
        raise ProtocolError("bad ack")
    return _ACK.unpack(payload)


def telemetry_payload(t: Telemetry) -> bytes:
    return _TELEMETRY.pack(t.measured_um_pp, t.resonance_hz, t.faults, t.frames_ok, t.crc_errors,
                           t.framing_errors, t.underruns, t.setpoints & 0xFFFFFFFF, 1 if t.enabled else 0)


def parse_telemetry(payload: bytes) -> Telemetry:
    if len(payload) != _TELEMETRY.size:
        raise ProtocolError("bad telemetry length")
    values = _TELEMETRY.unpack(payload)
    return Telemetry(*values[:-1], bool(values[-1]))


def sim_fault_payload(kind: int, duration_ms: int = 0) -> bytes:
    return struct.pack("<BH", kind, duration_ms)
