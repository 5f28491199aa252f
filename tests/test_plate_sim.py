"""The simulated plate: the firmware core (protocol v3 on the device side) around the plate's physics,
and that nothing stops it.

In-process tests drive :class:`PlateSimulator` with a clock of their own (``advance(now)``; frames are
handled at the time last advanced to), so the time-dependent behaviour is exact; the threaded ones use a
real pty and wait on conditions. The core's rules one by one are in test_firmware_core.py."""

import math
import os
import select
import time
import tty

import numpy as np
import pytest
from conftest import wait_for
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.plate import PlateSimulator, PlateTruth
from ultraglide.devices.sim.pty_plate import PtyPlate

PROFILE = load_profile("sim-plate")  # 25 kHz, Q 200, 8 µm p-p full scale, 6 µm p-p limit
RATE = 12000


class Host:
    """Frames into an in-process simulator with a numbered seq; answers decoded."""

    def __init__(self, sim: PlateSimulator):
        self.sim = sim
        self.seq = 0
        self.index = 0

    def send(self, kind: int, payload: bytes = b"") -> list[p.Frame]:
        self.seq += 1
        return [p.decode_frame(reply[:-1]) for reply in self.sim.receive(p.encode_frame(kind, self.seq, payload))]

    def stream(self, t: float, seconds: float, fraction: float, step: float = 0.002) -> float:
        """Setpoints on time for ``seconds`` from ``t`` (the simulator's clock); returns the end time."""
        n = int(round(step * RATE))
        for _ in range(int(round(seconds / step))):
            self.send(p.SETPOINTS, p.setpoints_payload(self.index, RATE, np.full(n, fraction)))
            self.index += n
            t += step
            self.sim.advance(t)
        return t


def nak_reason(answers: list[p.Frame]) -> int | None:
    assert len(answers) == 1 and answers[0].kind in (p.ACK, p.NAK), answers
    return p.parse_nak(answers[0].payload)[1] if answers[0].kind == p.NAK else None


def events(sim: PlateSimulator) -> list[dict]:
    found = []
    while not sim.events.empty():
        found.append(sim.events.get())
    return found


def test_unknown_and_malformed_frames_get_a_nak_with_its_reason():
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    cases = [
        (p.ENABLE, b"\x02", p.NAK_BAD_VALUE),  # v1 took 2 (or nothing) for "off"
        (p.ENABLE, b"", p.NAK_BAD_LENGTH),
        (0x42, b"", p.NAK_UNKNOWN_TYPE),
        (p.SET_CARRIER, p.carrier_payload(35000.0), p.NAK_BAD_VALUE),
        (p.SET_CARRIER, p.carrier_payload(float("nan")), p.NAK_BAD_VALUE),
        (p.SET_CARRIER, b"\x00\x00", p.NAK_BAD_LENGTH),
        (p.HEARTBEAT, b"\x01", p.NAK_BAD_LENGTH),
        (p.SETPOINTS, p.setpoints_payload(0, RATE, np.ones(4))[:-1], p.NAK_BAD_LENGTH),
        (p.SETPOINTS, p.setpoints_payload(0, 500, np.ones(4)), p.NAK_BAD_VALUE),  # below 1 kHz
        (p.SETPOINTS, p.setpoints_payload(0, RATE, np.ones(241)), p.NAK_BAD_VALUE),
        (p.SIM_FAULT, b"", p.NAK_BAD_LENGTH),  # v1's thread died here, freezing the plate
        (p.SIM_FAULT, p.sim_fault_payload(9, 10), p.NAK_BAD_VALUE),
        (p.SIM_FAULT, p.sim_fault_payload(p.SIM_HANG, 60000), p.NAK_BAD_VALUE),
        (p.CLEAR_FAULTS, b"\x01", p.NAK_BAD_LENGTH),
        (p.SET_LOOP, b"", p.NAK_BAD_LENGTH),  # v3
        (p.SET_LOOP, b"\x02", p.NAK_BAD_VALUE),
        (p.HELLO_REPLY, b"", p.NAK_UNKNOWN_TYPE),  # a device's own message is no command
        # the order of the checks (v3): known, supported, length, value
        (0x42, b"\x07", p.NAK_UNKNOWN_TYPE),
        (p.ENABLE, b"\x05\x05", p.NAK_BAD_LENGTH),  # wrong length and a bad value: the length is checked first
        (p.SETPOINTS, p.setpoints_payload(0, 500, np.ones(300))[:-2], p.NAK_BAD_LENGTH),
    ]
    for kind, payload, reason in cases:
        assert nak_reason(host.send(kind, payload)) == reason, (kind, payload)
    assert not sim.enabled and sim.carrier_hz == PROFILE.resonance_hz  # refused frames changed nothing
    assert sim.counters.frames_ok == len(cases)  # each was a valid frame (and fed the watchdog)
    assert sim.fault_requests == []
    assert sim.fault_counts()["bad-command"] == len(cases) == sim.counters.naks
    assert nak_reason(host.send(p.ENABLE, b"\x01")) is None and sim.enabled
    assert nak_reason(host.send(p.SET_CARRIER, p.carrier_payload(24000.0))) is None and sim.carrier_hz == 24000.0
    assert nak_reason(host.send(p.SET_LOOP, b"\x01")) == p.NAK_BAD_VALUE  # only while disabled
    (hello,) = host.send(p.HELLO, p.hello_payload(2))
    assert p.hello_reply_version(hello.payload) == 2
    assert nak_reason(host.send(p.SET_LOOP, b"\x07")) == p.NAK_UNSUPPORTED  # a v2 session: before the value


def test_hello_negotiates_the_version_and_tells_the_limits():
    sim = PlateSimulator(PROFILE)
    for asked, answered in ((1, 2), (2, 2), (3, 3), (4, 3), (255, 3)):  # the highest not above the host's
        (reply,) = Host(sim).send(p.HELLO, p.hello_payload(asked))
        assert reply.kind == p.HELLO_REPLY and p.hello_reply_version(reply.payload) == answered, asked
    hello = p.parse_hello_reply(reply.payload)
    assert (hello.carrier_min_hz, hello.carrier_max_hz) == (20000.0, 28000.0)
    assert (hello.min_setpoint_rate_hz, hello.max_setpoint_rate_hz) == (1000, 48000)
    assert (hello.watchdog_ms, hello.buffer_ms) == (100, 250) and hello.max_amplitude_um_pp == 6.0
    assert hello.max_drive_um_pp == 8.0 and hello.full_scale_um_pp == 8.0  # the profile's overdrive, v3
    assert (hello.sensors, hello.sensor_rate_hz, hello.has_amplitude_loop) == (p.SENSOR_AMPLITUDE, 1000, True)
    v2 = PlateSimulator(PROFILE, max_version=2)  # a device that speaks only v2 (for the host's v2 path)
    (reply,) = Host(v2).send(p.HELLO, p.hello_payload(3))
    assert p.hello_reply_version(reply.payload) == 2 and len(reply.payload) == 33 + len(v2.name)


def test_setpoints_sent_while_disabled_are_discarded_and_never_replayed():
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(sim._clock, 0.1, 0.5)
    assert sim.amplitude_um_pp == pytest.approx(4.0, abs=0.01)
    host.send(p.ENABLE, p.enable_payload(False))
    for _ in range(10):  # 240 setpoints at 90 % while disabled
        host.send(p.SETPOINTS, p.setpoints_payload(host.index, RATE, np.full(24, 0.9)))
        host.index += 24
    assert sim.counters.discarded_setpoints == 240
    host.send(p.ENABLE, p.enable_payload(True))
    sim.advance(t + 0.05)  # 50 ms enabled with nothing new sent: the plate rests
    assert sim.amplitude_um_pp < 1e-3 and sim.peak_um_pp < 4.01


def test_lost_and_late_setpoints_are_counted_by_index():
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    frame = lambda first, n: host.send(p.SETPOINTS, p.setpoints_payload(first, RATE, np.full(n, 0.1)))  # noqa: E731
    frame(1000, 24)  # the first frame after enable starts the stream wherever it starts
    frame(1024, 24)
    frame(1108, 24)  # 60 values never arrived
    assert sim.counters.lost_setpoints == 60 and sim.counters.late_setpoints == 0
    frame(1108, 24)  # repeated: all late
    frame(1122, 24)  # 10 behind: 10 late, 14 kept
    assert sim.counters.late_setpoints == 34 and sim.counters.setpoints == 24 * 3 + 14
    frame(0xFFFFFFF0 + 0, 24)  # far behind (wrapping arithmetic): late, all of it
    assert sim.counters.late_setpoints == 58 and sim.counters.lost_setpoints == 60


def test_the_watchdog_is_armed_only_while_enabled():
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    t0 = sim._clock
    sim.advance(t0 + 1.0)  # powered, nobody talking: not a fault
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(t0 + 1.0, 0.2, 0.5)
    host.send(p.ENABLE, p.enable_payload(False))
    sim.advance(t + 1.0)  # the host finished and went away
    assert sim.counters.watchdog_trips == 0 and sim.fault_counts()["watchdog"] == 0
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(t + 1.0, 0.1, 0.5)
    sim.advance(t + 0.2)  # enabled and silent: one trip
    assert sim.fault_counts()["watchdog"] == 1 and sim.amplitude_um_pp < 0.01


def test_faults_latch_until_cleared_and_every_one_is_counted():
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    t = sim._clock
    for _ in range(2):  # two starvations: 30 ms of stream, then 30 ms of nothing
        t = host.stream(t, 0.03, 0.2)
        t += 0.03
        sim.advance(t)
    assert sim.fault_counts()["underrun"] == 2
    for _ in range(3):  # read any number of times: still latched
        assert sim.telemetry().faults == p.FAULT_UNDERRUN
    assert nak_reason(host.send(p.CLEAR_FAULTS, p.clear_faults_payload(p.FAULT_WATCHDOG))) is None
    assert sim.telemetry().faults == p.FAULT_UNDERRUN  # other bits stay
    host.send(p.CLEAR_FAULTS, p.clear_faults_payload(p.FAULT_UNDERRUN))
    telemetry = p.parse_telemetry(p.telemetry_payload(sim.telemetry()))
    assert telemetry.faults == 0 and telemetry.counts_by_name()["underrun"] == 2  # cleared, still counted


def test_the_devices_limiter_holds_its_plate_at_the_limit():
    """v3: the device's limit binds. Codes above the limit's share of full scale settle at the limit, not above:
    no over-limit, no trip (v2 let the plate go to 6.03 µm, and trip at full scale)."""
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(sim._clock, 0.05, 6.03 / 8.0)
    t = host.stream(t, 0.05, 1.0)
    assert sim.enabled and sim.amplitude_um_pp == pytest.approx(6.0, abs=1e-3) and sim.peak_um_pp <= 6.0 + 1e-4
    assert sim.fault_counts()["over-limit"] == 0 and sim.fault_counts()["trip"] == 0
    assert sim.telemetry().drive_code == 49151  # round(6 / 8 × 65535): the limit's code


def test_over_limit_then_trip_on_the_measured_amplitude():
    """A plate stronger than its firmware believes (8.04 and 8.8 µm p-p at full scale, not 8): the limiter's
    6 µm of drive makes 6.03 µm (over the limit, under the trip), or 6.6 µm (tripped at the sample it crossed)."""
    sim = PlateSimulator(PROFILE, truth=PlateTruth(25000.0, 200.0, full_scale_um_pp=8.04))
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    host.stream(sim._clock, 0.05, 1.0)
    assert 6.0 < sim.amplitude_um_pp < 6.06 and sim.enabled
    assert sim.fault_counts()["over-limit"] == 1 and sim.fault_counts()["trip"] == 0
    strong = PlateSimulator(PROFILE, truth=PlateTruth(25000.0, 200.0, full_scale_um_pp=8.8))
    host = Host(strong)
    host.send(p.ENABLE, p.enable_payload(True))
    host.stream(strong._clock, 0.05, 1.0)
    assert not strong.enabled and strong.fault_counts() == {
        "watchdog": 0, "trip": 1, "over-limit": 1, "overrun": 0, "underrun": 0, "bad-command": 0, "overheat": 0}
    assert strong.peak_um_pp <= 6.0 * 1.01 + 0.005  # cut at the sample it crossed (rising 0.7 nm a sample there)


def test_an_underrun_never_holds_an_overdrive_above_the_limit():
    """The host may overdrive briefly (pre-compensation); if the stream then runs dry, the held value is
    capped at the steady limit's share of full scale, so the plate settles at the limit, not at full scale."""
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(sim._clock, 0.05, 3.0 / 8.0)
    t = host.stream(t, 0.001, 1.0, step=0.001)  # 1 ms at full scale (8 µm p-p): 4.65 µm, then nothing more
    for _ in range(40):  # 40 ms starved: 16 time constants of this plate
        t += 0.001
        sim.advance(t)
    assert sim.fault_counts()["underrun"] == 1
    assert sim.fault_counts()["over-limit"] == 0 and sim.fault_counts()["trip"] == 0 and sim.enabled
    assert 5.9 < sim.amplitude_um_pp <= 6.0  # held at the limit (6 µm p-p), not at the 8 µm burst


def test_the_plates_truth_is_a_detuned_drifting_resonator():
    f0, q = 25062.5, 100.0  # not the profile's 25 kHz and Q 200
    sim = PlateSimulator(PROFILE, truth=PlateTruth(f0, q))
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    host.send(p.SET_CARRIER, p.carrier_payload(25000.0))
    t = host.stream(sim._clock, 0.1, 0.5)
    gain = 1 / math.sqrt(1 + (2 * q * (25000.0 - f0) / f0) ** 2)  # 0.895: detuned by f0 / 4Q
    steady = sim.amplitude_um_pp
    assert steady == pytest.approx(4.0 * gain, rel=1e-3)
    host.send(p.ENABLE, p.enable_payload(False))  # the drive stops at once; the envelope decays with tau
    sim.advance(t + 0.005)
    alpha = math.exp(-1 / (RATE * q / (math.pi * f0)))  # per sample, tau = Q / (pi f0) = 1.27 ms
    # 60 samples, give or take the one that floating-point time and the owed fraction may shift
    assert steady * alpha ** 61 <= sim.amplitude_um_pp <= steady * alpha ** 59
    (hello,) = host.send(p.HELLO, p.hello_payload())
    assert p.parse_hello_reply(hello.payload).resonance_hz == PROFILE.resonance_hz  # what the host is told

    drifting = PlateSimulator(PROFILE, truth=PlateTruth(25000.0, 200.0, drift_hz_per_s=125.0))
    host = Host(drifting)
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(drifting._started + 0.5, 0.1, 0.5)
    f0_now = 25000.0 + 125.0 * (t - drifting._started)  # 25 075 Hz after 0.6 s
    assert drifting.amplitude_um_pp == pytest.approx(4.0 / math.sqrt(1 + (400 * (25000.0 - f0_now) / f0_now) ** 2),
                                                     rel=0.01)
    assert drifting.amplitude_um_pp < 0.7 * 4.0  # it has drifted well off the carrier


def test_defaults_are_the_profiles_resonance():
    sim = PlateSimulator(PROFILE)
    assert sim.truth == PlateTruth(25000.0, 200.0, 0.0, None, 0.0)
    host = Host(sim)
    host.send(p.ENABLE, p.enable_payload(True))
    host.stream(sim._clock, 0.1, 0.5)
    assert sim.amplitude_um_pp == pytest.approx(4.0, abs=1e-3)


def test_events_name_what_happened():
    sim = PlateSimulator(PROFILE)
    host = Host(sim)
    host.send(p.HELLO, p.hello_payload())
    host.send(p.SET_CARRIER, p.carrier_payload(25100.0))
    host.send(p.ENABLE, p.enable_payload(True))
    t = host.stream(sim._clock, 0.02, 0.3)
    sim.advance(t + 0.2)  # silence: watchdog, the stream stops
    host.send(p.SIM_FAULT, p.sim_fault_payload(p.SIM_OVERHEAT))
    seen = events(sim)
    names = [e["event"] for e in seen]
    for expected in ("hello", "carrier", "enabled", "stream_started", "watchdog", "stream_stopped", "fault",
                     "disabled"):
        assert expected in names, names
    assert next(e for e in seen if e["event"] == "carrier")["carrier_hz"] == 25100.0
    faults = [e["fault"] for e in seen if e["event"] == "fault"]
    assert faults == ["underrun", "overheat"]  # the buffer ran dry when the stream stopped, then the overheat
    assert all(isinstance(e["t_s"], float) for e in seen)


# ---- nothing stops it: frames with valid CRCs and any payload (hypothesis) ----------------------------

def command_frames():
    """Frames of every command: mostly well-formed with values in and out of range, some with any payload."""
    either = lambda likely, anything: st.one_of(likely, anything)  # noqa: E731
    structured = st.one_of(
        st.builds(lambda f: (p.SET_CARRIER, p.carrier_payload(f)),
                  either(st.floats(19000, 29000), st.floats(width=32))),
        st.builds(lambda b: (p.ENABLE, bytes([b])), either(st.sampled_from([0, 1, 1, 1]), st.integers(0, 255))),
        st.builds(lambda first, rate, codes: (p.SETPOINTS, p.setpoints_payload(first, rate, np.array(codes))),
                  either(st.integers(0, 2000), st.integers(0, 0xFFFFFFFF)),
                  either(st.sampled_from([12000, 1000, 48000]), st.integers(0, 60000)),
                  st.lists(st.floats(-0.5, 1.5), max_size=300)),
        st.builds(lambda kind, ms: (p.SIM_FAULT, p.sim_fault_payload(kind, ms)),
                  either(st.sampled_from(sorted(p.SIM_FAULT_KINDS)), st.integers(0, 255)),
                  either(st.integers(0, 400), st.integers(0, 0xFFFF))),
        st.builds(lambda mask: (p.CLEAR_FAULTS, p.clear_faults_payload(mask)), st.integers(0, 0xFFFF)),
        st.builds(lambda v: (p.HELLO, bytes([v])), st.integers(0, 255)),
        st.builds(lambda v: (p.SET_LOOP, bytes([v])), either(st.sampled_from([0, 1]), st.integers(0, 255))),
        st.just((p.HEARTBEAT, b"")),
    )
    raw = st.tuples(st.one_of(st.sampled_from(p.HOST_COMMANDS), st.integers(0, 255)), st.binary(max_size=600))
    return st.lists(st.tuples(st.one_of(structured, structured, raw), st.integers(0, 0xFFFF)), max_size=30)


def fuzz_wire(frames) -> bytes:
    wire = b""
    for (kind, payload), seq in frames:
        if len(payload) <= 600:  # within MAX_BODY
            wire += p.encode_frame(kind, seq, payload)
    return wire


def assert_answers_and_rests(sim: PlateSimulator) -> None:
    """It answers HELLO, and with the output on and the host silent, the watchdog rests the plate."""
    host = Host(sim)
    (reply,) = host.send(p.HELLO, p.hello_payload())
    assert reply.kind == p.HELLO_REPLY
    t = max(sim._clock, time.perf_counter())
    while sim.status().stage_hot:  # an injected overheat lasts up to 5 s of the simulator's time
        t += 0.5
        sim.advance(t)
    host.send(p.SET_CARRIER, p.carrier_payload(PROFILE.resonance_hz))
    host.send(p.ENABLE, p.enable_payload(False))
    host.send(p.SET_LOOP, b"\x00")  # fuzzed frames may have turned the loop on
    host.send(p.ENABLE, p.enable_payload(True))
    trips = sim.fault_counts()["watchdog"]
    t = host.stream(t + 0.01, 0.1, 0.4)
    assert sim.amplitude_um_pp == pytest.approx(3.2, abs=0.01)
    sim.advance(t + 0.2)
    assert sim.fault_counts()["watchdog"] == trips + 1 and sim.amplitude_um_pp < 0.01


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(frames=command_frames())
def test_fuzzed_frames_never_stop_the_simulator(frames):
    sim = PlateSimulator(PROFILE)
    replies = sim.receive(fuzz_wire(frames))
    for reply in replies:  # every answer is a well-formed frame naming a known message
        assert p.decode_frame(reply[:-1]).kind in (p.HELLO_REPLY, p.ACK, p.NAK, p.CLOCK_REPLY)  # (telemetry comes
        # with time)
    assert sim.counters.handler_errors == 0
    sim.advance()
    assert_answers_and_rests(sim)


class PtyHost:
    """The test's side of a PtyPlate's port: raw bytes, frames decoded, reopened if the port was re-created."""

    def __init__(self, plate: PtyPlate):
        self.plate = plate
        self.fd = -1
        self.seq = 100
        self.decoder = p.FrameDecoder()
        self.reopen()

    def reopen(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
        deadline = time.monotonic() + 10
        while True:
            try:
                self.fd = os.open(self.plate.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.01)
        tty.setraw(self.fd)
        self.name = self.plate.pty_name

    def write(self, data: bytes, timeout: float = 1.0) -> None:
        """Write what the port takes within ``timeout`` (a hung or vanished plate takes nothing)."""
        deadline = time.monotonic() + timeout
        while data and time.monotonic() < deadline:
            select.select([], [self.fd], [], 0.05)
            try:
                data = data[os.write(self.fd, data):]
            except BlockingIOError:
                continue
            except OSError:
                return  # the port went away (an injected disconnect): the caller retries

    def wait_for(self, want, timeout: float) -> p.Frame | None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.fd], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self.fd, 65536)
            except OSError:
                return None
            for frame in self.decoder.feed(data):
                if want(frame):
                    return frame
        return None

    def command(self, kind: int, payload: bytes, timeout: float = 1.0) -> p.Frame | None:
        self.seq = (self.seq + 1) & 0xFFFF
        seq = self.seq
        self.write(p.encode_frame(kind, seq, payload))
        return self.wait_for(lambda f: f.kind in (p.ACK, p.NAK) and f.payload[:2] == seq.to_bytes(2, "little"),
                             timeout)

    def recover(self) -> None:
        """End injected faults and get an answer again (an injected drop or corruption may eat a try)."""
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            self.plate.end_injected()
            if self.plate.pty_name != self.name or self.plate._master < 0:
                time.sleep(0.01)
                self.reopen()
            if self.command(p.CLEAR_FAULTS, p.clear_faults_payload(0)) is not None:
                # the fuzz's own fault requests were read with or before this frame, and acted on before its ACK
                self.plate.end_injected()
                return
        raise AssertionError("the simulated plate stopped answering")


def answers_hello(host: PtyHost, timeout: float = 60.0) -> bool:
    """The simulator answers HELLO once the injected faults are over. An injection read just after the
    recovery (a disconnect re-opens the pty, a drop eats a frame) may still swallow one HELLO: ask again."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        host.recover()
        host.write(p.encode_frame(p.HELLO, 1, p.hello_payload()))
        if host.wait_for(lambda f: f.kind == p.HELLO_REPLY, 5) is not None:
            return True
    return False


@pytest.mark.slow
def test_fuzzed_frames_through_the_real_pty_never_stop_its_threads():
    plate = PtyPlate(PROFILE).start()
    try:
        host = PtyHost(plate)

        @settings(max_examples=100, deadline=None, suppress_health_check=list(HealthCheck))
        @given(frames=command_frames())
        def fuzz(frames):
            host.write(fuzz_wire(frames))
            assert answers_hello(host)
            assert plate.alive

        fuzz()
        # the watchdog still works, on its own thread: on, a stream, then silence
        sim = plate.simulator
        trips = sim.fault_counts()["watchdog"]
        deadline = time.monotonic() + 30
        while sim.status().stage_hot and time.monotonic() < deadline:  # an injected overheat lasts up to 5 s (v3)
            host.wait_for(lambda frame: False, 0.1)  # reading meanwhile: a full pty drops what the plate sends
        assert host.command(p.ENABLE, p.enable_payload(False), 10) is not None
        assert host.command(p.ENABLE, p.enable_payload(True), 10).kind == p.ACK
        for k in range(100):
            host.write(p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(24 * k, RATE, np.full(24, 0.4))))
            time.sleep(0.002)
        assert wait_for(lambda: sim.fault_counts()["watchdog"] > trips and sim.amplitude_um_pp < 0.01)
        assert sim.peak_um_pp > 0  # it did play
        assert plate.alive and sim.counters.handler_errors == 0
    finally:
        plate.stop()



def test_a_hung_frame_handler_still_rests_the_plate():
    plate = PtyPlate(PROFILE).start()
    try:
        host = PtyHost(plate)
        assert host.command(p.ENABLE, p.enable_payload(True), 10) is not None
        sim = plate.simulator
        for k in range(50):
            host.write(p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(24 * k, RATE, np.full(24, 0.5))))
            time.sleep(0.002)
        assert wait_for(lambda: sim.amplitude_um_pp > 1.0)
        host.command(p.SIM_FAULT, p.sim_fault_payload(p.SIM_HANG, 5000), 10)
        hung_until = time.monotonic() + 5.0
        for k in range(50, 500):  # the host keeps streaming; the handler reads none of it
            if sim.amplitude_um_pp < 0.01 or time.monotonic() > hung_until - 1:
                break
            host.write(p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(24 * k, RATE, np.full(24, 0.5))))
            time.sleep(0.002)
        assert time.monotonic() < plate._hang_until  # still hung
        assert wait_for(lambda: sim.fault_counts()["watchdog"] == 1 and sim.amplitude_um_pp < 0.01,
                          plate._hang_until - time.monotonic())
    finally:
        plate.stop()


class SteadyPress:
    """A finger that presses 0.5 N and drags with 0.2 N per µm p-p of the plate's amplitude (a ForceSource)."""

    def __init__(self):
        self.calls = []

    def forces(self, t_s, amplitude_um_pp):
        self.calls.append((t_s, len(amplitude_um_pp)))
        return np.full(len(amplitude_um_pp), 0.5), 0.2 * np.asarray(amplitude_um_pp)


def test_a_finger_on_the_plate_reaches_the_host_in_sensors_frames():
    """The SIL's force inputs: a ForceSource's blocks go to the core beside the measured amplitude, and come
    out in SENSORS frames, averaged over each 1 ms sensor sample."""
    finger = SteadyPress()
    sim = PlateSimulator(PROFILE, finger=finger)
    host = Host(sim)
    (reply,) = host.send(p.HELLO, p.hello_payload())
    hello = p.parse_hello_reply(reply.payload)
    assert hello.sensors == p.SENSOR_AMPLITUDE | p.SENSOR_NORMAL_FORCE | p.SENSOR_LATERAL_FORCE
    host.send(p.ENABLE, p.enable_payload(True))
    t = sim._clock
    frames = []
    for k in range(100):
        host.send(p.SETPOINTS, p.setpoints_payload(12 * k, RATE, np.full(12, 0.25)))
        t += 0.001
        frames += [p.decode_frame(f[:-1]) for f in sim.advance(t)]
    samples = np.concatenate([p.parse_sensors(f.payload).samples for f in frames if f.kind == p.SENSORS])
    # 100 ms of 1 ms sensor samples, less the frame still filling (one 10 ms period) and the sample in progress,
    # however the frames' phase falls against the test's first millisecond
    assert len(samples) >= 100 - 10 - 1
    assert samples["normal_force_n"] == pytest.approx(np.full(len(samples), 0.5), abs=1e-6)
    late = samples[-20:]
    assert late["amplitude_um_pp"] == pytest.approx(np.full(20, 2.0), abs=1e-3)  # 0.25 of 8 µm, settled
    assert late["lateral_force_n"] == pytest.approx(0.2 * late["amplitude_um_pp"], rel=1e-5)
    assert finger.calls[0][0] >= 0 and all(b[0] > a[0] for a, b in zip(finger.calls, finger.calls[1:], strict=False))


def test_quiet_gaps_count_the_hosts_silences_while_enabled_and_nothing_else():
    """``PtyPlate.quiet_gaps``: a silence from the host longer than the watchdog's timeout while the output is
    enabled is one; a silence while disabled, or one an injected drop made, is none."""
    plate = PtyPlate(PROFILE).start()
    try:
        host = PtyHost(plate)
        sim = plate.simulator

        def stream(first: int) -> None:
            for k in range(first, first + 20):
                host.write(p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(24 * k, RATE, np.full(24, 0.4))))

        assert host.command(p.ENABLE, p.enable_payload(True), 10).kind == p.ACK
        stream(0)
        assert wait_for(lambda: sim.fault_counts()["watchdog"] == 1)  # the host fell silent: a trip
        assert plate.quiet_gaps == 0  # not yet heard again
        assert host.command(p.CLEAR_FAULTS, p.clear_faults_payload(0), 10) is not None
        assert plate.quiet_gaps == 1
        assert host.command(p.ENABLE, p.enable_payload(False), 10).kind == p.ACK
        host.wait_for(lambda frame: False, 0.3)  # silent 0.3 s while disabled (reading what the plate sends)
        assert host.command(p.ENABLE, p.enable_payload(True), 10).kind == p.ACK
        assert plate.quiet_gaps == 1
        stream(20)
        plate.inject(p.SIM_DROP, 600.0)  # an injected drop's silence trips the watchdog too, but is not the host's
        stream(40)
        assert wait_for(lambda: sim.fault_counts()["watchdog"] == 2)
        plate.end_injected()
        assert host.command(p.CLEAR_FAULTS, p.clear_faults_payload(0), 10) is not None
        assert plate.quiet_gaps == 1 and sim.counters.watchdog_trips == 2
    finally:
        plate.stop()
