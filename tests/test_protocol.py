"""The wire protocol: round trips, and any bytes at all into the decoder (hypothesis)."""

import binascii

import numpy as np
import pytest
from conftest import ROOT
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


# ---- docs/protocol.md is normative: its tables must say what the code does --------------------------

DOC = (ROOT / "docs" / "protocol.md").read_text()
SIZES = {"u8": 1, "u16": 2, "u32": 4, "f32": 4}


def _rows(header: str) -> list[list[str]]:
    """The rows of the first table whose header row starts with ``header``."""
    lines = [line.strip() for line in DOC.splitlines()]
    start = next(i for i, line in enumerate(lines) if line.startswith(header))
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split("|")])
    return rows


def _fixed_size(fields: str) -> int:
    """Bytes of the fixed part of a payload written as ``name:u32, n × name:u16, name:utf-8 (rest)``."""
    if fields.startswith("("):
        return 0
    size = 0
    for field in fields.strip("`").split(", "):
        kind = field.split(":")[-1].strip().split(" ")[-1].strip("`")
        if "utf-8" in field or field.startswith("count ×"):
            continue  # variable parts
        repeat = int(field.split(":")[1].split("×")[0]) if "×" in field else 1
        size += repeat * SIZES[kind]
    return size


def test_the_documents_constants_are_the_codes():
    rows = _rows("| constant |")
    assert len(rows) >= 10
    for name, value, _ in rows:
        assert getattr(p, name.strip("`")) == pytest.approx(float(value)), name


def test_the_documents_message_tables_are_the_codes():
    host = _rows("| type | name | payload | answer |")
    device = _rows("| type | name | payload |")
    assert {name for _, name, *_ in host} == {"HELLO", "SET_CARRIER", "ENABLE", "SETPOINTS", "HEARTBEAT",
                                              "CLEAR_FAULTS", "SIM_FAULT"}
    for kind, name, payload, *_ in host + device:
        assert getattr(p, name) == int(kind, 16), name
        fixed = _fixed_size(payload.split("`")[1] if "`" in payload else payload)
        expected = p.PAYLOAD_SIZES["SETPOINTS header"] if name == "SETPOINTS" else \
            p.PAYLOAD_LENGTHS.get(getattr(p, name), p.PAYLOAD_SIZES.get(name))
        assert fixed == expected, (name, fixed, expected)


def test_the_documents_fault_bits_and_nak_reasons_are_the_codes():
    faults = _rows("| bit | fault |")
    assert {int(bit, 16): name for bit, name, *_ in faults} == p.FAULT_NAMES
    reasons = _rows("| reason | meaning |")
    assert {int(reason): meaning for reason, meaning in reasons} == p.NAK_REASONS


def test_the_documents_byte_budget_is_the_framing():
    per_frame = len(p.encode_frame(p.SETPOINTS, 0xFFFF, p.setpoints_payload(0, 12000, np.full(24, 0.5))))
    frames_per_s = round(1 / p.BATCH_S)
    assert per_frame == 67 and per_frame * frames_per_s == 33500
    assert "= 33 500 bytes/s" in DOC and "67 bytes × 500 frames" in DOC
    telemetry = len(p.encode_frame(p.TELEMETRY, 1, p.telemetry_payload(
        p.Telemetry(1.0, 25000.0, 0, True, *([1] * 7), (0,) * p.FAULT_BITS))))
    assert telemetry == 80 and telemetry * p.TELEMETRY_HZ == 4000 and "4 000 bytes/s" in DOC
    for n in (1, 24, 96, 118):  # the general formula on the page, against real frames
        assert len(p.encode_frame(p.SETPOINTS, 1, p.setpoints_payload(0, 12000, np.full(n, 0.3)))) == 19 + 2 * n
    for link, bytes_per_s, _, fastest in _rows("| link | bytes/s |")[:4]:
        baud = int(link.split()[1])
        assert int(bytes_per_s.replace(" ", "")) == baud // 10  # 8N1: ten bits a byte
        assert int(fastest.removesuffix(" setpoints/s").replace(" ", "")) == round((baud // 10 - 9500) / 2, -1)
    fast = len(p.encode_frame(p.SETPOINTS, 0xFFFF, p.setpoints_payload(0, 12000, np.full(12, 0.5))))
    assert fast == 43 and fast * round(1 / p.FAST_BATCH_S) == 43000 and "43 bytes × 1000 frames = 43 000 bytes/s" in DOC


def test_the_frame_period_is_1_ms_only_where_the_link_has_room():
    # a 12 kHz stream in 1 ms frames: 1000 × (19 + 2 × 12) = 43 000 bytes/s; a 921 600 baud link carries
    # 92 160 bytes/s, half of it 46 080 (fits); 460 800 baud: 23 040 (does not)
    assert p.batch_s_for(921600, 12000) == 0.001
    assert p.batch_s_for(460800, 12000) == 0.002
    # 24 kHz: 19 000 + 48 000 = 67 000 bytes/s > 46 080: the 2 ms frames' smaller overhead; at 2 Mbaud it fits
    assert p.batch_s_for(921600, 24000) == 0.002 and p.batch_s_for(2_000_000, 24000) == 0.001
    # the boundary: 46 080 bytes/s is half of 921 600 baud; 43 000 + 2 × 1540 = 46 080 exactly
    assert p.batch_s_for(921600, 13540) == 0.001 and p.batch_s_for(921600, 13541) == 0.002


def test_setpoint_codes_round_to_nearest_with_ties_to_even():
    lsb = 1 / p.SETPOINT_SCALE
    fractions = np.array([-0.1, 0.0, lsb, 1.5 * lsb, 2.5 * lsb, 0.5, 1.0, 7.0])
    # hand-computed: clipped to [0, 1], × 65535, 1.5 → 2 and 2.5 → 2 (ties to even), 32767.5 → 32768
    assert p.setpoint_codes(fractions).tolist() == [0, 0, 1, 2, 2, 32768, 65535, 65535]
    first, rate, values = p.parse_setpoints(p.setpoints_payload(7, 12000, np.array([0.25])))
    assert (first, rate) == (7, 12000) and values[0] == 16384 / 65535  # round(16383.75)


TIES = [k + 0.5 for k in range(4)] + [32767.5, 65534.5]  # codes exactly half-way: rounded to even


@given(seq=st.integers(0, 1 << 20), first=st.integers(0, 1 << 40), rate=st.integers(1000, 100000),
       fractions=st.lists(st.one_of(st.floats(-2.0, 3.0), st.sampled_from(TIES).map(lambda c: c / 65535)),
                          max_size=p.MAX_SETPOINTS_PER_FRAME))
def test_setpoint_framer_sends_the_bytes_of_the_plain_encoder(seq, first, rate, fractions):
    """The writer's framer against the plain path (payload, then frame), for any values, indices and seqs."""
    values = np.array(fractions, dtype=float)
    framer = p.SetpointFramer(rate)
    expected = p.encode_frame(p.SETPOINTS, seq, p.setpoints_payload(first, rate, values))
    assert framer.frame(seq, first, values) == expected
    assert framer.frame(seq, first, values) == expected  # its buffers carry nothing from one frame to the next


def test_setpoint_framer_refuses_more_than_a_frame():
    with pytest.raises(ValueError, match="241 setpoints do not fit one frame"):
        p.SetpointFramer(12000).frame(1, 0, np.zeros(241))


def test_setpoint_framer_makes_no_array():
    """Framing 240 values allocates only bytes of the frame's size (body, COBS output, terminator: under
    3 × 500 B at the peak); the plain path's arrays of clipped, scaled and rounded values take more."""
    import tracemalloc

    values = np.linspace(-0.1, 1.1, p.MAX_SETPOINTS_PER_FRAME)
    framer = p.SetpointFramer(12000)
    wire = len(framer.frame(1, 0, values))  # warm: first-call caches are not the frame's cost

    def peak(encode) -> int:
        tracemalloc.start()
        try:
            before, _ = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            encode()
            _, top = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        return top - before

    framed = peak(lambda: framer.frame(2, 240, values))
    plain = peak(lambda: p.encode_frame(p.SETPOINTS, 2, p.setpoints_payload(240, 12000, values)))
    assert framed < 3 * wire + 512
    assert plain > 3 * wire + 512  # the bound tells the two apart
