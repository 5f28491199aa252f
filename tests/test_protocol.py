"""The wire protocol: round trips, and any bytes at all into the decoder (hypothesis)."""

import binascii

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ultraglide.devices import protocol as p


@given(kind=st.integers(0, 255), seq=st.integers(0, 0xFFFF), payload=st.binary(max_size=900))
def test_frames_round_trip(kind, seq, payload):
    wire = p.encode_frame(kind, seq, payload)
    assert wire.endswith(b"\x00") and b"\x00" not in wire[:-1]  # zero only ends a frame
    frame = p.decode_frame(wire[:-1])
    assert (frame.kind, frame.seq, frame.payload) == (kind, seq, payload)


def test_crc_is_ieee_crc32_over_header_and_payload():
    from cobs import cobs
    body = cobs.decode(p.encode_frame(p.HEARTBEAT, 7, b"abc")[:-1])
    # header: type 0x05, seq 7 little-endian; CRC-32 of "\x05\x07\x00abc", independently computed
    assert body[:3] == b"\x05\x07\x00"
    assert int.from_bytes(body[-4:], "little") == binascii.crc32(b"\x05\x07\x00abc")


@settings(max_examples=300)
@given(garbage=st.binary(max_size=3000), chunks=st.lists(st.integers(1, 50), max_size=40))
def test_any_bytes_never_crash_and_the_next_frame_gets_through(garbage, chunks):
    decoder = p.FrameDecoder()
    good = p.encode_frame(p.SETPOINTS, 42, p.setpoints_payload(10, 12000, np.linspace(0, 1, 20)))
    stream = garbage + b"\x00" + good  # a terminator ends whatever the garbage was
    frames, position = [], 0
    for size in chunks + [len(stream)]:
        frames += decoder.feed(stream[position:position + size])
        position += size
    assert frames and frames[-1].seq == 42 and frames[-1].kind == p.SETPOINTS
    first, rate, values = p.parse_setpoints(frames[-1].payload)
    assert (first, rate) == (10, 12000) and values == pytest.approx(np.linspace(0, 1, 20), abs=1 / 65535)


def test_decoder_counts_and_bounds_garbage():
    decoder = p.FrameDecoder()
    wire = p.encode_frame(p.HEARTBEAT, 1)
    corrupted = bytearray(wire)
    corrupted[2] ^= 0x10
    assert decoder.feed(bytes(corrupted)) == []
    assert decoder.crc_errors + decoder.framing_errors == 1
    decoder.feed(b"\x07" * 5000)  # a long run with no terminator is dropped, not buffered
    assert len(decoder._buffer) <= decoder.MAX_ENCODED
    assert decoder.framing_errors >= 1
    assert len(decoder.feed(b"\x00" + wire)) == 1


def test_messages_round_trip():
    reply = p.HelloReply(2, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "plate")
    assert p.parse_hello_reply(p.hello_reply_payload(reply)) == reply
    telemetry = p.Telemetry(2.5, 25000.0, p.FAULT_WATCHDOG, True, 10, 1, 2, 4000, 3, 4, 5, (1, 0, 0, 0, 7, 0, 0, 0))
    assert p.parse_telemetry(p.telemetry_payload(telemetry)) == telemetry
    assert telemetry.fault_names() == ["watchdog"]
    assert telemetry.counts_by_name()["watchdog"] == 1 and telemetry.counts_by_name()["underrun"] == 7
    assert p.parse_ack(p.ack_payload(9)) == 9
    assert p.parse_nak(p.nak_payload(9, p.NAK_BAD_VALUE)) == (9, p.NAK_BAD_VALUE)
    with pytest.raises(p.ProtocolError):
        p.parse_setpoints(p.setpoints_payload(0, 12000, np.ones(4))[:-1])
