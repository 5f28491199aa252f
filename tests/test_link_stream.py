"""The link decides the stream: a plate driver states in HELLO_REPLY what its link carries (and its plate's Q), the
host fits its stream to it and says so, a URL's ``rate``/``frame_ms`` win where they fit, and a driver that
describes its plate may stand in for a profile nobody gave. Codecs against hand-packed bytes, the firmware core's
own encoder (through its host binding), the stream's choice against the byte budget worked by hand, and the
commands against the simulated plate on a real pty (stated, not stated, v2)."""

from __future__ import annotations

import json
import struct

import pytest
from conftest import assert_one_line_error, run_cli, serve_plate
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.firmware import sil
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.devices.rig import load_plate
from ultraglide.devices.serial.handshake import hello_spec, plate_of_hello, plate_of_spec
from ultraglide.devices.serial.link import choose_stream, probe_hello

PROFILE = load_profile("sim-plate")


def hello(link_bytes_per_s=0, q=200.0, version=3, min_rate=1000, max_rate=48000, **fields) -> p.HelloReply:
    features = p.FEATURE_AMPLITUDE_LOOP | (p.FEATURE_LINK_STATED if link_bytes_per_s else 0)
    return p.HelloReply(version, 25000.0, 8.0, 6.0, min_rate, max_rate, 20000.0, 28000.0, 100, 250, "board", 8.0,
                        p.SENSOR_AMPLITUDE, 1000, features, link_bytes_per_s, q if link_bytes_per_s else 0.0,
                        **fields)


# ---- the wire ------------------------------------------------------------------------------------------------

def test_a_reply_that_states_its_link_carries_two_fields_before_the_name():
    payload = p.hello_reply_payload(hello(14000, 150.0))
    head = struct.pack("<BfffIIffHHfBHB", 3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, 8.0,
                       1, 1000, 1 | 8)
    assert payload == head + struct.pack("<If", 14000, 150.0) + b"board"  # 49 bytes, then the name
    parsed = p.parse_hello_reply(payload)
    assert (parsed.link_bytes_per_s, parsed.q, parsed.name, parsed.states_link) == (14000, 150.0, "board", True)


def test_a_reply_without_the_bit_reads_as_before_and_states_nothing():
    payload = p.hello_reply_payload(hello())
    assert len(payload) == 41 + len("board")
    parsed = p.parse_hello_reply(payload)
    assert (parsed.link_bytes_per_s, parsed.q, parsed.name, parsed.states_link) == (0, 0.0, "board", False)
    v2 = p.parse_hello_reply(p.hello_reply_payload(hello(version=2)))
    assert (v2.version, v2.states_link, v2.name) == (2, False, "board")


def test_the_firmware_core_states_its_link_and_q_only_when_configured_and_only_in_v3():
    for stated, session, expected in ((14000, 3, (14000, 180.0)), (0, 3, (0, 0.0)), (14000, 2, (0, 0.0))):
        core = sil.FirmwareCore(q=180.0, link_bytes_per_s=stated, sim_faults=False)
        core.receive(p.encode_frame(p.HELLO, 7, p.hello_payload(session)))
        core.poll()  # replies are encoded outside the frame's critical section, in the main loop
        reply = None
        for frame in p.FrameDecoder().feed(core.transmit()):
            if frame.kind == p.HELLO_REPLY:
                reply = p.parse_hello_reply(frame.payload)
        assert reply is not None and reply.version == session
        assert (reply.link_bytes_per_s, reply.q) == expected
        assert reply.name == "ultraglide plate simulator"  # the name is read whole after the two fields


# ---- the stream the host chooses (bytes/s = 19 / frame_s + 2 × rate, docs/protocol.md) -------------------------

@pytest.mark.parametrize("link, rate, frame_ms", [
    (14000, 1000, 4),  # half is 7 000: 1000/s in 4 ms frames costs 4 750 + 2 000 = 6 750; in 2 ms, 11 500
    (92160, 12000, 1),  # half is 46 080: 12 000/s in 1 ms frames costs 19 000 + 24 000 = 43 000 (the default)
    (60000, 12000, 4),  # half is 30 000: 12 000/s in 2 ms is 33 500, in 4 ms 28 750
    # half is 15 000: 12 000/s never fits (24 000 in values alone), 6 000/s in 4 ms is 16 750; 4 000/s in 1 ms
    # is 27 000, in 2 ms 17 500, in 4 ms 12 750
    (30000, 4000, 4),
])
def test_the_host_takes_the_fastest_rate_in_the_shortest_frame_within_half_the_link(link, rate, frame_ms):
    plan = choose_stream("/dev/pts/9", hello(link), 12000, 921600)
    assert (plan.rate_hz, plan.batch_s, plan.chosen_by) == (rate, frame_ms / 1000, "device")
    assert plan.bytes_per_s == 19 / (frame_ms / 1000) + 2 * rate <= link / 2
    assert plan.line("/dev/pts/9").startswith(f"stream: {rate} setpoints/s in {frame_ms} ms frames")
    assert f"{link / 1000:.1f} kB/s the plate driver's link carries" in plan.line("/dev/pts/9")


def test_the_device_rate_range_and_the_uart_bound_the_choice():
    # a device that plays at most 2 000/s: 2 000 in 1 ms frames (23 000 of 46 080)
    plan = choose_stream("/dev/pts/9", hello(92160, max_rate=2000), 12000, 921600)
    assert (plan.rate_hz, plan.batch_s) == (2000, 0.001)
    # a device that states a fast link, opened at 230 400 baud: 23 040 bytes/s, half 11 520: 6 000/s in 4 ms costs
    # 16 750, 4 000/s 12 750, 3 000/s 10 750
    plan = choose_stream("/dev/ttyUSB0", hello(200000), 12000, 230400)
    assert (plan.rate_hz, plan.batch_s) == (3000, 0.004)
    # ... at 115 200 baud, half is 5 760: not even 1 000/s in 4 ms (6 750) fits
    with pytest.raises(DeviceError, match="carries 11520 bytes/s .* needs 6750"):
        choose_stream("/dev/ttyUSB0", hello(200000), 12000, 115200)


def test_what_the_url_asks_wins_where_it_fits_the_whole_link_and_is_refused_where_not():
    # rate=2000 on 14 000 bytes/s: 4 ms frames cost 8 750, over half but within the whole link; 2 ms 13 500 too,
    # and the shortest frame within the half comes first, then within the whole: 2 ms
    plan = choose_stream("/dev/pts/9", hello(14000), 12000, 921600, rate_hz=2000)
    assert (plan.rate_hz, plan.batch_s, plan.chosen_by) == (2000, 0.002, "url")
    assert "as the device URL asks" in plan.line("/dev/pts/9")
    plan = choose_stream("/dev/pts/9", hello(14000), 12000, 921600, batch_s=0.004)
    assert (plan.rate_hz, plan.batch_s) == (1000, 0.004)
    with pytest.raises(DeviceError, match=r"carries 14000 bytes/s .* needs at least 31000") as refused:
        choose_stream("/dev/pts/9", hello(14000), 12000, 921600, rate_hz=6000, batch_s=0.001)  # 19 000 + 12 000
    assert "\n" not in str(refused.value)


def test_a_link_too_slow_for_any_stream_is_refused_in_one_line():
    with pytest.raises(DeviceError, match=r"carries 5000 bytes/s .* slowest stream .* needs 6750") as refused:
        choose_stream("/dev/pts/9", hello(5000), 12000, 921600)
    assert "\n" not in str(refused.value)


def test_a_device_that_states_nothing_gets_the_default_and_the_line_says_so():
    plan = choose_stream("/dev/pts/9", hello(), 12000, 921600)
    assert (plan.rate_hz, plan.batch_s, plan.chosen_by) == (12000, p.batch_s_for(921600, 12000), "default")
    assert "the default: the plate driver does not say what its link carries" in plan.line("/dev/pts/9")
    assert "serial:/dev/pts/9?rate=1000&frame_ms=4" in plan.line("/dev/pts/9")
    v2 = choose_stream("/dev/pts/9", hello(version=2), 12000, 460800)
    assert (v2.rate_hz, v2.batch_s) == (12000, 0.002)  # 460 800 baud: 2 ms frames, as before
    assert "speaks protocol v2" in v2.line("/dev/pts/9")


# ---- the plate a handshake describes ------------------------------------------------------------------------

def test_a_handshake_that_states_q_describes_a_plate_that_travels_as_a_spec():
    plate = plate_of_hello(hello(14000, 150.0))
    assert (plate.name, plate.resonance_hz, plate.q, plate.full_scale_um_pp, plate.max_amplitude_um_pp,
            plate.max_drive_um_pp, plate.carrier_min_hz, plate.carrier_max_hz) == \
        ("board", 25000.0, 150.0, 8.0, 6.0, 8.0, 20000.0, 28000.0)
    spec = hello_spec(plate)
    assert spec.startswith("hello:") and load_plate(spec) == plate_of_spec(spec) == plate
    assert plate_of_hello(hello()) is None and plate_of_hello(hello(version=2)) is None
    with pytest.raises(DeviceError, match="not a plate a handshake described"):
        plate_of_spec('hello:{"name": "x"}')


def test_an_audible_plate_from_a_handshake_is_refused_in_one_line():
    audible = p.HelloReply(3, 15000.0, 8.0, 6.0, 1000, 48000, 10000.0, 28000.0, 100, 250, "singer", 8.0,
                           features=p.FEATURE_LINK_STATED, link_bytes_per_s=14000, q=100.0)
    with pytest.raises(DeviceError, match="not one a profile may hold.*audible.*give --profile") as refused:
        plate_of_hello(audible)
    assert "\n" not in str(refused.value)


# ---- against the simulated plate on a real pty ----------------------------------------------------------------

def test_probe_reads_the_simulated_plates_reply_and_leaves_it_as_it_was():
    plate = serve_plate(PROFILE)
    try:
        reply = p.parse_hello_reply(probe_hello(plate.path, 921600))
        assert (reply.link_bytes_per_s, reply.q, reply.version) == (92160, 200.0, 3)
        assert not plate.simulator.core.status().enabled
    finally:
        plate.stop()


def test_play_with_no_profile_takes_the_plate_the_driver_describes_and_says_so(tmp_path):
    truth = PlateProfile("bench", 24000.0, 120.0, 10.0, 5.0, carrier_min_hz=21000.0, carrier_max_hz=27000.0)
    plate = serve_plate(truth)
    try:
        result = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}", "--duration-s", "1", "--json")
    finally:
        plate.stop()
    assert result.returncode == 0, result.stdout + result.stderr
    said = [line for line in result.stderr.splitlines() if line.strip()]
    assert said == ["ultraglide play: no --profile or --rig: plate: ultraglide plate simulator (as the plate driver "
                    "describes it in its handshake): resonance 24000 Hz; a sample of 1.0 is 10 µm p-p; limit 5 µm "
                    "p-p"], result.stderr
    status = json.loads(result.stdout)
    assert status["stream"] == {"rate_hz": 12000, "frame_ms": 1.0, "bytes_per_s": 43000.0,
                                "link_bytes_per_s": 92160, "chosen_by": "device"}
    assert any(note.startswith("stream: 12000 setpoints/s in 1 ms frames") for note in status["notes"])
    assert status["limit_um_pp"] == 5.0 and status["report"]["verdict"] == "clean", status["report"]
    assert plate.simulator.peak_um_pp <= 5.0 * (1 + p.TRIP_MARGIN)


@pytest.mark.parametrize("options", [{"link_bytes_per_s": 0}, {"max_version": 2}], ids=["v3-unstated", "v2"])
def test_a_driver_that_states_nothing_needs_a_profile_and_gets_the_default_stream_said(options):
    plate = serve_plate(PROFILE, **options)
    try:
        refused = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}", "--duration-s", "1")
        line = assert_one_line_error(refused)
        assert refused.returncode == 2
        assert "does not describe its plate in its handshake" in line and "--profile" in line
        result = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                         "--duration-s", "1")
    finally:
        plate.stop()
    assert result.returncode == 0, result.stdout + result.stderr
    default = [line for line in result.stdout.splitlines() if line.startswith("stream: ")]
    assert len(default) == 1 and "the default" in default[0] and "?rate=1000&frame_ms=4" in default[0], result.stdout
    assert default[0].startswith("stream: 12000 setpoints/s in 1 ms frames")


def test_a_url_stream_the_stated_link_cannot_carry_is_refused_before_streaming():
    plate = serve_plate(PROFILE, link_bytes_per_s=14000)
    try:
        result = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}?rate=12000&frame_ms=1",
                         "--profile", "sim-plate", "--duration-s", "1")
        assert plate.simulator.core.status().setpoints == 0  # nothing was streamed
    finally:
        plate.stop()
    line = assert_one_line_error(result)
    assert "carries 14000 bytes/s" in line and "12000 setpoints/s in 1 ms frames needs 43000" in line
