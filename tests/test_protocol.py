"""The wire protocol: round trips, and any bytes at all into the decoder (hypothesis)."""

import binascii
import dataclasses
import re
import struct

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
    assert reply.max_drive_um_pp == 6.0 and reply.sensors == 0 and not reply.has_amplitude_loop  # v2: none
    telemetry = p.Telemetry(2.5, 25000.0, p.FAULT_WATCHDOG, True, 10, 1, 2, 4000, 3, 4, 5, (1, 0, 0, 0, 7, 0, 0, 0),
                            version=2)
    assert p.parse_telemetry(p.telemetry_payload(telemetry, 2)) == telemetry
    assert telemetry.fault_names() == ["watchdog"]
    assert telemetry.counts_by_name()["watchdog"] == 1 and telemetry.counts_by_name()["underrun"] == 7
    assert p.parse_ack(p.ack_payload(9)) == 9
    assert p.parse_nak(p.nak_payload(9, p.NAK_BAD_VALUE)) == (9, p.NAK_BAD_VALUE)
    with pytest.raises(p.ProtocolError):
        p.parse_setpoints(p.setpoints_payload(0, 12000, np.ones(4))[:-1])


def test_a_clock_reply_round_trips_and_its_bytes_are_the_tables():
    """CLOCK_REPLY: asked_seq u16, sample u32, fraction u16, little-endian (by hand: 0x1234, 0x89ABCDEF, 0x8000)."""
    reply = p.ClockReply(0x1234, 0x89ABCDEF, 0x8000)
    assert p.clock_reply_payload(reply) == bytes([0x34, 0x12, 0xEF, 0xCD, 0xAB, 0x89, 0x00, 0x80])
    assert p.parse_clock_reply(p.clock_reply_payload(reply)) == reply and reply.samples == 0x89ABCDEF + 0.5
    with pytest.raises(p.ProtocolError):
        p.parse_clock_reply(p.clock_reply_payload(reply)[:-1])


def test_v3_messages_round_trip_and_extend_v2s_layouts_at_their_ends():
    reply = p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "plate", 7.5,
                         p.SENSOR_AMPLITUDE | p.SENSOR_NORMAL_FORCE, 1000, p.FEATURE_AMPLITUDE_LOOP)
    v3 = p.hello_reply_payload(reply)
    assert p.parse_hello_reply(v3) == reply and reply.has_amplitude_loop
    v2 = p.hello_reply_payload(dataclasses.replace(reply, version=2))
    # 33 bytes of v2's fields, then max_drive f32, sensors u8, sensor rate u16, features u8: 8 more, then the name
    assert (len(v2), len(v3)) == (33 + 5, 41 + 5) and v3[1:33] == v2[1:33] and v3[-5:] == v2[-5:] == b"plate"
    assert struct.unpack_from("<fBHB", v3, 33) == (7.5, 3, 1000, 1)
    telemetry = p.Telemetry(2.5, 25000.0, 0, True, 10, 1, 2, 4000, 3, 4, 5, (0,) * 8, 6, 123456, 12000, 120, 32768,
                            p.PLAYBACK_PLAYING, p.LOOP_AMPLITUDE)
    payload = p.telemetry_payload(telemetry)
    assert len(payload) == 71 + 18 and payload[:71] == p.telemetry_payload(telemetry, 2)
    assert struct.unpack_from("<IIIHHBB", payload, 71) == (6, 123456, 12000, 120, 32768, 2, 1)
    assert p.parse_telemetry(payload) == telemetry
    with pytest.raises(p.ProtocolError, match="telemetry of 70 bytes"):
        p.parse_telemetry(payload[:70])
    samples = p.sensor_samples([1.0, 2.0, 3.5], normal_force_n=[0.1, 0.2, 0.3])
    sensors = p.parse_sensors(p.sensors_payload(1000, p.NOT_PLAYING, samples))
    assert sensors == p.Sensors(1000, 0xFFFFFFFF, samples) and len(p.sensors_payload(0, 0, samples)) == 9 + 36
    assert np.isnan(sensors.samples["lateral_force_n"]).all()
    assert sensors.samples["normal_force_n"].tolist() == pytest.approx([0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="1 to 80 samples"):
        p.sensors_payload(0, 0, p.sensor_samples(np.zeros(81)))
    with pytest.raises(p.ProtocolError):
        p.parse_sensors(p.sensors_payload(0, 0, samples)[:-1])


def test_the_name_is_at_most_64_bytes_of_utf8_and_a_host_replaces_what_is_invalid():
    base = p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "")
    long = "é" * 40  # 80 bytes: cut to 32 whole characters (64 bytes), never half of one
    assert p.parse_hello_reply(p.hello_reply_payload(dataclasses.replace(base, name=long))).name == "é" * 32
    assert p.parse_hello_reply(p.hello_reply_payload(base)).name == ""  # 0 bytes is a name too
    raw = p.hello_reply_payload(base) + b"plate \xff" + b"x" * 100  # invalid UTF-8, and more than 64 bytes
    name = p.parse_hello_reply(raw).name
    assert name == "plate \ufffd" + "x" * 57  # 64 bytes taken, the bad byte replaced


def test_a_frame_of_max_body_decoded_bytes_passes_and_a_longer_run_is_one_framing_error():
    decoder = p.FrameDecoder()
    biggest = p.encode_frame(p.HEARTBEAT, 1, bytes(range(1, 256)) * 3 + bytes(range(1, 253)))  # 1024 decoded
    assert len(biggest) - 1 == 1029 <= p.MAX_ENCODED == 1024 + 5 + 1
    assert [f.kind for f in decoder.feed(biggest)] == [p.HEARTBEAT]
    with pytest.raises(ValueError, match="exceeds 1024"):
        p.encode_frame(p.HEARTBEAT, 1, bytes(1018))
    decoder.feed(b"\x07" * 1030)  # 1030 bytes without a delimiter: still a frame in the making
    assert decoder.framing_errors == 0
    decoder.feed(b"\x07" * 2000)  # over 1030: dropped, one error however long it goes on
    assert decoder.framing_errors == 1
    assert [f.seq for f in decoder.feed(b"\x00" + p.encode_frame(p.HEARTBEAT, 5))] == [5]
    assert decoder.framing_errors == 1


# ---- docs/protocol.md is normative: its tables must say what the code does --------------------------

DOC = (ROOT / "docs" / "protocol.md").read_text()
SIZES = {"u8": 1, "u16": 2, "u32": 4, "f32": 4}


def _rows(header: str) -> list[list[str]]:
    """The rows of the first table whose header row is ``header``, cell for cell."""
    wanted = [cell.strip() for cell in header.strip().strip("|").split("|")]
    lines = [line.strip() for line in DOC.splitlines()]
    start = next(i for i, line in enumerate(lines)
                 if line.startswith("|") and [cell.strip() for cell in line.strip("|").split("|")] == wanted)
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
    rows = _rows("| constant | value | meaning |")
    assert len(rows) >= 20
    for name, value, _ in rows:
        assert getattr(p, name.strip("`")) == pytest.approx(float(value)), name
    assert p.MAX_ENCODED == p.MAX_BODY + -(-p.MAX_BODY // 254) + 1


def test_the_documents_message_tables_are_the_codes():
    host = _rows("| type | name | payload | answer |")
    device = _rows("| type | name | payload |")
    v2 = _rows("| type | name | v2 payload |")
    assert {name for _, name, *_ in host} == {"HELLO", "SET_CARRIER", "ENABLE", "SETPOINTS", "HEARTBEAT",
                                              "CLEAR_FAULTS", "SET_LOOP", "SETPOINTS_FORCE", "CLOCK", "SIM_FAULT"}
    assert {getattr(p, name) for _, name, *_ in host} == set(p.HOST_COMMANDS)
    assert {name for _, name, *_ in device} == {"HELLO_REPLY", "ACK", "NAK", "TELEMETRY", "SENSORS", "CLOCK_REPLY"}
    assert {name for _, name, *_ in v2} == {"HELLO_REPLY", "TELEMETRY"}
    for kind, name, payload, *_ in host + device:
        assert getattr(p, name) == int(kind, 16), name
        fixed = _fixed_size(payload.split("`")[1] if "`" in payload else payload)
        expected = p.PAYLOAD_SIZES[f"{name} header"] if name in ("SETPOINTS", "SETPOINTS_FORCE") else \
            p.PAYLOAD_LENGTHS.get(getattr(p, name), p.PAYLOAD_SIZES.get(name))
        assert fixed == expected, (name, fixed, expected)
    for kind, name, payload in v2:
        assert getattr(p, name) == int(kind, 16)
        assert _fixed_size(payload.split("`")[1]) == p.V2_PAYLOAD_SIZES[name], name
    sample = re.search(r"each `sample` is\s+`([^`]+)`", DOC).group(1)
    assert _fixed_size(sample.replace(" | ", ", ")) == p.PAYLOAD_SIZES["SENSORS sample"] == 12


def test_the_documents_fault_bits_and_nak_reasons_are_the_codes():
    faults = _rows("| bit | fault | raised when | what the device did "
                   "| a condition that re-sets it while it persists |")
    assert {int(bit, 16): name for bit, name, *_ in faults} == p.FAULT_NAMES
    reasons = _rows("| reason | meaning |")
    assert {int(reason): meaning for reason, meaning in reasons} == p.NAK_REASONS


def test_every_rule_is_in_the_conformance_table_and_tagged_in_the_text():
    table = _rows("| rule | section | what the device must do | the simulator's break |")
    rules = [rule for rule, *_ in table]
    assert len(rules) == len(set(rules)) >= 25
    text = DOC[:DOC.index("## Conformance")]
    tagged = set(re.findall(r"\[(R-[A-Z0-9-]+)\]", text))
    assert tagged == set(rules)  # each rule's sentence carries its identifier, and nothing else is tagged
    headings = {line.lstrip("#").strip() for line in DOC.splitlines() if line.startswith("## ")}
    for rule, section, *_ in table:
        assert any(heading.startswith(section) for heading in headings), (rule, section)


def test_the_documents_byte_budget_is_the_framing():
    per_frame = len(p.encode_frame(p.SETPOINTS, 0xFFFF, p.setpoints_payload(0, 12000, np.full(24, 0.5))))
    frames_per_s = round(1 / p.BATCH_S)
    assert per_frame == 67 and per_frame * frames_per_s == 33500
    assert "= 33 500 bytes/s" in DOC and "67 bytes × 500 frames" in DOC
    blank = p.Telemetry(1.0, 25000.0, 0, True, *([1] * 7), (0,) * p.FAULT_BITS)
    telemetry = len(p.encode_frame(p.TELEMETRY, 1, p.telemetry_payload(blank)))
    assert telemetry == 98 and telemetry * p.TELEMETRY_HZ == 4900 and "98 bytes\n  on the wire) 50 times" in DOC
    assert "4 900 bytes/s" in DOC
    telemetry_v2 = len(p.encode_frame(p.TELEMETRY, 1, p.telemetry_payload(blank, 2)))
    assert telemetry_v2 == 80 and telemetry_v2 * p.TELEMETRY_HZ == 4000 and "80 bytes, 4 000 bytes/s" in DOC
    sensors = {n: len(p.encode_frame(p.SENSORS, 1, p.sensors_payload(0, 0, p.sensor_samples(np.ones(n)))))
               for n in range(1, p.MAX_SENSOR_SAMPLES + 1)}
    assert all(sensors[n] == 18 + 12 * n for n in range(1, 20))
    assert all(18 + 12 * n <= sensors[n] <= 18 + 12 * n + (16 + 12 * n) // 254 for n in sensors)  # COBS: ≤ 1 per 254
    assert sensors[10] == 138 and 138 * round(1000 / p.SENSORS_PERIOD_MS) == 13800 and "13 800 bytes/s" in DOC
    assert sensors[50] == 618 and 618 * round(1000 / p.SENSORS_REST_PERIOD_MS) == 12360 and "12 360 bytes/s" in DOC
    assert 13800 + 4900 == 18700 and "18 700 bytes/s in all" in DOC and "17 260 in all" in DOC
    for n in (1, 24, 96, 118):  # the general formula on the page, against real frames
        assert len(p.encode_frame(p.SETPOINTS, 1, p.setpoints_payload(0, 12000, np.full(n, 0.3)))) == 19 + 2 * n
    rows = _rows("| link | bytes/s | 12 kHz stream in 2 ms frames (33 500 bytes/s) | fastest stream that fits "
                 "(2 ms frames) | device to host, v3 with 1 kHz sensors (18 700 bytes/s) |")
    for link, bytes_per_s, _, fastest, device in rows[:4]:
        baud = int(link.split()[1])
        assert int(bytes_per_s.replace(" ", "")) == baud // 10  # 8N1: ten bits a byte
        assert int(fastest.removesuffix(" setpoints/s").replace(" ", "")) == round((baud // 10 - 9500) / 2, -1)
        if baud // 10 < 18700:
            assert device.startswith("does not fit")
        else:
            assert device == f"{round(100 * 18700 / (baud // 10))} % of the link"
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


def test_empty_framer_sends_the_bytes_of_the_plain_encoder_for_every_seq():
    """The writer's CLOCK frames against the plain path, for all 65536 seqs (zeros in the seq and the CRC move COBS's
    codes), and the 16 bits of a larger seq kept as the plain encoder keeps them."""
    framer = p.EmptyFramer(p.CLOCK)
    for seq in range(65536):
        assert framer.frame(seq) == p.encode_frame(p.CLOCK, seq), seq
    assert framer.frame(65536 + 5) == p.encode_frame(p.CLOCK, 5) == p.EmptyFramer(p.CLOCK).frame(5)


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
