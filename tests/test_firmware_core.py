"""The firmware's C core through its binding (software in the loop), rule by rule of docs/protocol.md v3.

A :class:`Device` here is the bare core: frames in, answers out, and time rendered a millisecond at a time
(48 drive samples, one tick) with the measured amplitude the test chooses, so every expectation is exact
and hand-computed. The simulated plate around it (physics, pty) is tested in test_plate_sim.py; the
amplitude loop on that plate in test_amplitude_loop.py."""

from __future__ import annotations

import binascii
import math
import re
import subprocess

import numpy as np
import pytest
from cobs import cobs
from conftest import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.firmware import sil

FS = 48000  # drive samples a second
PER_MS = FS // 1000
RATE = 12000
FIRMWARE = ROOT / "devices" / "firmware"


class Device:
    """The core with a host's seq counter and a millisecond clock; the plate measures ``measured`` µm p-p."""

    def __init__(self, **settings):
        self.core = sil.FirmwareCore(**settings)
        self.seq = 0
        self.decoder = p.FrameDecoder()
        self.measured = 0.0
        self.drive: list[np.ndarray] = []
        self.sent: list[p.Frame] = []  # everything the device sent, in order

    def _take(self) -> list[p.Frame]:
        frames = self.decoder.feed(self.core.transmit())
        self.sent += frames
        return frames

    def send(self, kind: int, payload: bytes = b"", seq: int | None = None) -> list[p.Frame]:
        self.seq = (self.seq + 1) & 0xFFFF if seq is None else seq
        self.core.receive(p.encode_frame(kind, self.seq, payload))
        return self._take()

    def answer(self, kind: int, payload: bytes = b"") -> int | None:
        """The NAK reason of the one answer (None for an ACK)."""
        answers = [f for f in self.send(kind, payload) if f.kind in (p.ACK, p.NAK)]
        assert len(answers) == 1, answers
        return p.parse_nak(answers[0].payload)[1] if answers[0].kind == p.NAK else None

    def setpoints(self, first: int, values, rate: int = RATE) -> list[p.Frame]:
        codes = np.asarray(values, dtype=float)
        return self.send(p.SETPOINTS, p.setpoints_payload(first, rate, codes))

    def run(self, ms: int, measured=None) -> list[p.Frame]:
        """``ms`` milliseconds of drive (kept in ``drive``), the plate measuring ``measured`` (a number, or a
        function of the drive block returning the block's amplitudes)."""
        frames = []
        for _ in range(ms):
            drive = self.core.render(PER_MS).copy()
            self.drive.append(drive)
            level = self.measured if measured is None else measured
            amplitude = level(drive) if callable(level) else np.full(PER_MS, level, dtype=np.float32)
            self.core.sense(np.asarray(amplitude, dtype=np.float32))
            frames += self._take()  # as a UART drains it: the transmit ring holds 4 KB
        return frames

    def status(self) -> sil.Status:
        return self.core.status()

    def counts(self) -> dict[str, int]:
        counts = self.status().fault_counts
        return {name: counts[bit.bit_length() - 1] for bit, name in p.FAULT_NAMES.items()}

    def played(self) -> np.ndarray:
        return np.concatenate(self.drive) if self.drive else np.zeros(0)


def telemetry(frames: list[p.Frame]) -> list[p.Telemetry]:
    return [p.parse_telemetry(f.payload) for f in frames if f.kind == p.TELEMETRY]


def enabled(**settings) -> Device:
    device = Device(**settings)
    assert device.answer(p.ENABLE, p.enable_payload(True)) is None
    return device


# ---- the build and the protocol's numbers ----------------------------------------------------------------

def test_the_cores_protocol_numbers_are_the_hosts():
    header = (FIRMWARE / "include" / "ug_protocol.h").read_text()
    defines = dict(re.findall(r"#define UG_(\w+) ([0-9.xA-F]+)[uf]?", header))
    number = lambda text: float(int(text, 16)) if text.startswith("0x") else float(text)  # noqa: E731
    same = {"PROTOCOL_VERSION", "MAX_BODY", "MAX_ENCODED", "SETPOINT_SCALE", "MAX_SETPOINTS_PER_FRAME",
            "TELEMETRY_HZ", "WATCHDOG_MS", "WATCHDOG_RAMP_MS", "BUFFER_MS", "PREFILL_MS", "TRIP_MARGIN",
            "OVER_LIMIT_REARM", "SENSORS_PERIOD_MS", "SENSORS_REST_PERIOD_MS", "MIN_SENSOR_RATE_HZ",
            "MAX_SENSOR_SAMPLES", "MAX_NAME_BYTES", "NOT_PLAYING", "MAX_SIM_FAULT_MS", "HELLO", "SET_CARRIER",
            "ENABLE", "SETPOINTS", "HEARTBEAT", "CLEAR_FAULTS", "SET_LOOP", "SIM_FAULT", "HELLO_REPLY", "ACK", "NAK",
            "TELEMETRY", "SENSORS", "NAK_UNKNOWN_TYPE", "NAK_UNSUPPORTED", "NAK_BAD_LENGTH", "NAK_BAD_VALUE",
            "NAK_INTERNAL", "FAULT_WATCHDOG", "FAULT_TRIP", "FAULT_OVER_LIMIT", "FAULT_OVERRUN", "FAULT_UNDERRUN",
            "FAULT_BAD_COMMAND", "FAULT_OVERHEAT", "FAULT_BITS", "SENSOR_AMPLITUDE", "SENSOR_NORMAL_FORCE",
            "SENSOR_LATERAL_FORCE", "FEATURE_AMPLITUDE_LOOP", "SETPOINTS_FORCE", "FEATURE_FORCE_CORRECTION",
            "FEATURE_LINK_STATED", "FEATURE_RESET_STATED", "RESTART_POWER_ON", "RESTART_WATCHDOG", "RESTART_FAULT",
            "RESTART_SOFTWARE", "RESTART_PIN", "CLOCK", "CLOCK_REPLY", "FEATURE_CLOCK_STATED", "MAX_CLOCK_LAG_MS",
            "MAX_FORCE_EXPONENT", "MAX_REFERENCE_FORCE_N", "FORCE_SPAN", "SIM_DROP", "SIM_CORRUPT", "SIM_HANG",
            "SIM_DISCONNECT", "SIM_OVERHEAT"}
    for name in same:
        assert number(defines[name]) == pytest.approx(float(getattr(p, name))), name
    playback = {"OFF": p.PLAYBACK_OFF, "PREFILL": p.PLAYBACK_PREFILL, "PLAYING": p.PLAYBACK_PLAYING,
                "DRY": p.PLAYBACK_DRY, "RAMP": p.PLAYBACK_RAMP}
    assert {name: number(defines[name]) for name in playback} == playback
    assert number(defines["TELEMETRY_V3_SIZE"]) == p.PAYLOAD_SIZES["TELEMETRY"]
    assert number(defines["HELLO_REPLY_V2_SIZE"]) == p.V2_PAYLOAD_SIZES["HELLO_REPLY"]
    assert number(defines["HELLO_REPLY_LINK_SIZE"]) == p.PAYLOAD_SIZES["HELLO_REPLY with link"] == 49
    assert number(defines["HELLO_RESET_SIZE"]) == p.PAYLOAD_SIZES["HELLO_REPLY restart fields"] == 5
    assert number(defines["CLOCK_REPLY_SIZE"]) == p.PAYLOAD_SIZES["CLOCK_REPLY"] == 8


def test_the_rules_the_simulator_breaks_are_the_documents():
    doc = (ROOT / "docs" / "protocol.md").read_text()
    table = doc[doc.index("| rule | section |"):]
    broken = [row.split("|")[1].strip() for row in table.splitlines()[2:] if row.startswith("|")
              and row.split("|")[4].strip() != "—"]
    assert sorted(sil.rules()) == sorted(broken)


@pytest.mark.slow
def test_the_core_builds_without_warnings_and_is_clean_under_gccs_analyzer(tmp_path):
    """C11, -Wall -Wextra -Werror -Wshadow -Wdouble-promotion, and gcc's static analyzer (-fanalyzer), for the
    board build (no conformance breaks) and the simulator's."""
    sources = sorted((FIRMWARE / "core").glob("*.c")) + [FIRMWARE / "ports" / "sim" / "ug_sim.c"]
    for breaks in ("0", "1"):
        for source in sources:
            result = subprocess.run(["gcc", "-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-Wshadow",
                                     "-Wdouble-promotion", "-fanalyzer", f"-DUG_CONFORMANCE_BREAKS={breaks}",
                                     f"-I{FIRMWARE / 'include'}", f"-I{FIRMWARE / 'core'}",
                                     f"-I{FIRMWARE / 'ports' / 'sim'}", "-c", str(source), "-o",
                                     str(tmp_path / (source.stem + ".o"))], capture_output=True, text=True, timeout=300)
            assert result.returncode == 0 and not result.stderr, (source.name, result.stderr)
    # the libFuzzer harness and the callgrind budget program (run by scripts, not here) still build
    for source in (FIRMWARE / "fuzz" / "fuzz_core.c", ROOT / "bench" / "firmware_core_budget.c"):
        includes = [f"-I{FIRMWARE / folder}" for folder in ("include", "core", "ports/sim")]
        result = subprocess.run(["gcc", "-std=c11", "-O1", "-Wall", "-Wextra", "-Werror", "-c", *includes, str(source),
                                 "-o", str(tmp_path / (source.stem + ".o"))],
                                capture_output=True, text=True, timeout=300)
        assert result.returncode == 0 and not result.stderr, (source.name, result.stderr)


def test_the_core_uses_no_allocation_and_no_io():
    """No malloc, free, printf, file or time calls anywhere in the portable core (newlib-nano's string and
    math functions only)."""
    forbidden = re.compile(r"\b(malloc|calloc|realloc|free|printf|sprintf|snprintf|fopen|fwrite|puts|time|clock|"
                           r"abort|exit)\s*\(")
    for source in (FIRMWARE / "core").glob("*.[ch]"):
        text = re.sub(r"/\*.*?\*/", "", source.read_text(), flags=re.S)
        assert not forbidden.search(text), source.name


@settings(max_examples=200)
@given(data=st.binary(max_size=1200))
def test_the_cores_crc_and_cobs_are_zlibs_and_the_cobs_packages(data):
    assert sil.crc32(data) == binascii.crc32(data)
    assert sil.cobs_encode(data) == cobs.encode(data)


# ---- framing and answers ------------------------------------------------------------------------------------

def test_the_devices_seq_starts_at_0_and_counts_every_frame_it_sends():  # [R-DEVICE-SEQ]
    device = Device()
    device.send(p.HELLO, p.hello_payload())
    device.run(45)  # telemetry at 1, 21 and 41 ms; SENSORS every 50 ms at rest
    device.send(0x42)
    seqs = [f.seq for f in device.sent]
    assert seqs == list(range(len(seqs))) and len(seqs) >= 5
    assert [f.kind for f in device.sent[:2]] == [p.HELLO_REPLY, p.TELEMETRY]


def test_acks_and_naks_name_the_seq_they_answer():  # [R-SEQ-ECHO]
    device = Device()
    for seq in (0, 1, 777, 0xFFFF):
        (ack,) = device.send(p.CLEAR_FAULTS, p.clear_faults_payload(0), seq=seq)
        (nak,) = device.send(0x42, seq=seq)
        assert p.parse_ack(ack.payload) == seq and p.parse_nak(nak.payload) == (seq, p.NAK_UNKNOWN_TYPE)


def test_a_bad_crc_is_dropped_counted_and_feeds_nothing():  # [R-CRC]
    device = enabled()
    frame = bytearray(p.encode_frame(p.ENABLE, 9, p.enable_payload(False)))
    body = cobs.decode(bytes(frame[:-1]))
    bad = cobs.encode(body[:-1] + bytes([body[-1] ^ 1])) + b"\x00"  # the CRC's last byte flipped
    device.core.receive(bad)
    assert device._take() == [] and device.status().crc_errors == 1 and device.status().enabled
    device.run(101)  # no valid frame since ENABLE: the watchdog fires (a bad frame does not feed it)
    assert device.counts()["watchdog"] == 1


def test_max_body_counts_decoded_bytes():  # [R-FRAMING]
    device = Device()
    biggest = p.encode_frame(p.HEARTBEAT, 1, bytes(range(1, 256)) * 3 + bytes(range(1, 253)))  # 1024 decoded
    device.core.receive(biggest)
    (nak,) = device._take()  # taken (a HEARTBEAT with a payload: wrong length), not dropped
    assert p.parse_nak(nak.payload) == (1, p.NAK_BAD_LENGTH)
    device.core.receive(b"\x07" * 1031 + b"\x00" + b"\x09" * 3000 + b"\x00\x00")
    assert device.status().framing_errors == 2  # each over-long run once, however long
    device.core.receive(b"\x02\x05\x00")  # valid COBS, 2 bytes decoded: too short
    device.core.receive(b"\x05\x01\x00")  # a block that claims 4 bytes and ends after 1: not COBS
    assert device.status().framing_errors == 4 and device.status().frames_ok == 1


def test_every_command_is_answered_in_order_and_refusals_follow_the_order_of_checks():  # [R-NAK-ORDER] [R-ACK]
    device = Device(sim_faults=False, features=0)  # firmware without SIM_FAULT or the loop
    cases = [
        (0x42, b"anything", p.NAK_UNKNOWN_TYPE),
        (p.TELEMETRY, b"", p.NAK_UNKNOWN_TYPE),
        (p.SIM_FAULT, b"", p.NAK_UNSUPPORTED),  # unsupported before the wrong length
        (p.SET_LOOP, b"\x09\x09", p.NAK_UNSUPPORTED),
        (p.ENABLE, b"\x07\x07", p.NAK_BAD_LENGTH),  # length before value
        (p.SETPOINTS, p.setpoints_payload(0, 10, np.ones(300))[:-1], p.NAK_BAD_LENGTH),
        (p.SETPOINTS, b"\x00" * 9, p.NAK_BAD_LENGTH),
        (p.SETPOINTS, p.setpoints_payload(0, 10, np.ones(4)), p.NAK_BAD_VALUE),
        (p.SETPOINTS, p.setpoints_payload(0, 48001, np.ones(4)), p.NAK_BAD_VALUE),
        (p.SETPOINTS, p.setpoints_payload(0, 12000, np.ones(0)), p.NAK_BAD_VALUE),
        (p.SET_CARRIER, p.carrier_payload(math.inf), p.NAK_BAD_VALUE),
        (p.ENABLE, b"\x02", p.NAK_BAD_VALUE),
    ]
    for kind, payload, reason in cases:
        assert device.answer(kind, payload) == reason, (kind, payload)
    status = device.status()
    assert status.naks == len(cases) == device.counts()["bad-command"] == status.frames_ok
    for kind, payload in ((p.HELLO, b"\x03"), (p.SET_CARRIER, p.carrier_payload(21000.0)), (p.ENABLE, b"\x00"),
                          (p.CLEAR_FAULTS, b"\xff\xff")):
        answers = device.send(kind, payload)
        assert len(answers) == 1 and answers[0].kind in (p.ACK, p.HELLO_REPLY)
    assert device.send(p.HEARTBEAT) == [] and device.setpoints(0, [0.1]) == []  # answered only when refused
    hot = Device()
    hot.core.set_stage_hot(True)
    assert hot.answer(p.ENABLE, b"\x01") == p.NAK_INTERNAL and not hot.status().enabled


def test_a_refused_frame_changes_nothing_but_feeds_the_watchdog():  # [R-NAK-NO-EFFECT]
    device = enabled()
    device.setpoints(0, np.full(240, 0.3))
    device.run(50)
    before = device.status()
    assert device.answer(p.SET_CARRIER, p.carrier_payload(35000.0)) == p.NAK_BAD_VALUE
    assert device.answer(p.SETPOINTS, p.setpoints_payload(240, 24000, np.full(24, 0.9))) == p.NAK_BAD_VALUE
    after = device.status()
    for name in ("carrier_hz", "setpoints", "expected_index", "stream_rate_hz", "buffered", "lost_setpoints"):
        assert getattr(after, name) == getattr(before, name), name
    assert device.counts()["bad-command"] == 2
    device.run(90)  # 90 ms after the refused frames (140 after the last accepted one): no watchdog
    assert device.counts()["watchdog"] == 0
    device.run(11)
    assert device.counts()["watchdog"] == 1


# ---- the device's clock (CLOCK, FEATURE_CLOCK_STATED) -----------------------------------------------------

def test_clock_is_answered_at_once_with_the_sensor_clock_it_numbers_sensors_by():  # [R-CLOCK]
    """At 48 kHz and 1 kHz sensors a sensor sample is 48 drive samples: after 7 ms and 30 samples the sensor
    clock is 7 + 30/48 = 7.625 samples (7, 40960/65536); with 24 samples more that the port says its ADC took
    since (``ug_port_samples_since_block``), 8 + 6/48 = 8.125. SENSORS number their samples on the same clock: the
    next frame continues from the last whole sample sensed, 7."""
    device = Device()
    (hello,) = device.send(p.HELLO, p.hello_payload(3))
    assert p.parse_hello_reply(hello.payload).features & p.FEATURE_CLOCK_STATED
    sensors = [p.parse_sensors(f.payload) for f in device.run(7) if f.kind == p.SENSORS]
    device.core.render(30)
    device.core.sense(np.zeros(30, dtype=np.float32))
    (reply,) = device.send(p.CLOCK)  # nothing else: no ACK
    assert reply.kind == p.CLOCK_REPLY and p.parse_clock_reply(reply.payload) == p.ClockReply(device.seq, 7, 40960)
    device.seq += 1
    device.core.receive(p.encode_frame(p.CLOCK, device.seq), samples_since=24)
    (reply,) = device._take()
    assert p.parse_clock_reply(reply.payload) == p.ClockReply(device.seq, 8, 8192)
    assert all(s.first_sample + len(s.samples) <= 7 for s in sensors)  # what it sent before: taken before
    sensors += [p.parse_sensors(f.payload) for f in device.run(60) if f.kind == p.SENSORS]
    assert sensors[0].first_sample == 0  # numbered from 0, consecutive ([R-SENSORS]): sample 7 began 7 ms in
    assert [s.first_sample for s in sensors[1:]] == [s.first_sample + len(s.samples) for s in sensors[:-1]]
    assert device.answer(p.CLOCK, b"\x00") == p.NAK_BAD_LENGTH


def test_clock_is_refused_by_a_device_without_sensors_and_in_a_v2_session():  # [R-CLOCK]
    bare = Device(sensors=0, sensor_rate_hz=0, features=0)
    (hello,) = bare.send(p.HELLO, p.hello_payload(3))
    assert not p.parse_hello_reply(hello.payload).features & p.FEATURE_CLOCK_STATED
    assert bare.answer(p.CLOCK) == p.NAK_UNSUPPORTED
    old = Device()
    old.send(p.HELLO, p.hello_payload(2))
    assert old.answer(p.CLOCK) == p.NAK_UNSUPPORTED


# ---- version and HELLO -----------------------------------------------------------------------------------

def test_a_v2_session_gets_v2s_layouts_no_sensors_and_no_loop():  # [R-VERSION]
    device = Device()
    (reply,) = device.send(p.HELLO, p.hello_payload(2))
    name = b"ultraglide plate simulator"
    assert p.parse_hello_reply(reply.payload).version == 2 and len(reply.payload) == 33 + len(name)
    frames = device.run(120)
    assert {f.kind for f in frames} == {p.TELEMETRY} and all(len(f.payload) == 71 for f in frames)
    assert device.answer(p.SET_LOOP, b"\x01") == p.NAK_UNSUPPORTED
    device.send(p.HELLO, p.hello_payload(3))
    frames = device.run(60)
    assert p.SENSORS in {f.kind for f in frames} and {len(f.payload) for f in frames if f.kind == p.TELEMETRY} == {89}
    assert device.answer(p.SET_LOOP, b"\x01") is None


def test_the_brake_pulls_no_further_than_its_rule_and_stops_when_the_plate_does_not_fall():  # [R-LOOP]
    """A plate measured at 3 µm p-p above a target of 0: the loop brakes (features bit 1) as hard as its rule
    allows. At the start of each 1 ms ADC block the fastest plausible plate (tau / 2 = 1.27 ms) is reset to the
    measurement p = 3 µm, and a drive u held for the loop period M = 48 samples would bring it to
    a^M p + (1 - a^M) u: to the margin m = 1 % of full scale (0.08 µm) for u = (m - a^M p) / (1 - a^M) = -2.37 µm
    by hand (a^M = exp(-48 / 61.1) = 0.456). This plate does not fall under the brake, as one vibrating in the
    opposite phase would not (the brake would drive it up): after that block the brake stays off (drive 0) until
    the measured amplitude has been below a target; then it brakes again, and stops again. A device without the
    brake never drives below 0."""
    decay = math.exp(-PER_MS / (FS * 0.5 * 200.0 / (math.pi * 25000.0)))
    rule = (0.01 - decay * 3.0 / 8.0) / (1.0 - decay)  # fraction of full scale
    assert rule * 8.0 == pytest.approx(-2.37, abs=0.01)
    for features in (p.FEATURE_AMPLITUDE_LOOP | p.FEATURE_BRAKING, p.FEATURE_AMPLITUDE_LOOP):
        device = Device(features=features, max_drive_um_pp=8.0)
        assert device.answer(p.SET_LOOP, b"\x01") is None
        assert device.answer(p.ENABLE, p.enable_payload(True)) is None
        index = 0
        for target_um_pp, measured_um_pp, ms in ((0.0, 3.0, 30), (2.0, 0.5, 10), (1.0, 3.0, 10)):
            device.measured = measured_um_pp
            for _ in range(ms):
                device.setpoints(index, np.full(12, target_um_pp / 8.0))
                index += 12
                device.run(1)
        blocks = device.played().reshape(-1, PER_MS)
        braking = np.flatnonzero(blocks.min(axis=1) < 0)
        if not features & p.FEATURE_BRAKING:
            assert len(braking) == 0
            continue
        first = braking[braking < 30]
        assert len(first) == 1 and blocks[first[0], 0] == pytest.approx(rule, abs=1e-4)  # the rule, exactly
        assert np.all(blocks[first[0] + 1:30] >= 0.0)  # then off: the plate did not fall
        again = braking[braking >= 40]  # re-armed by the plate below its target (the loop pushing), it brakes again
        assert len(again) >= 1 and np.all(blocks[again[-1] + 1:] >= 0.0)  # ... and stops again
        assert blocks.min() >= rule - 1e-6  # never beyond the rule (p is at most 3 µm)


def test_hello_changes_nothing_but_the_session():  # [R-HELLO-NO-STATE]
    device = enabled()
    device.setpoints(100, np.full(240, 0.4))
    device.run(15)
    device.send(p.CLEAR_FAULTS, p.clear_faults_payload(0))
    before = device.status()
    (reply,) = device.send(p.HELLO, p.hello_payload(3))
    after = device.status()
    assert reply.kind == p.HELLO_REPLY
    for name, _ in sil.Status._fields_:
        if name not in ("frames_ok",):
            assert np.all(np.asarray(getattr(after, name)) == np.asarray(getattr(before, name))), name
    assert after.frames_ok == before.frames_ok + 1 and after.enabled and after.buffered == before.buffered


# ---- setpoints -----------------------------------------------------------------------------------------------

def test_expected_never_moves_backwards_and_lost_and_late_are_counted():  # [R-EXPECTED]
    device = enabled()
    device.setpoints(1000, np.full(24, 0.1))  # a new stream: nothing lost
    assert device.status().expected_index == 1024
    device.setpoints(1084, np.full(24, 0.1))  # 60 lost
    assert (device.status().lost_setpoints, device.status().expected_index) == (60, 1108)
    device.setpoints(1084, np.full(24, 0.1))  # repeated: all late, expected unchanged
    assert (device.status().late_setpoints, device.status().expected_index) == (24, 1108)
    device.setpoints(1098, np.full(24, 0.1))  # 10 behind: 10 late, 14 kept, expected = 1098 + 24
    assert (device.status().late_setpoints, device.status().expected_index) == (34, 1122)
    device.setpoints(0xFFFFFFF0, np.full(24, 0.1))  # far behind (wrapping): all late
    assert (device.status().late_setpoints, device.status().expected_index) == (58, 1122)
    assert device.status().setpoints == 24 + 24 + 14
    wrap = enabled()
    wrap.setpoints(0xFFFFFFF8, np.full(24, 0.1))  # the index wraps at 2^32
    wrap.setpoints(16, np.full(24, 0.1))
    assert (wrap.status().expected_index, wrap.status().lost_setpoints) == (40, 0)


def test_overrun_values_are_counted_apart_and_every_value_once():  # [R-OVERRUN]
    device = enabled()
    index = 0
    for _ in range(13):  # 3120 values at 12 kHz: the buffer holds 250 ms, 3000
        device.setpoints(index, np.full(240, 0.2))
        index += 240
    status = device.status()
    assert (status.setpoints, status.overrun_setpoints, status.buffered) == (3000, 120, 3000)
    assert device.counts()["overrun"] == 1 and status.expected_index == 3120
    device.run(20)  # 240 values play; the next frame continues the index: no gap, no loss
    device.setpoints(index, np.full(240, 0.2))
    assert device.status().lost_setpoints == 0 and device.status().setpoints == 3240


def test_the_rate_is_set_by_the_first_frame_and_forgotten_on_disable():  # [R-RATE] [R-DISCARD]
    device = Device()
    assert device.answer(p.SETPOINTS, p.setpoints_payload(0, 500, np.ones(4))) == p.NAK_BAD_VALUE  # disabled too
    device.setpoints(0, np.full(10, 0.5), rate=8000)  # disabled: counted, not played, rate not remembered
    assert device.status().discarded_setpoints == 10 and device.status().stream_rate_hz == 0
    device.send(p.ENABLE, b"\x01")
    device.setpoints(0, np.full(24, 0.5), rate=24000)
    assert device.status().stream_rate_hz == 24000
    assert device.answer(p.SETPOINTS, p.setpoints_payload(24, 12000, np.ones(4))) == p.NAK_BAD_VALUE
    device.send(p.ENABLE, b"\x00")
    assert device.status().stream_rate_hz == 0 and device.status().expected_index == 0
    device.send(p.ENABLE, b"\x01")
    assert device.setpoints(0, np.full(24, 0.5), rate=12000) == []  # a new stream at another rate
    assert device.status().stream_rate_hz == 12000 and device.status().setpoints == 48


@pytest.mark.parametrize("rate, prefill", [(12000, 120), (1000, 10), (44100, 441), (48000, 480)])
def test_playback_starts_at_the_prefill_and_is_zero_before(rate, prefill):  # [R-PREFILL]
    device = enabled()  # ceil(10 ms × rate) values
    sent = 0
    while sent < prefill - 1:
        n = min(240, prefill - 1 - sent)
        device.setpoints(sent, np.full(n, 0.5), rate=rate)
        sent += n
    device.run(3)
    assert not device.played().any() and device.status().playback == p.PLAYBACK_PREFILL
    device.setpoints(prefill - 1, [0.5], rate=rate)
    device.run(1)
    assert device.status().playback == p.PLAYBACK_PLAYING and device.played()[-1] == pytest.approx(0.5, abs=1e-4)


@pytest.mark.parametrize("rate", [1000, 12000, 44100, 48000])
def test_values_play_at_the_streams_rate_up_to_the_drive_rate(rate):  # [R-PREFILL]: one every 1/rate s
    device = enabled()  # 48 kHz is the drive rate itself: each value plays for exactly one drive sample
    values = 0.1 + 0.5 * (np.arange(2 * rate // 10) % 97) / 97  # 200 ms of distinct values
    for first in range(0, len(values), 240):
        device.setpoints(first, values[first:first + 240], rate=rate)
    for _ in range(5):
        device.run(20)
        device.send(p.HEARTBEAT)  # the watchdog fed
    played = device.status().setpoints - device.status().buffered  # taken from the buffer in 100 ms
    assert device.counts()["underrun"] == 0 and abs(played - rate // 10) <= 2
    if rate == FS:
        start = np.flatnonzero(device.played())[0] + 1  # the first value starts playback, then plays its own sample
        assert device.played()[start:start + 960] == pytest.approx(values[:960].astype(np.float32), abs=2e-5)


def test_underrun_once_per_dry_spell_holding_the_last_value_capped_at_the_limit():  # [R-UNDERRUN]
    device = enabled()
    device.setpoints(0, np.concatenate((np.full(119, 0.3), [0.9])))  # the last one an overdrive (limit 0.75)
    device.run(30)  # 120 values play in 10 ms, then dry for 20 ms
    assert device.counts()["underrun"] == 1 and device.status().playback == p.PLAYBACK_DRY
    assert device.played()[-1] == pytest.approx(0.75, abs=1e-6)  # held at 6/8, not 0.9
    device.setpoints(120, np.full(60, 0.3))  # less than the prefill: still dry, no new underrun
    device.run(10)
    assert device.counts()["underrun"] == 1 and device.status().playback == p.PLAYBACK_DRY
    device.setpoints(180, np.full(60, 0.3))  # 120 buffered: plays again, then runs dry again: a second spell
    device.run(20)
    assert device.counts()["underrun"] == 2


def test_enable_1_while_enabled_keeps_the_stream_and_0_forgets_it():  # [R-ENABLE]
    device = enabled()
    device.setpoints(500, np.full(240, 0.4))
    device.run(12)
    before = device.status()
    assert device.answer(p.ENABLE, b"\x01") is None
    after = device.status()
    assert (after.buffered, after.expected_index, after.stream_rate_hz, after.playback) == \
        (before.buffered, before.expected_index, before.stream_rate_hz, before.playback)
    assert device.answer(p.ENABLE, b"\x00") is None
    device.run(1)
    assert device.played()[-PER_MS:].max() == 0.0  # zero within 1 ms
    off = device.status()
    assert (off.enabled, off.buffered, off.expected_index, off.stream_rate_hz) == (0, 0, 0, 0)
    assert device.answer(p.ENABLE, b"\x00") is None and not device.status().enabled


# ---- watchdog --------------------------------------------------------------------------------------------

def test_the_watchdog_fires_after_watchdog_ms_ramps_the_present_drive_and_keeps_the_stream():  # [R-WATCHDOG]
    device = enabled()
    device.setpoints(0, np.full(240, 0.6))
    device.run(100)  # 100 ms since the last valid frame: it fires at this tick (101 ms at most)
    assert device.counts()["watchdog"] == 1 and device.status().playback == p.PLAYBACK_RAMP
    assert device.status().buffered == 0 and device.status().expected_index == 240
    device.run(25)
    drive = device.played()
    fired = int(np.flatnonzero(np.diff(drive) < -1e-4)[0]) + 1  # the ramp's first step
    assert 100 * PER_MS <= fired <= 101 * PER_MS
    start = drive[fired - 1]
    assert start == pytest.approx(0.6, abs=1e-4)  # held since the buffer ran dry: the present drive
    ramp = device.played()[fired:fired + 20 * PER_MS + 1]
    expected = start * (1 - np.arange(len(ramp)) / (20 * PER_MS))
    assert ramp == pytest.approx(np.maximum(expected, 0.0), abs=2e-3)  # linear to zero over 20 ms
    assert device.played()[fired + 20 * PER_MS:].max() == 0.0 and device.status().playback == p.PLAYBACK_PREFILL
    device.run(300)
    assert device.counts()["watchdog"] == 1  # once per silence
    device.setpoints(400, np.full(240, 0.3))  # the stream resumes: 160 values lost in the silence
    assert device.status().lost_setpoints == 160 and device.status().stream_rate_hz == RATE
    device.run(100)
    assert device.counts()["watchdog"] == 2  # a new silence
    off = Device()
    off.run(500)
    assert off.counts()["watchdog"] == 0  # never armed while disabled


def test_a_stall_of_the_simulator_is_neither_silence_nor_a_gap_and_its_telemetry_is_one_frame_after():
    """The simulated plate's process did not run for 60 ms (a loaded machine): the frames that waited on the
    link are read (with the 60 ms lag), then the clock catches up. Excused, that time feeds neither the
    watchdog nor the stream's gap, and the three telemetry frames due in it become one, once the clock is
    back, reporting the buffer then (made on time, they reported it before the catch-up played it)."""
    def stalled(excused: bool):
        device = Device()
        device.send(p.HELLO, p.hello_payload(3))
        assert device.answer(p.ENABLE, p.enable_payload(True)) is None
        device.setpoints(0, np.full(240, 0.5))  # 20 ms at 12 kHz
        device.run(10)
        device.core.events()
        for first in (240, 480, 720):  # 60 ms more, come while the simulator did not run
            device.seq += 1
            device.core.receive(p.encode_frame(p.SETPOINTS, device.seq,
                                               p.setpoints_payload(first, RATE, np.full(240, 0.5))), 60)
        if excused:
            device.core.excuse(60)
        telemetry = [p.parse_telemetry(f.payload) for f in device.run(60) if f.kind == p.TELEMETRY]
        return device, telemetry, [e.kind for e in device.core.events()]

    device, telemetry, events = stalled(excused=True)
    assert len(telemetry) == 1 and telemetry[0].buffered_setpoints == device.status().buffered
    assert 960 - 70 * 12 - 2 <= device.status().buffered <= 960 - 70 * 12  # (less what interpolation holds)
    assert sil.EV_STREAM_STOPPED not in events and device.counts()["watchdog"] == 0
    assert device.counts()["underrun"] == 0
    # not excused: three frames, the first reporting 50 ms of values more than the buffer held after
    _, telemetry, _ = stalled(excused=False)
    assert len(telemetry) == 3 and telemetry[0].buffered_setpoints >= device.status().buffered + 40 * 12


# ---- limits and faults -----------------------------------------------------------------------------------

def test_the_devices_limiter_clips_to_the_limit_and_overdrives_only_below_it():  # [R-LIMIT]
    device = enabled(max_drive_um_pp=8.0)
    device.setpoints(0, np.full(240, 1.0))  # full scale (8 µm) requested; the limit is 6 µm
    device.run(20, measured=2.0)
    drive = device.played()
    assert drive[0] == pytest.approx(1.0)  # overdrive, up to the ceiling, while the plate is below its limit
    # ... but only briefly: the fastest plausible plate (Q/2: tau 1.27 ms) would reach the limit after
    # tau ln(1 / (1 - 0.75)) = 1.77 ms at full drive, and from then on the drive is the limit's share
    above = np.flatnonzero(drive > 0.75 + 1e-6)
    assert 1.6e-3 < len(above) / FS < 1.9e-3 and drive[-1] == pytest.approx(0.75, abs=1e-6)
    near = enabled(max_drive_um_pp=8.0)
    near.setpoints(0, np.full(240, 0.8))  # 6.4 µm asked: the model alone would allow it for a while
    near.run(1, measured=1.0)
    assert near.played()[-1] == pytest.approx(0.8)
    near.run(1, measured=6.0)  # the plate reached the limit during this block (measured as the block ends) ...
    assert near.played()[-1] == pytest.approx(0.8)
    near.run(1, measured=6.0)  # ... and from the next sample on, the limit's share
    assert near.played()[-PER_MS:] == pytest.approx(np.full(PER_MS, 0.75))
    capped = enabled(max_drive_um_pp=6.0)  # no overdrive granted
    capped.setpoints(0, np.full(240, 1.0))
    capped.run(20)
    assert capped.played().max() == pytest.approx(0.75)


def test_over_limit_has_hysteresis_and_trip_cuts_disables_and_latches():  # [R-OVER-LIMIT] [R-TRIP]
    device = enabled()
    for level, raised in ((6.01, 1), (5.9, 1), (6.01, 1), (5.87, 1), (6.01, 2)):  # re-armed below 5.88
        device.run(1, measured=level)
        assert device.counts()["over-limit"] == raised, level
    device.setpoints(0, np.full(240, 0.5))
    device.run(12)

    def rising(drive):  # crosses 6.06 (the trip) at the 10th sample of the block
        return 6.0 + 0.01 * np.arange(1, len(drive) + 1)

    device.run(1, measured=rising)
    status = device.status()
    assert device.counts()["trip"] == 1 and not status.enabled and status.faults & p.FAULT_TRIP
    assert status.stream_rate_hz == 0 and status.buffered == 0
    device.run(5)
    assert device.status().faults & p.FAULT_TRIP  # latched until cleared


def test_faults_latch_count_every_raise_and_clearing_a_persisting_one_re_sets_it():
    # [R-FAULT-LATCH] [R-FAULT-COUNT] [R-CLEAR-FAULTS]
    device = Device()
    for _ in range(3):
        device.send(0x42)
    assert device.counts()["bad-command"] == 3 and device.status().faults == p.FAULT_BAD_COMMAND
    device.run(100)
    assert device.status().faults == p.FAULT_BAD_COMMAND  # telemetry read it many times: still latched
    device.run(1, measured=6.5)
    device.core.set_stage_hot(True)
    assert device.status().faults == p.FAULT_BAD_COMMAND | p.FAULT_OVER_LIMIT | p.FAULT_OVERHEAT
    device.answer(p.CLEAR_FAULTS, p.clear_faults_payload(0xFFFF))
    # over the limit and hot still: both set again at once, not counted again
    assert device.status().faults == p.FAULT_OVER_LIMIT | p.FAULT_OVERHEAT
    assert device.counts()["over-limit"] == 1 and device.counts()["overheat"] == 1
    device.core.set_stage_hot(False)
    device.run(1, measured=1.0)
    device.answer(p.CLEAR_FAULTS, p.clear_faults_payload(p.FAULT_OVERHEAT))
    assert device.status().faults == p.FAULT_OVER_LIMIT  # the other bit stays
    device.answer(p.CLEAR_FAULTS, p.clear_faults_payload(p.FAULT_OVER_LIMIT))
    assert device.status().faults == 0


def test_an_injected_overheat_lasts_its_duration():
    device = enabled()
    assert device.answer(p.SIM_FAULT, p.sim_fault_payload(p.SIM_OVERHEAT, 30)) is None
    assert not device.status().enabled and device.status().stage_hot
    device.run(29)
    assert device.answer(p.ENABLE, b"\x01") == p.NAK_INTERNAL
    device.run(2)
    assert device.answer(p.ENABLE, b"\x01") is None and device.status().enabled


# ---- telemetry, sensors, carrier -----------------------------------------------------------------------------

def test_telemetry_every_20_ms_in_the_sessions_layout_with_the_stream():  # [R-TELEMETRY]
    device = enabled()
    device.setpoints(77, np.full(240, 0.5))
    frames = telemetry(device.run(1000))
    assert len(frames) == 50
    last = frames[-1]
    assert last.version == 3 and last.enabled and last.stream_rate_hz == RATE and last.expected_index == 317
    early = telemetry(enabled().run(10))
    assert len(early) == 1 and early[0].playback == p.PLAYBACK_PREFILL and early[0].stream_rate_hz == 0
    device = enabled()
    device.setpoints(0, np.full(240, 0.5))
    (t,) = telemetry(device.run(13))
    # the first telemetry leaves at the first tick, 1 ms in: 12 values played of 240
    assert (t.playback, t.drive_code, t.buffered_setpoints) == (p.PLAYBACK_PLAYING, 32768, 240 - 12)


def test_sensors_carry_every_sample_once_with_the_playing_index():  # [R-SENSORS]
    device = enabled()
    device.send(p.HELLO, p.hello_payload(3))
    device.setpoints(5000, np.full(240, 0.5))
    device.setpoints(5240, np.full(240, 0.5))
    frames = device.run(40, measured=lambda drive: 8.0 * drive)
    sensors = [p.parse_sensors(f.payload) for f in frames if f.kind == p.SENSORS]
    assert len(sensors) >= 3
    numbers = np.concatenate([s.first_sample + np.arange(len(s.samples)) for s in sensors])
    assert np.array_equal(numbers, np.arange(numbers[0], numbers[0] + len(numbers)))  # consecutive, none twice
    assert all(len(s.samples) <= 10 + 1 for s in sensors[1:])  # at most 10 ms apart while enabled
    for s in sensors:
        assert np.isnan(s.samples["normal_force_n"]).all() and np.isnan(s.samples["lateral_force_n"]).all()
    # a sample's number is the millisecond it covers; the first drive sample played index 5000, and each value
    # plays for 4 drive samples (12 kHz in 48 kHz), popped at the end of its last: ms k begins with 5000 + 12k - 1
    for s in sensors:
        assert s.setpoint_index == (5000 if s.first_sample == 0 else 5000 + 12 * s.first_sample - 1)
    late = sensors[-1].samples["amplitude_um_pp"]
    assert late == pytest.approx(4.0, abs=1e-3)


def test_the_carrier_is_a_phase_continuous_sine_at_the_drive():  # [R-CARRIER]
    device = enabled()
    device.setpoints(0, np.full(240, 0.5))
    device.setpoints(240, np.full(240, 0.5))
    device.run(11)  # playing 0.5
    dac_rate = FS * 4
    first = device.core.dac(dac_rate // 100).astype(float)  # 10 ms at 192 kHz
    spectrum = np.abs(np.fft.rfft(first * np.hanning(len(first))))
    peak_hz = np.argmax(spectrum) * dac_rate / len(first)
    assert peak_hz == pytest.approx(25000.0, abs=100.0) and np.abs(first).max() == pytest.approx(0.5 * 32767, rel=2e-3)
    assert device.answer(p.SET_CARRIER, p.carrier_payload(24000.0)) is None  # while enabled: allowed
    second = device.core.dac(dac_rate // 100).astype(float)
    joined = np.concatenate((first[-200:], second[:200])) / (0.5 * 32767)
    phase = np.unwrap(np.angle(_analytic(joined)))
    step = np.diff(phase)[150:250]
    assert np.all(step > 0) and np.max(np.abs(np.diff(step))) < 0.05  # no jump in phase at the change
    spectrum = np.abs(np.fft.rfft(second * np.hanning(len(second))))
    assert np.argmax(spectrum) * dac_rate / len(second) == pytest.approx(24000.0, abs=100.0)


def _analytic(x: np.ndarray) -> np.ndarray:
    from scipy.signal import hilbert

    return hilbert(x)


# ---- each rule the simulator can break, broken, is seen broken ---------------------------------------------

def _streaming(device: Device, values=0.4, n=240, first=0) -> Device:
    device.answer(p.ENABLE, b"\x01")
    device.setpoints(first, np.full(n, values))
    return device


def _follows(rule: str, device: Device) -> bool:
    """A probe of ``rule``: True when ``device`` follows it."""
    if rule == "R-FRAMING":
        frame = p.encode_frame(p.HEARTBEAT, 1, bytes(range(1, 256)) * 3 + bytes(range(1, 253)))
        device.core.receive(frame)
        return [f.kind for f in device._take()] == [p.NAK]
    if rule == "R-CRC":
        device.answer(p.ENABLE, b"\x01")
        body = cobs.decode(p.encode_frame(p.ENABLE, 9, b"\x00")[:-1])
        device.core.receive(cobs.encode(body[:-1] + bytes([body[-1] ^ 1])) + b"\x00")
        return bool(device.status().enabled)
    if rule == "R-DEVICE-SEQ":
        (hello,) = device.send(p.HELLO, b"\x03")
        (ack,) = device.send(p.CLEAR_FAULTS, b"\x00\x00")
        (again,) = device.send(p.HELLO, b"\x03")
        return (hello.seq, ack.seq, again.seq) == (0, 1, 2)
    if rule == "R-SEQ-ECHO":
        return p.parse_ack(device.send(p.CLEAR_FAULTS, b"\x00\x00", seq=1234)[0].payload) == 1234
    if rule == "R-VERSION":
        return p.hello_reply_version(device.send(p.HELLO, b"\x02")[0].payload) == 2
    if rule == "R-HELLO-NO-STATE":
        _streaming(device)
        before = device.status().buffered
        device.send(p.HELLO, b"\x03")
        return bool(device.status().enabled) and device.status().buffered == before
    if rule == "R-NAK-ORDER":
        return device.answer(p.ENABLE, b"\x07\x07") == p.NAK_BAD_LENGTH
    if rule == "R-NAK-NO-EFFECT":
        device.answer(p.SET_CARRIER, p.carrier_payload(35000.0))
        return device.status().carrier_hz == 25000.0
    if rule == "R-ACK":
        return [f.kind for f in device.send(p.ENABLE, b"\x01")] == [p.ACK]
    if rule == "R-CARRIER":
        _streaming(device)
        return device.answer(p.SET_CARRIER, p.carrier_payload(24000.0)) is None
    if rule == "R-TELEMETRY":
        return 45 <= len(telemetry(device.run(1000))) <= 55
    if rule == "R-SENSORS":
        sensors = [p.parse_sensors(f.payload) for f in device.run(200) if f.kind == p.SENSORS]
        pairs = zip(sensors[:-1], sensors[1:], strict=True)
        return len(sensors) >= 3 and all(b.first_sample == a.first_sample + len(a.samples) for a, b in pairs)
    if rule == "R-RATE":
        _streaming(device)
        device.answer(p.ENABLE, b"\x00")
        device.answer(p.ENABLE, b"\x01")
        return device.setpoints(0, np.full(24, 0.2), rate=24000) == []
    if rule == "R-EXPECTED":
        _streaming(device, first=1000)
        device.setpoints(990, np.full(5, 0.2))
        return device.status().expected_index == 1240
    if rule == "R-OVERRUN":
        device.answer(p.ENABLE, b"\x01")
        for k in range(13):
            device.setpoints(240 * k, np.full(240, 0.2))
        return device.status().setpoints == 3000 and device.status().overrun_setpoints == 120
    if rule == "R-PREFILL":
        _streaming(device, n=60)
        device.run(5)
        return not device.played().any()
    if rule == "R-UNDERRUN":
        _streaming(device)
        device.run(70)
        return device.counts()["underrun"] == 1
    if rule == "R-DISCARD":
        device.setpoints(0, np.full(240, 0.5))
        device.answer(p.ENABLE, b"\x01")
        device.run(20)
        return not device.played().any()
    if rule == "R-ENABLE":
        _streaming(device)
        device.answer(p.ENABLE, b"\x01")
        return device.status().buffered == 240
    if rule == "R-LIMIT":
        _streaming(device, values=1.0)
        device.run(10)
        return device.played().max() <= 0.75 + 1e-6
    if rule == "R-OVER-LIMIT":
        device.run(20, measured=6.02)
        return device.counts()["over-limit"] == 1
    if rule == "R-WATCHDOG":
        _streaming(device)
        device.run(110)
        return device.counts()["watchdog"] == 1
    if rule == "R-FAULT-LATCH":
        device.send(0x42)
        device.run(60)
        return bool(device.status().faults & p.FAULT_BAD_COMMAND)
    if rule == "R-FAULT-COUNT":
        for _ in range(3):
            device.send(0x42)
        return device.counts()["bad-command"] == 3
    if rule == "R-CLEAR-FAULTS":
        device.send(0x42)
        device.answer(p.CLEAR_FAULTS, b"\xff\xff")
        return device.status().faults == 0
    if rule == "R-LOOP":
        _streaming(device)
        return device.answer(p.SET_LOOP, b"\x01") == p.NAK_BAD_VALUE
    if rule == "R-CLOCK":  # 20 ms and 24 drive samples in: the sensor clock is 20.5 samples
        device.run(20)
        device.core.render(24)
        device.core.sense(np.zeros(24, dtype=np.float32))
        (reply,) = device.send(p.CLOCK)
        return p.parse_clock_reply(reply.payload).samples == 20.5
    raise AssertionError(f"no probe for {rule}")


@pytest.mark.parametrize("rule", sil.rules())
def test_each_break_breaks_its_rule_and_only_the_broken_device_fails_the_probe(rule):
    assert _follows(rule, Device(max_drive_um_pp=6.0)), rule
    assert not _follows(rule, Device(max_drive_um_pp=6.0, breaks=(rule,))), rule


def test_a_rule_that_does_not_exist_cannot_be_broken():
    with pytest.raises(DeviceError, match="no rule R-NOTHING to break"):
        sil.FirmwareCore(breaks=("R-NOTHING",))


# ---- fuzzing through the binding: any frames, any garbage, any order (hypothesis) --------------------------

def _commands():
    """(kind, payload) of every command, mostly well-formed with values in and out of range."""
    either = st.one_of
    setpoint = st.builds(lambda first, rate, codes: (p.SETPOINTS, p.setpoints_payload(first, rate, np.array(codes))),
                         either(st.integers(0, 4000), st.integers(0, 0xFFFFFFFF)),
                         either(st.sampled_from([12000, 12000, 1000, 48000]), st.integers(0, 60000)),
                         st.lists(st.floats(-0.2, 1.2), max_size=260))
    return st.one_of(
        setpoint, setpoint, setpoint,
        st.builds(lambda f: (p.SET_CARRIER, p.carrier_payload(f)),
                  either(st.floats(19000, 29000), st.floats(width=32))),
        st.builds(lambda b: (p.ENABLE, bytes([b])), either(st.sampled_from([0, 1, 1]), st.integers(0, 255))),
        st.builds(lambda m: (p.CLEAR_FAULTS, p.clear_faults_payload(m)), st.integers(0, 0xFFFF)),
        st.builds(lambda v: (p.HELLO, bytes([v])), either(st.sampled_from([2, 3]), st.integers(0, 255))),
        st.builds(lambda v: (p.SET_LOOP, bytes([v])), either(st.sampled_from([0, 1]), st.integers(0, 255))),
        st.builds(lambda k, ms: (p.SIM_FAULT, p.sim_fault_payload(k, ms)), st.sampled_from([5, 5, 9]),
                  st.integers(0, 40)),
        st.just((p.HEARTBEAT, b"")),
        st.tuples(st.integers(0, 255), st.binary(max_size=40)),
    )


def _steps():
    """A session: frames, garbage, and time passing (ms) with the plate's Q off the core's by 0.5-2x."""
    step = st.one_of(st.tuples(st.just("frame"), _commands()), st.tuples(st.just("frame"), _commands()),
                     st.tuples(st.just("garbage"), st.binary(min_size=1, max_size=60)),
                     st.tuples(st.just("time"), st.integers(1, 150)))
    return st.tuples(st.sampled_from([0.5, 1.0, 2.0]), st.floats(0.5, 1.0), st.booleans(),
                     st.lists(step, max_size=40))


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(session=_steps())
def test_fuzzed_sessions_keep_every_invariant(session):
    q_factor, gain, braking, steps = session
    device = Device(max_drive_um_pp=8.0, features=p.FEATURE_AMPLITUDE_LOOP | (p.FEATURE_BRAKING if braking else 0))
    limit, full_scale = 6.0, 8.0
    alpha = math.exp(-1.0 / (FS * q_factor * 200.0 / (math.pi * 25000.0)))
    plate = 0.0
    sent_values: dict[int, int] = {}  # seq of a SETPOINTS frame -> its values
    commands: set[int] = set()  # seqs of frames that must be answered
    sent: list[tuple[int, int]] = []  # (seq, command) of every valid frame, in order
    counts_before = np.zeros(8)
    valid = 0
    for kind, what in steps:
        if kind == "frame":
            command, payload = what
            device.seq = (device.seq + 1) & 0xFFFF
            device.core.receive(p.encode_frame(command, device.seq, payload))
            sent.append((device.seq, command))
            valid += 1
            if command == p.SETPOINTS and len(payload) >= 10:
                sent_values[device.seq] = int.from_bytes(payload[8:10], "little")
            if command in (p.HELLO, p.SET_CARRIER, p.ENABLE, p.CLEAR_FAULTS, p.SET_LOOP, p.SIM_FAULT, p.CLOCK) or \
                    command not in p.HOST_COMMANDS or (command == p.HEARTBEAT and payload):
                commands.add(device.seq)
            device._take()
        elif kind == "garbage":
            device.core.receive(what + b"\x00")
            device._take()
        else:
            for _ in range(what):
                drive = device.core.render(PER_MS).copy()
                # never beyond the drive ceiling; in antiphase (a brake) never beyond minus the limit
                assert drive.min() >= (-limit / full_scale - 1e-6 if braking else 0.0) and drive.max() <= 1.0 + 1e-6
                phasor, _ = lfilter([(1 - alpha) * gain * full_scale], [1, -alpha], drive, zi=[alpha * plate])
                plate = float(phasor[-1])
                # the device's limit binds: a plate up to twice as fast as configured, driven on or off
                # resonance, never goes above its limit in either phase (whatever the host sent, loop on or off),
                # and a brake never pulls it through zero into the opposite phase
                assert np.abs(phasor).max() <= limit * (1 + 1e-4), np.abs(phasor).max()
                assert phasor.min() >= -1e-4, phasor.min()
                device.core.sense(np.abs(phasor).astype(np.float32))
                device._take()
        status = device.status()
        counts = np.array(status.fault_counts)
        assert np.all(counts >= counts_before)  # counters never go back
        counts_before = counts
    status = device.status()
    answers = [f for f in device.sent if f.kind in (p.ACK, p.NAK, p.HELLO_REPLY, p.CLOCK_REPLY)]
    naks = {p.parse_nak(f.payload)[0] for f in answers if f.kind == p.NAK}
    # every command answered once, refused SETPOINTS and HEARTBEAT too, in the order they were sent
    expected = [(seq, command) for seq, command in sent if seq in commands or seq in naks]
    assert len(answers) == len(expected)
    for answer, (seq, command) in zip(answers, expected, strict=True):
        if answer.kind == p.HELLO_REPLY:
            assert command == p.HELLO
        elif answer.kind == p.CLOCK_REPLY:
            assert command == p.CLOCK and p.parse_clock_reply(answer.payload).asked_seq == seq
        else:
            assert (p.parse_ack(answer.payload) if answer.kind == p.ACK else p.parse_nak(answer.payload)[0]) == seq
    accepted = sum(n for seq, n in sent_values.items() if seq not in naks)
    assert status.setpoints + status.overrun_setpoints + status.late_setpoints + status.discarded_setpoints == accepted
    assert status.frames_ok == valid and status.naks == len(naks) == status.fault_counts[5]
    seqs = [f.seq for f in device.sent]
    assert seqs == list(range(len(seqs)))  # the device's frames, numbered from 0, none skipped


def test_a_library_built_from_other_sources_is_refused(monkeypatch):
    """The library carries the SHA-256 of the sources it was built from; the binding refuses one whose sources
    are not those beside it (edited since the install), rather than run other code than it shows."""
    lib = sil.load()
    sil._check_fresh(lib)  # this checkout's library: accepted
    monkeypatch.setattr(sil, "sources_digest", lambda: "0" * 64)
    with pytest.raises(sil.FirmwareBuildError, match="built from other sources"):
        sil._check_fresh(lib)
