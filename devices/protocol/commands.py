"""Protocol v3's commands, host → device: their payloads both ways, and SETPOINTS frames built without
allocating (:class:`SetpointFramer`, the serial writer's path). Re-exported by :mod:`ultraglide.devices.protocol`.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass

import numpy as np
from cobs import cobs
from ultraglide.devices.protocol.frames import CRC_LAYOUT, HEADER_LAYOUT, ProtocolError
from ultraglide.devices.protocol.spec import (
    CLEAR_FAULTS,
    CLOCK,
    ENABLE,
    HEARTBEAT,
    HELLO,
    MAX_BODY,
    MAX_SETPOINTS_PER_FRAME,
    PROTOCOL_VERSION,
    SET_CARRIER,
    SET_LOOP,
    SETPOINT_SCALE,
    SETPOINTS,
    SETPOINTS_FORCE,
    SIM_FAULT,
)

SETPOINT_HEADER_LAYOUT = struct.Struct("<IIH")  # first_index, rate_hz, count
FORCE_REFERENCE_LAYOUT = struct.Struct("<ffH")  # SETPOINTS_FORCE, after the count: force_n, exponent, limit_code
_CARRIER = struct.Struct("<f")
_CLEAR = struct.Struct("<H")
_SIM_FAULT = struct.Struct("<BH")

# exact payload lengths, where a command has one
PAYLOAD_LENGTHS = {HELLO: 1, SET_CARRIER: _CARRIER.size, ENABLE: 1, HEARTBEAT: 0, CLEAR_FAULTS: _CLEAR.size,
                   SET_LOOP: 1, CLOCK: 0, SIM_FAULT: _SIM_FAULT.size}


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
    return SETPOINT_HEADER_LAYOUT.pack(first_index & 0xFFFFFFFF, rate_hz, len(values)) + values.tobytes()


class SetpointFramer:
    """SETPOINTS frames of one stream, built in buffers made once: the serial writer's path makes no array.

    ``frame(seq, first_index, fractions)`` gives the same bytes as
    ``encode_frame(SETPOINTS, seq, setpoints_payload(first_index, rate_hz, fractions))`` for at most
    :data:`MAX_SETPOINTS_PER_FRAME` values; with ``force`` (a :class:`ForceReference`) a SETPOINTS_FORCE frame,
    the bytes of ``setpoints_force_payload``. What it allocates is bytes of the frame's own size (the body
    handed to COBS, COBS's output, the terminator added), no array, whatever the number of values."""

    _CODES_AT = HEADER_LAYOUT.size + SETPOINT_HEADER_LAYOUT.size

    def __init__(self, rate_hz: int):
        self.rate_hz = rate_hz
        self._body = bytearray(MAX_BODY)
        self._body_view = memoryview(self._body)
        self._scaled = np.empty(MAX_SETPOINTS_PER_FRAME)
        self._codes = np.empty(MAX_SETPOINTS_PER_FRAME, dtype="<u2")
        self._code_bytes = memoryview(self._codes).cast("B")

    def frame(self, seq: int, first_index: int, fractions: np.ndarray, force: ForceReference | None = None) -> bytes:
        count = len(fractions)
        if count > MAX_SETPOINTS_PER_FRAME:
            raise ValueError(f"{count} setpoints do not fit one frame (at most {MAX_SETPOINTS_PER_FRAME})")
        scaled = self._scaled[:count]
        # as setpoint_codes: clipped (np.clip's codes by its two ufuncs, without its wrapper), scaled, rounded
        # (ties to even)
        np.minimum(np.maximum(fractions, 0.0, out=scaled), 1.0, out=scaled)
        np.multiply(scaled, SETPOINT_SCALE, out=scaled)
        np.rint(scaled, out=scaled)
        np.copyto(self._codes[:count], scaled, casting="unsafe")
        body = self._body
        HEADER_LAYOUT.pack_into(body, 0, SETPOINTS if force is None else SETPOINTS_FORCE, seq & 0xFFFF)
        SETPOINT_HEADER_LAYOUT.pack_into(body, HEADER_LAYOUT.size, first_index & 0xFFFFFFFF, self.rate_hz, count)
        at = self._CODES_AT
        if force is not None:
            FORCE_REFERENCE_LAYOUT.pack_into(body, at, *force.fields())
            at += FORCE_REFERENCE_LAYOUT.size
        end = at + 2 * count
        body[at:end] = self._code_bytes[:2 * count]
        CRC_LAYOUT.pack_into(body, end, binascii.crc32(self._body_view[:end]))
        return cobs.encode(bytes(self._body_view[:end + CRC_LAYOUT.size])) + b"\x00"  # its C code takes no memoryview


@dataclass(frozen=True)
class ForceReference:
    """What SETPOINTS_FORCE adds to a frame's values: the normal force (N) the host computed them at, the model's
    local force exponent there (d ln a / d ln F; 0: no correction), and the host's limit as a fraction of the
    device's full scale (the device caps a corrected value at it and at its own)."""

    force_n: float
    exponent: float
    limit_fraction: float

    def fields(self) -> tuple[float, float, int]:
        limit = int(round(min(max(self.limit_fraction, 0.0), 1.0) * SETPOINT_SCALE))
        return float(self.force_n), float(self.exponent), limit

    def __repr__(self) -> str:
        return (f"ForceReference({self.force_n:.3f} N, exponent {self.exponent:.3f}, "
                f"limit {100 * self.limit_fraction:.1f} % of full scale)")


def setpoints_force_payload(first_index: int, rate_hz: int, fractions: np.ndarray, force: ForceReference) -> bytes:
    """SETPOINTS_FORCE: SETPOINTS' fields, the force reference after the count, then the codes."""
    values = setpoint_codes(fractions)
    return (SETPOINT_HEADER_LAYOUT.pack(first_index & 0xFFFFFFFF, rate_hz, len(values))
            + FORCE_REFERENCE_LAYOUT.pack(*force.fields()) + values.tobytes())


def parse_setpoints_force(payload: bytes) -> tuple[int, int, ForceReference, np.ndarray]:
    """``(first_index, rate_hz, reference, fractions of full scale)``; ProtocolError if the lengths disagree."""
    header = SETPOINT_HEADER_LAYOUT.size + FORCE_REFERENCE_LAYOUT.size
    if len(payload) < header:
        raise ProtocolError("SETPOINTS_FORCE frame too short")
    first, rate, count = SETPOINT_HEADER_LAYOUT.unpack_from(payload)
    force_n, exponent, limit = FORCE_REFERENCE_LAYOUT.unpack_from(payload, SETPOINT_HEADER_LAYOUT.size)
    data = payload[header:]
    if len(data) != 2 * count:
        raise ProtocolError(f"SETPOINTS_FORCE frame says {count} values but carries {len(data) / 2:g}")
    codes = np.frombuffer(data, dtype="<u2")
    return first, rate, ForceReference(force_n, exponent, limit / SETPOINT_SCALE), codes.astype(float) / SETPOINT_SCALE


def parse_setpoint_codes(payload: bytes) -> tuple[int, int, np.ndarray]:
    """``(first_index, rate_hz, codes u16)``; ProtocolError if the lengths disagree."""
    if len(payload) < SETPOINT_HEADER_LAYOUT.size:
        raise ProtocolError("setpoint frame too short")
    first, rate, count = SETPOINT_HEADER_LAYOUT.unpack_from(payload)
    data = payload[SETPOINT_HEADER_LAYOUT.size:]
    if len(data) != 2 * count:
        raise ProtocolError(f"setpoint frame says {count} values but carries {len(data) / 2:g}")
    return first, rate, np.frombuffer(data, dtype="<u2")


def parse_setpoints(payload: bytes) -> tuple[int, int, np.ndarray]:
    """``(first_index, rate_hz, fractions of full scale)``."""
    first, rate, codes = parse_setpoint_codes(payload)
    return first, rate, codes.astype(float) / SETPOINT_SCALE

def clear_faults_payload(mask: int) -> bytes:
    return _CLEAR.pack(mask & 0xFFFF)


def parse_clear_faults(payload: bytes) -> int:
    if len(payload) != _CLEAR.size:
        raise ProtocolError("CLEAR_FAULTS payload is not 2 bytes")
    return _CLEAR.unpack(payload)[0]


def set_loop_payload(mode: int) -> bytes:
    return bytes([mode])


def sim_fault_payload(kind: int, duration_ms: int = 0) -> bytes:
    return _SIM_FAULT.pack(kind, duration_ms)


def parse_sim_fault(payload: bytes) -> tuple[int, int]:
    if len(payload) != _SIM_FAULT.size:
        raise ProtocolError("SIM_FAULT payload is not 3 bytes")
    return _SIM_FAULT.unpack(payload)


