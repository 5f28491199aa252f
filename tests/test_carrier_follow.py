"""A plate that reports another carrier than the one it was sent is a device fault: ``play`` on a serial plate says
so in words and exits 3. The plate is the real simulator on a pty, made to report a carrier of its own
(devices/sim/lies.py); the rule (a second running off every carrier sent in the last 0.25 s, devices/serial/
follow.py) is checked at its edges by hand-made frames, 50 a second as telemetry comes."""

import re

import pytest
from conftest import run_cli, serve_plate
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.serial.follow import CARRIER_LAG_S, CarrierFollow
from ultraglide.devices.sim.lies import Lies

PROFILE = load_profile("sim-plate")
FRAME_S = 0.02  # telemetry's period
SAID = re.compile(r"the plate does not follow the carrier it is sent: from \d+\.\d\d s it was sent (\d+\.\d\d) Hz and "
                  r"said it played (\d+\.\d\d) Hz for 1\.00 s running; \d+ frames? after that")


def frames(follow, sent_hz, reported_hz, seconds, start_s=0.0, judged=True):
    count = round(seconds / FRAME_S)
    for k in range(count):
        follow.observe(sent_hz, reported_hz, judged, start_s + k * FRAME_S)
    return start_s + count * FRAME_S


@pytest.mark.parametrize("reported_hz, fault", [(25000.0, False), (25000.009, False), (25000.02, True),
                                                (24000.0, True)])
def test_the_tolerance_is_a_hundredth_of_a_hertz(reported_hz, fault):
    follow = CarrierFollow()
    frames(follow, 25000.0, reported_hz, 1.2)
    assert (follow.words() is not None) == fault


def test_just_under_a_second_off_the_carrier_is_not_yet_a_fault_and_a_frame_on_it_starts_again():
    follow = CarrierFollow()
    at = frames(follow, 25000.0, 24000.0, 0.98)  # 49 frames: 0.96 s from the first to the last
    at = frames(follow, 25000.0, 25000.0, FRAME_S, at)
    frames(follow, 25000.0, 24000.0, 0.98, at)
    assert follow.words() is None
    frames(follow, 25000.0, 24000.0, 1.1, at + 1.0)
    said = SAID.match(follow.words())
    assert said and float(said[1]) == 25000.0 and float(said[2]) == 24000.0


def test_frames_not_judged_are_left_out():
    follow = CarrierFollow()
    frames(follow, 25000.0, 24000.0, 3.0, judged=False)  # the handshake: the device's own carrier until it is set
    assert follow.words() is None


def test_a_carrier_just_replaced_is_still_believed_for_the_lag():
    follow = CarrierFollow()
    at = frames(follow, 25000.0, 25000.0, 0.5)
    # a tracker moving 1 Hz every 0.1 s, telemetry a step behind: always a carrier sent within the lag
    previous = 25000.0
    for step in range(30):
        sent = 25001.0 + step
        at = frames(follow, sent, previous, 0.1, at)
        previous = sent
    assert follow.words() is None
    # a plate that stays on a carrier sent longer ago than the lag does not follow
    at = frames(follow, 26000.0, previous, CARRIER_LAG_S + 1.1, at)
    assert follow.words() is not None and float(SAID.match(follow.words())[2]) == previous


def test_play_on_a_plate_that_plays_its_own_carrier_says_so_and_exits_3():
    plate = serve_plate(PROFILE, lies=Lies({"telemetry.carrier_hz": 24000.0}))
    try:
        result = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                         "--duration-s", 4, timeout=300)
    finally:
        plate.stop()
    assert result.returncode == 3, (result.stdout, result.stderr)
    said = [line for line in result.stdout.splitlines() if SAID.match(line)]
    assert len(said) == 1, result.stdout
    assert [float(v) for v in SAID.match(said[0]).groups()] == [25000.0, 24000.0]  # the profile's resonance, the lie
    assert result.stderr.strip().splitlines()[-1] == "ultraglide play: the plate faulted (exit status 3)"


def test_play_on_an_honest_plate_is_not_taken_for_one_that_does_not_follow():
    plate = serve_plate(PROFILE)
    try:
        result = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                         "--duration-s", 3, timeout=300)
    finally:
        plate.stop()
    assert "does not follow the carrier" not in result.stdout, result.stdout
