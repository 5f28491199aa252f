"""Protocol v3's framing: ``COBS(type u8 | seq u16 | payload | crc32 u32) 0x00``, one frame at a time or
from a byte stream in any chunks (:class:`FrameDecoder`). Re-exported by :mod:`ultraglide.devices.protocol`.
"""

from __future__ import annotations

import binascii
import math
import struct
from dataclasses import dataclass

from cobs import cobs
from ultraglide.devices.protocol.spec import MAX_BODY, MAX_ENCODED

from ultraglide.errors import UltraglideError

HEADER_LAYOUT = struct.Struct("<BH")  # type, seq
CRC_LAYOUT = struct.Struct("<I")  # CRC-32 of type, seq and payload


class ProtocolError(UltraglideError, ValueError):
    """A frame from a plate driver that cannot be decoded or parsed: bad COBS, a CRC that does not match, a payload
    of the wrong length for its type. A :class:`ValueError` too, so code that catches bad values catches it.

    The serial driver counts such frames (a link's noise) and goes on; code that parses frames itself, as a
    plate driver's test bench does, catches it.

    Examples
    --------
    >>> from ultraglide.devices.protocol import ProtocolError, decode_frame, encode_frame
    >>> damaged = bytearray(encode_frame(0x90, 7, b"payload")[:-1])  # without its 0x00 terminator
    >>> damaged[5] ^= 0x01  # one bit of the payload flipped on the way
    >>> try:
    ...     decode_frame(damaged)
    ... except ProtocolError as error:
    ...     print(error)
    CRC mismatch
    """


@dataclass(frozen=True)
class Frame:
    kind: int
    seq: int
    payload: bytes


def encode_frame(kind: int, seq: int, payload: bytes = b"") -> bytes:
    body = HEADER_LAYOUT.pack(kind, seq & 0xFFFF) + payload
    body += CRC_LAYOUT.pack(binascii.crc32(body))
    if len(body) > MAX_BODY:
        raise ValueError(f"frame body of {len(body)} bytes exceeds {MAX_BODY}")
    return cobs.encode(body) + b"\x00"


class EmptyFramer:
    """Frames of one command without a payload (CLOCK), built in a buffer made once: only the seq and the CRC
    change, so the serial writer's path makes no payload, header or body of its own for it.

    ``frame(seq)`` gives the bytes of ``encode_frame(kind, seq)``. What it allocates is bytes of the frame's own
    size (COBS's output and the terminator added), as
    :class:`~ultraglide.devices.protocol.commands.SetpointFramer` does for SETPOINTS.

    Examples
    --------
    >>> framer = EmptyFramer(0x09)
    >>> framer.frame(513) == encode_frame(0x09, 513)
    True
    """

    def __init__(self, kind: int):
        self.kind = kind
        self._body = bytearray(HEADER_LAYOUT.size + CRC_LAYOUT.size)
        self._header = memoryview(self._body)[:HEADER_LAYOUT.size]

    def frame(self, seq: int) -> bytes:
        body = self._body
        HEADER_LAYOUT.pack_into(body, 0, self.kind, seq & 0xFFFF)
        CRC_LAYOUT.pack_into(body, HEADER_LAYOUT.size, binascii.crc32(self._header))
        return cobs.encode(body) + b"\x00"  # (its C code takes the bytearray itself, not a memoryview)


def decode_frame(packet: bytes) -> Frame:
    """Decode one frame's bytes (without its 0x00 terminator)."""
    if not packet:
        raise ProtocolError("empty frame")
    try:
        body = cobs.decode(bytes(packet))
    except cobs.DecodeError as error:
        raise ProtocolError(f"bad COBS encoding: {error}") from None
    if len(body) < HEADER_LAYOUT.size + CRC_LAYOUT.size:
        raise ProtocolError(f"frame of {len(body)} bytes is too short")
    if len(body) > MAX_BODY:
        raise ProtocolError(f"frame of {len(body)} bytes is too long")
    (crc,) = CRC_LAYOUT.unpack_from(body, len(body) - CRC_LAYOUT.size)
    if binascii.crc32(body[:-CRC_LAYOUT.size]) != crc:
        raise ProtocolError("CRC mismatch")
    kind, seq = HEADER_LAYOUT.unpack_from(body)
    return Frame(kind, seq, body[HEADER_LAYOUT.size:-CRC_LAYOUT.size])


def frame_bytes_on_wire(payload_bytes: int) -> int:
    """Bytes one frame takes on the wire: COBS adds one byte per started 254 of body, plus the 0x00."""
    body = HEADER_LAYOUT.size + payload_bytes + CRC_LAYOUT.size
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


