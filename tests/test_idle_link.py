"""The serial link at rest, on a real pty: a host whose drive is zero stops streaming and disables the
output; the first non-zero drive enables it and reaches the plate at once; a plate that cut itself out
(trip, overheat) is never re-enabled by that."""

import time

import numpy as np
import pytest
from conftest import serve_plate, wait_for
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.serial.link import IDLE_AFTER_S
from ultraglide.devices.serial.plate import SerialPlate
from ultraglide.devices.sim.plate import TELEMETRY_S, TICK_S, PlateSimulator

PROFILE = load_profile("sim-plate")
RATE_HZ = 12000


class Level:
    """A source of a steady drive (µm p-p) that the test changes; remembers when the writer first
    pulled a non-zero value after each change (perf_counter s)."""

    def __init__(self, amplitude_um_pp=0.0):
        self.amplitude = amplitude_um_pp
        self.pulled = 0
        self.first_nonzero_s = None
        self.stopping = False

    def set(self, amplitude_um_pp):
        self.first_nonzero_s = None
        self.amplitude = amplitude_um_pp

    def pull(self, n, now_s):
        self.pulled += n
        if self.amplitude > 0 and self.first_nonzero_s is None:
            self.first_nonzero_s = time.perf_counter()
        return np.full(n, 0.0 if self.stopping else self.amplitude)

    def request_stop(self):
        self.stopping = True

    @property
    def finished(self):
        return self.stopping


def pulled_for(source, seconds):
    """Wait until the writer has pulled ``seconds`` more of the stream (its own clock, whatever the load)."""
    target = source.pulled + int(seconds * RATE_HZ)
    assert wait_for(lambda: source.pulled >= target, timeout=60)


def events(sim):
    found = []
    while not sim.events.empty():
        found.append(sim.events.get())
    return found


@pytest.fixture
def plate():
    served = serve_plate(PROFILE)
    yield served
    served.stop()


@pytest.fixture
def connect():
    """``connect(plate, source)``: a driver started on the plate, stopped when the test ends even if it failed (a
    driver left streaming would load the tests that run after it)."""
    started = []

    def start(plate, source, **options):
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10, **options)
        driver.start(source)
        started.append(driver)
        return driver

    yield start
    for driver in started:
        driver.stop()


def test_a_resting_host_sends_nothing_and_the_plate_is_disabled_without_a_fault(plate, connect):
    sim = plate.simulator
    source = Level(0.0)
    driver = connect(plate, source)
    assert wait_for(lambda: driver.counters.idle_rests == 1 and not sim.enabled, timeout=30)
    # the plate has taken the disable; its output stage, a thread of its own, may not yet have ticked over the
    # time before it (a loaded machine may underrun the 50 ms of zeros before the rest, and that is counted
    # then): the baseline once it has reported twice since, its telemetry being sent by that stage
    reported = driver.telemetry_frames
    assert wait_for(lambda: driver.telemetry_frames >= reported + 2, timeout=30)
    played = sim.counters.setpoints + sim.counters.discarded_setpoints
    frames, telemetry = sim.counters.frames_ok, driver.telemetry_frames
    faults = sim.fault_counts()
    pulled_for(source, 1.0)  # a second of a resting stream: 500 frames before
    assert sim.counters.setpoints + sim.counters.discarded_setpoints == played
    # not one frame (no setpoints, no heartbeat), but a CLEAR_FAULTS for a fault latched before the rest
    assert sim.counters.frames_ok - frames <= sum(faults.values())
    assert driver.telemetry_frames >= telemetry + 10  # the plate still reports (the host's silence check)
    assert driver.status()["connected"] and driver.counters.silences == 0
    assert driver.status()["output"] == "idle (disabled)"
    # resting raises nothing
    assert sim.fault_counts() == faults and faults["watchdog"] == 0, (faults, sim.fault_counts())
    assert sim.amplitude_um_pp == 0.0
    driver.stop()
    assert not sim.enabled
    assert [e["event"] for e in events(sim)].count("enabled") == 1  # the handshake's: no enable on the way out


def test_the_first_non_zero_drive_enables_the_plate_and_reaches_it_at_once(plate, connect):
    sim = plate.simulator
    source = Level(0.0)
    driver = connect(plate, source)
    assert wait_for(lambda: driver.counters.idle_rests == 1 and not sim.enabled, timeout=30)
    events(sim)
    source.set(3.0)
    assert wait_for(lambda: sim.amplitude_um_pp > 0.05, timeout=30)
    reached_s = time.perf_counter()
    touched_s = source.first_nonzero_s
    # from the writer's pull to the plate moving: the 2 ms batch, the link and the plate's 10 ms prefill
    # (the same as a stream that never stopped: its buffer held that much ahead); bound generous for a
    # loaded machine, far below the 50 ms rest or anything a keep-alive would add
    assert reached_s - touched_s < 0.1, reached_s - touched_s
    started = [e for e in events(sim) if e["event"] in ("enabled", "stream_started")]
    assert [e["event"] for e in started] == ["enabled", "stream_started"]
    assert started[1]["t_s"] + sim._started - touched_s < 0.05  # the first frame followed the ENABLE at once
    assert wait_for(lambda: abs(sim.amplitude_um_pp - 3.0) < 0.01)
    assert sim.counters.lost_setpoints == 0 and sim.counters.late_setpoints == 0  # a new stream, no gap
    assert driver.counters.idle_wakes == 1 and driver.status()["output"] == "streaming"
    source.set(0.0)  # lift: the plate decays under zero drive, then the host rests it again
    assert wait_for(lambda: driver.counters.idle_rests == 2 and not sim.enabled, timeout=30)
    assert wait_for(lambda: sim.amplitude_um_pp < 1e-3)
    # no trip; and a watchdog only where the host's writer, starved by a loaded machine, sent nothing for
    # longer than the plate waits (it counts each such stall itself): never from resting or waking
    assert sim.fault_counts()["trip"] == 0
    assert sim.fault_counts()["watchdog"] <= driver.counters.send_stalls, driver.counters
    driver.stop()
    assert not sim.enabled


def test_a_plate_that_cut_itself_out_is_never_re_enabled_by_a_touch(plate, connect):
    sim = plate.simulator
    source = Level(3.0)
    driver = connect(plate, source)
    assert wait_for(lambda: abs(sim.amplitude_um_pp - 3.0) < 0.05, timeout=30)
    plate.inject(p.SIM_OVERHEAT, 0)
    assert wait_for(lambda: driver.fault_counts()["overheat"] == 1, timeout=30)
    source.set(0.0)
    pulled_for(source, 2 * IDLE_AFTER_S + 0.1)
    source.set(3.0)  # a touch after the cut
    pulled_for(source, 0.5)
    assert not sim.enabled and sim.amplitude_um_pp < 0.01
    assert driver.counters.idle_wakes == 0
    assert driver.status()["output"] == "cut by the device"
    driver.stop()


def test_the_firmware_output_stage_ticks_only_while_it_has_work():
    sim = PlateSimulator(PROFILE)
    # half a millisecond past the core's first tick: "1 ms" in floating seconds can render one sample short of it
    # (the clock starts at perf_counter's value), which left the tick, and its telemetry, still due
    t = sim._clock + 0.0015
    sim.advance(t)  # the core's first tick: telemetry sent, the next one 20 ms after that tick
    assert sim.next_wake_s(t) == pytest.approx(TELEMETRY_S - 0.0005, abs=1e-4)  # disabled, at rest: only telemetry
    assert sim.next_wake_s(t + 0.015) == pytest.approx(TELEMETRY_S - 0.0155, abs=1e-4)
    sim.receive(p.encode_frame(p.ENABLE, 1, p.enable_payload(True)))
    assert sim.next_wake_s(t) == TICK_S  # enabled: the sample clock runs
    for k in range(20):
        sim.receive(p.encode_frame(p.SETPOINTS, k + 2, p.setpoints_payload(k * 24, RATE_HZ, np.full(24, 0.5))))
        sim.advance(t + (k + 1) * TICK_S)
    assert sim.amplitude_um_pp > 1.0
    sim.receive(p.encode_frame(p.ENABLE, 40, p.enable_payload(False)))
    sim.advance(t + 0.042)
    assert sim.amplitude_um_pp > 0.1 and sim.next_wake_s(t + 0.042) == TICK_S  # disabled, still ringing down
    sim.advance(t + 0.042 + 20 * PROFILE.q / (np.pi * PROFILE.resonance_hz))  # 20 time constants: e^-20 of it
    assert sim.amplitude_um_pp < 1e-6 and sim.next_wake_s(sim._clock) > TICK_S


def test_a_921600_baud_link_streams_a_frame_every_millisecond(plate):
    # 12 kHz in 1 ms frames is 43 000 bytes/s, under half of 921 600 baud (46 080 bytes/s): 12 values a frame,
    # so a touch waits about 1 ms at most for the next one
    sim = plate.simulator
    receive, decoder, counts = sim.receive, p.FrameDecoder(), []

    def tapped(data):
        counts.extend(len(p.parse_setpoints(frame.payload)[2]) for frame in decoder.feed(data)
                      if frame.kind == p.SETPOINTS)
        return receive(data)

    sim.receive = tapped
    driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)  # the default baud rate, 921 600
    driver.start(Level(2.0))
    try:
        assert wait_for(lambda: len(counts) >= 200, timeout=60)
    finally:
        driver.stop()
    assert driver.batch_s == 0.001
    # a batch is pulled once 12 values are due; the writer's wake-up lands a little after, so 12-13 values;
    # 2 ms frames would carry 24 or more, always. A writer woken late (a loaded machine) sends what is due by
    # then, more, in frames of at most 240: so every batch carries 12 or more, and those sent on time fewer
    # than 24 (how many are on time is the machine's load, a benchmark's matter, not this test's)
    sizes = counts[:200]
    batches = [n for before, n in zip([0, *sizes], sizes, strict=False) if before < p.MAX_SETPOINTS_PER_FRAME]
    assert 12 <= min(batches) < 24, sizes  # (frames after a full one are the rest of its batch)
    slow = SerialPlate(plate.path, PROFILE, baudrate=460800)  # half the link would not hold 1 ms frames
    assert slow.batch_s == 0.002
