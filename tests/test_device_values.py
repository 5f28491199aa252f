"""No device value believed without a check: the real simulated plate on a pty, made to lie (devices/sim/lies.py)
within the protocol's framing, one field at a time. A HELLO_REPLY that cannot be true refuses the device in one
line; a TELEMETRY or SENSORS frame with a value that cannot be is not taken and is a device fault (exit status 3),
said once with the field, its value and its range, counted in the status; the ranges are docs/protocol.md's."""

import math

import numpy as np
import pytest
from conftest import serve_plate, wait_for
from sources import Constant
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.protocol.ranges import hello_out_of_range
from ultraglide.devices.serial.plate import SerialPlate
from ultraglide.devices.sim.lies import Lies

PROFILE = load_profile("sim-plate")  # full scale 8, limit 6 µm p-p, carrier 20-28 kHz; the simulator's HELLO says so
DEADLINE_S = 60.0

# HELLO_REPLY: each field out of its range, and the sentence's start (the range from docs/protocol.md)
HELLO_LIES = {
    "resonance_hz": (31000.0, "resonance_hz = 31000, outside 20000..28000 Hz"),
    "full_scale_um_pp": (math.nan, "full_scale_um_pp = nan, outside"),
    "max_amplitude_um_pp": (9.0, "max_amplitude_um_pp = 9, outside 1e-06..8 µm p-p"),
    "max_drive_um_pp": (5.0, "max_drive_um_pp = 5, outside 6..8 µm p-p"),
    "carrier_min_hz": (-1.0, "carrier_min_hz = -1, outside 1000..100000 Hz"),
    "watchdog_ms": (5, "watchdog_ms = 5, outside 20..1000 ms"),
    "buffer_ms": (2000, "buffer_ms = 2000, outside 50..1000 ms"),
    "min_setpoint_rate_hz": (0, "min_setpoint_rate_hz = 0, outside 1..1e+06"),
    "sensor_rate_hz": (10, "sensor_rate_hz = 10 with sensors, below 1000"),
    "sensors": (0x21, "sensors = 0x21 has bits no sensor is defined for"),
    "features": (2, "features says braking without the amplitude loop"),
}

# TELEMETRY, by class: amplitudes and frequencies (floats), codes and states, the stream's numbers
TELEMETRY_LIES = {
    "measured_um_pp=nan": ("measured_um_pp", "measured_um_pp = nan, outside 0..16 µm p-p"),
    "measured_um_pp=-0.5": ("measured_um_pp", "measured_um_pp = -0.5, outside 0..16 µm p-p"),
    "measured_um_pp=40": ("measured_um_pp", "measured_um_pp = 40, outside 0..16 µm p-p"),
    "carrier_hz=31000": ("carrier_hz", "carrier_hz = 31000, outside 20000..28000 Hz"),
    "carrier_hz=inf": ("carrier_hz", "carrier_hz = inf, outside 20000..28000 Hz"),
    "faults=256": ("faults", "faults = 0x0100 has bits no fault is defined for"),
    "playback=9": ("playback", "playback = 9, not a state (0-4)"),
    "loop=7": ("loop", "loop = 7, not a loop mode"),
    "stream_rate_hz=500000": ("stream_rate_hz", "stream_rate_hz = 500000, outside its own 1000-48000"),
    "buffered_setpoints=60000": ("buffered_setpoints", "buffered_setpoints = 60000, more than its 250 ms buffer"),
}

SENSORS_LIES = {
    "amplitude_um_pp=nan": ("amplitude_um_pp", "amplitude_um_pp = nan, outside 0..16 µm p-p"),
    "amplitude_um_pp=-1": ("amplitude_um_pp", "amplitude_um_pp = -1, outside 0..16 µm p-p"),
    "normal_force_n=2": ("normal_force_n", "normal_force_n = 2 from a device without a normal force sensor"),
    "first_sample=5": ("first_sample", "first_sample = 5, not the"),
}


def run_lying(lie: str | None, frames: int = 40):
    """A driver streaming a steady 1 µm p-p to the simulated plate, which tells ``lie`` (``FRAME.FIELD=VALUE``)
    from its 20th telemetry frame on; the driver stopped after ``frames`` more."""
    plate = serve_plate(PROFILE)
    try:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.start(Constant(1.0))
        try:
            assert wait_for(lambda: driver.telemetry_frames >= 20, timeout=DEADLINE_S)
            if lie is None:
                taken = driver.telemetry_frames
                assert wait_for(lambda: driver.telemetry_frames >= taken + frames, timeout=DEADLINE_S)
            else:
                plate.lies = Lies.parse([lie])  # from now on (its frames are re-encoded whole as they leave)
                assert wait_for(lambda: sum(driver.status()["values_not_believed"].values()) >= 5,
                                timeout=DEADLINE_S)
        finally:
            driver.stop()
    finally:
        plate.stop()
    return driver


def test_an_honest_plate_reports_nothing_that_cannot_be():
    driver = run_lying(None, frames=150)  # 3 s: the amplitude judged over two windows and more too
    assert driver.status()["values_not_believed"] == {}
    assert not any("cannot be" in line or "does not follow" in line for line in driver.report().lines)


@pytest.mark.parametrize("field", sorted(HELLO_LIES))
def test_a_handshake_reply_that_cannot_be_true_refuses_the_device_in_one_line(field):
    value, words = HELLO_LIES[field]
    lies = Lies({f"hello.{field}": value})
    if field == "features":  # braking without the loop: the simulator's features 3 (loop and brake) become 2
        lies = Lies({"hello.features": 2})
    plate = serve_plate(PROFILE, lies=lies)
    try:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        with pytest.raises(DeviceError) as refused:
            driver.start(Constant(1.0))
    finally:
        plate.stop()
    message = str(refused.value)
    assert "\n" not in message and "the plate driver's handshake reply cannot be believed: " in message, message
    assert words in message, message
    assert not plate.simulator.enabled  # never enabled: nothing it said was acted on


@pytest.mark.parametrize("lie", sorted(TELEMETRY_LIES))
def test_telemetry_that_cannot_be_is_not_believed_and_is_a_device_fault(lie):
    field, words = TELEMETRY_LIES[lie]
    driver = run_lying(f"telemetry.{lie}")
    report, status = driver.report(), driver.status()
    assert report.exit_status == 3, report.lines  # a device fault
    said = [line for line in report.lines if line.startswith("the plate reported values that cannot be: ")]
    assert len(said) == 1, report.lines  # said once, however many frames lied
    assert f"TELEMETRY {field} ({words}" in said[0], said[0]
    assert status["values_not_believed"][f"TELEMETRY {field}"] >= 2  # counted, frame by frame
    if field == "measured_um_pp":  # never believed: the last telemetry taken is the last true one
        assert 0.0 <= status["measured_um_pp"] <= 2 * PROFILE.full_scale_um_pp


@pytest.mark.parametrize("lie", sorted(SENSORS_LIES))
def test_sensor_samples_that_cannot_be_are_not_believed_and_are_a_device_fault(lie):
    field, words = SENSORS_LIES[lie]
    driver = run_lying(f"sensors.{lie}")
    report = driver.report()
    assert report.exit_status == 3, report.lines
    said = [line for line in report.lines if line.startswith("the plate reported values that cannot be: ")]
    assert len(said) == 1 and f"SENSORS {field} ({words}" in said[0], report.lines
    if driver.intake.sensors is not None:  # the last frame taken holds only values that can be
        amplitude = np.asarray(driver.intake.sensors.samples["amplitude_um_pp"], dtype=float)
        assert np.all(np.isfinite(amplitude) & (amplitude >= 0))


def test_a_clock_reply_that_cannot_be_is_not_believed_and_is_a_device_fault():
    """A plate that states its clock (CLOCK_REPLY) as sample 5, far behind the SENSORS it has sent: not believed
    (docs/protocol.md: at most MAX_CLOCK_LAG_MS behind them), said once, a device fault; nothing reaches a clock
    listener."""
    heard = []
    plate = serve_plate(PROFILE)
    try:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.add_clock_listener(lambda *reply: heard.append(reply))
        driver.start(Constant(1.0))
        try:
            assert wait_for(lambda: len(heard) >= 3, timeout=DEADLINE_S)  # honest replies first: believed
            plate.lies = Lies.parse(["clock_reply.sample=5", "clock_reply.fraction=0"])
            assert wait_for(lambda: driver.status()["values_not_believed"].get("CLOCK_REPLY sample", 0) >= 3,
                            timeout=DEADLINE_S)
            taken = len(heard)
        finally:
            driver.stop()
    finally:
        plate.stop()
    report = driver.report()
    assert report.exit_status == 3, report.lines
    said = [line for line in report.lines if line.startswith("the plate reported values that cannot be: ")]
    assert len(said) == 1 and "CLOCK_REPLY sample (sample = 5.0, " in said[0] and "samples behind" in said[0], said
    assert len(heard) == taken  # none of the lies reached the listener


class LiesOnce(Lies):
    """The lies told in one frame of their kind, then no more (a device that restarted answering one CLOCK)."""

    def rewrite(self, frames: list[bytes]) -> list[bytes]:
        told = super().rewrite(frames)
        if told != frames:
            self.fields.clear()  # falsy now: the plate tells no more
            self._by_frame.clear()
        return told


def test_a_clock_reply_from_a_board_just_restarted_is_dropped_not_a_fault():
    """A board that restarts mid-run without a new HELLO answers CLOCK at once from near 0, while the request
    carried the end of the SENSORS read before the restart (here: one reply at sample 3, mid-stream). As SENSORS
    beginning again once a connection, it is no device fault: the reply is dropped (not heard, not counted, no
    exit status 3), and the replies after it are believed."""
    heard = []
    plate = serve_plate(PROFILE)
    try:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.add_clock_listener(lambda *reply: heard.append(reply))
        driver.start(Constant(1.0))
        try:
            assert wait_for(lambda: len(heard) >= 3, timeout=DEADLINE_S)  # into the stream: SENSORS past sample 3
            plate.lies = LiesOnce.parse(["clock_reply.sample=3", "clock_reply.fraction=0"])
            assert wait_for(lambda: not plate.lies, timeout=DEADLINE_S)  # told once
            after = len(heard)
            assert wait_for(lambda: len(heard) >= after + 3, timeout=DEADLINE_S)  # honest ones go on being heard
        finally:
            driver.stop()
    finally:
        plate.stop()
    assert all(b[0] > a[0] for a, b in zip(heard, heard[1:], strict=False))  # the reply at 3 reached no listener
    report = driver.report()  # (its status may still say a host stalled on a loaded machine: not this test's)
    assert driver.status()["values_not_believed"] == {} and report.exit_status != 3, report.lines
    assert not [line for line in report.lines if "values that cannot be" in line], report.lines


def test_the_simulators_own_handshake_is_within_every_range():
    # the reference the ranges are drawn against: docs/protocol.md's numbers, as the firmware's core answers them
    plate = serve_plate(PROFILE)
    try:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.start(Constant(0.0))
        hello = driver.session.state.device
        driver.stop()
    finally:
        plate.stop()
    assert hello_out_of_range(hello) == []
    assert (hello.watchdog_ms, hello.buffer_ms, hello.carrier_min_hz, hello.carrier_max_hz) == (100, 250, 20000, 28000)
    assert hello.max_amplitude_um_pp <= hello.max_drive_um_pp <= hello.full_scale_um_pp
    assert hello.sensors & p.SENSOR_AMPLITUDE and hello.sensor_rate_hz >= p.MIN_SENSOR_RATE_HZ
