"""Devices against real parts: the simulator on a real pty, PortAudio through ALSA, WAV files."""

import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import soundfile
from conftest import ROOT, assert_one_line_error, run_cli, serve_plate, start_cli, wait_for
from scipy import signal as sps
from sources import Constant
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.devices.serial.plate import SerialPlate
from ultraglide.devices.sim.plate import PlateSimulator, PlateTruth
from ultraglide.devices.sim.pty_plate import PtyPlate
from ultraglide.devices.urls import parse_device_url

PROFILE = load_profile("sim-plate")


@pytest.fixture
def plate():
    served = serve_plate(PROFILE)
    yield served
    served.stop()



def test_clean_link_streams_at_the_control_rate_with_no_lost_frame(plate):
    driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
    driver.start(Constant(3.0))
    sim = plate.simulator
    # three seconds' worth of setpoints, however long a loaded machine takes to stream them
    assert wait_for(lambda: sim.counters.setpoints >= 0.98 * 3.0 * 12000, timeout=60)
    assert wait_for(lambda: abs(sim.amplitude_um_pp - 3.0) < 0.01)  # the plate follows the setpoint
    driver.stop()
    assert wait_for(lambda: sim.counters.frames_ok == driver.counters.frames_sent)
    # none lost on the link: any the device counts lost, the host skipped after falling behind (a loaded machine)
    assert sim.counters.lost_setpoints == driver.counters.setpoints_skipped and sim.counters.crc_errors == 0
    assert sim.counters.framing_errors == 0
    assert sim.counters.setpoints >= 0.98 * 3.0 * 12000  # every setpoint sent arrived (none lost, above)
    assert not sim.enabled  # zero and disable at the end
    assert wait_for(lambda: sim.amplitude_um_pp < 0.01)


@pytest.mark.parametrize("fault, check", [
    (p.SIM_DROP, lambda sim, drv: sim.counters.lost_setpoints > 0),
    (p.SIM_CORRUPT, lambda sim, drv: sim.counters.crc_errors + sim.counters.framing_errors > 0),
    # a hung device is silent and, once the link's buffer is full, takes nothing: either is how the host notices
    # (whichever comes first: both wait the same time), and every loss of the link is one of them
    (p.SIM_HANG, lambda sim, drv: drv.counters.reconnects >= 1
     and drv.counters.silences + drv.counters.write_timeouts >= drv.counters.disconnects >= 1),
    (p.SIM_DISCONNECT, lambda sim, drv: drv.counters.disconnects >= 1 and drv.counters.reconnects >= 1),
])
def test_injected_faults_are_detected_counted_and_recovered(plate, fault, check):
    driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
    source = Constant(3.0)
    driver.start(source)
    assert wait_for(lambda: driver.telemetry is not None and abs(driver.telemetry.measured_um_pp - 3.0) < 0.05)
    if fault in (p.SIM_HANG, p.SIM_DISCONNECT):  # until the host has noticed: a loaded host's late wakes restart its
        plate.inject(fault, 600.0)  # silence check (they are not the device's silence), so no fixed length is enough
        assert wait_for(lambda: driver.counters.disconnects >= 1, timeout=120), \
            (driver.counters, plate.simulator.counters)
        plate.end_injected()
    else:  # seen by the device once frames come again: a short fault, then its count
        plate.inject(fault, 0.3)
    # detected and counted, and recovered: streaming again with the plate back at its amplitude
    def recovered() -> dict:
        telemetry = driver.telemetry
        return {"detected": check(plate.simulator, driver), "connected": driver.status()["connected"],
                "at its amplitude": telemetry is not None and abs(telemetry.measured_um_pp - 3.0) < 0.05,
                "enabled": plate.simulator.enabled}
    assert wait_for(lambda: all(recovered().values())), (recovered(), driver.counters, plate.simulator.counters)
    pulled = source.pulled
    assert wait_for(lambda: source.pulled > pulled)  # the renderer kept running throughout
    driver.stop()


def test_a_reconnect_with_the_amplitude_loop_asks_for_it_on_a_disabled_device(plate):
    """SET_LOOP is refused while the device is enabled (it may be, after a hang the host took for a lost link): the
    handshake disables before asking, so the first reconnect succeeds and nothing is refused."""
    driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10, amplitude_loop=True)
    driver.start(Constant(3.0))
    assert wait_for(lambda: driver.telemetry is not None and abs(driver.telemetry.measured_um_pp - 3.0) < 0.05)
    plate.inject(p.SIM_HANG, 600.0)  # until the host has noticed (see test_injected_faults_are_detected_...)
    assert wait_for(lambda: driver.counters.disconnects >= 1, timeout=120), (driver.counters, plate.simulator.counters)
    plate.end_injected()
    assert wait_for(lambda: driver.counters.reconnects >= 1 and driver.status()["connected"] and driver.loop_on
                    and plate.simulator.enabled and driver.telemetry is not None  # (None again after a reconnect)
                    and abs(driver.telemetry.measured_um_pp - 3.0) < 0.05)
    driver.stop()
    assert plate.simulator.counters.naks == 0 and plate.simulator.counters.fault_counts[_bad_command()] == 0


def _bad_command() -> int:
    return next(bit for bit, name in p.FAULT_NAMES.items() if name == "bad-command").bit_length() - 1


def test_fault_injection_by_protocol_frame(plate):
    driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)  # the ACK waits on a condition, 10 s at most
    driver.start(Constant(2.0))
    assert wait_for(lambda: plate.simulator.counters.setpoints > 0)  # streaming: a gap can be seen
    driver.command(p.SIM_FAULT, p.sim_fault_payload(p.SIM_DROP, 300))
    assert wait_for(lambda: plate.simulator.counters.lost_setpoints > 0)
    assert plate.simulator.counters.faults_injected == {"drop": 1}
    driver.stop()


def test_watchdog_ramps_to_zero_after_100_ms_of_silence():
    sim = PlateSimulator(PROFILE)
    sim.receive(p.encode_frame(p.ENABLE, 1, p.enable_payload(True)))
    t = sim._clock
    for k in range(50):  # 0.25 s of setpoints at 4 µm, delivered on time (each handled at the time reached)
        sim.receive(p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(k * 60, 12000, np.full(60, 0.5))))
        sim.advance(t + (k + 1) * 0.005)
    assert sim.amplitude_um_pp == pytest.approx(4.0, abs=0.01)
    last_heard = t + 49 * 0.005
    sim.advance(last_heard + 0.09)
    assert sim.amplitude_um_pp > 3.9 and sim.counters.watchdog_trips == 0  # silence shorter than 100 ms
    reports = sim.advance(last_heard + 0.15)
    assert sim.counters.watchdog_trips == 1
    frames = [p.decode_frame(frame[:-1]) for frame in reports]
    faults = [p.parse_telemetry(frame.payload).faults for frame in frames if frame.kind == p.TELEMETRY]
    assert faults and faults[-1] & p.FAULT_WATCHDOG
    sim.advance(last_heard + 0.15 + 0.02 + 8 * PROFILE.time_constant_s)
    assert sim.amplitude_um_pp < 0.01


def test_device_side_limit_rests_an_over_driven_plate():
    """v3: the device's own limiter keeps a plate driven at full scale at its limit (4 of 8 µm, no overdrive
    granted), enabled, never tripping; a plate stronger than its firmware believes (10 µm at full scale)
    overshoots what the limiter lets through and trips, caught on the way up at the sample it crossed."""
    profile = PlateProfile("weak", 25000.0, 200.0, 8.0, 4.0)
    for truth, trips in ((None, False), (PlateTruth(25000.0, 200.0, full_scale_um_pp=10.0), True)):
        sim = PlateSimulator(profile, truth=truth)
        sim.receive(p.encode_frame(p.ENABLE, 1, p.enable_payload(True)))
        t = sim._clock
        for k in range(100):  # full scale: 8 µm wanted on a plate whose limit is 4
            sim.receive(p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(k * 60, 12000, np.ones(60))))
            sim.advance(t + (k + 1) * 0.005)
        assert sim.counters.frames_ok == 101
        if trips:
            assert not sim.enabled and sim.fault_counts()["trip"] == 1
            assert sim.peak_um_pp < 4.0 * 1.02
        else:
            assert sim.enabled and sim.fault_counts()["trip"] == sim.fault_counts()["over-limit"] == 0
            assert sim.amplitude_um_pp == pytest.approx(4.0, abs=1e-3) and sim.peak_um_pp <= 4.0 + 1e-4


def test_a_failing_source_still_rests_the_plate(plate):
    class Failing(Constant):
        def pull(self, n, now_s):
            if self.pulled > 6000:
                raise RuntimeError("renderer crashed")
            return super().pull(n, now_s)

    driver = SerialPlate(plate.path, PROFILE)
    driver.start(Failing(3.0))
    assert wait_for(lambda: not plate.simulator.enabled and driver.counters.errors)
    assert "renderer crashed" in driver.counters.errors[0]
    assert wait_for(lambda: plate.simulator.amplitude_um_pp < 0.01)
    driver.stop()


def test_handshake_failures_are_clear(tmp_path):
    with pytest.raises(DeviceError, match="cannot open serial port"):
        SerialPlate(str(tmp_path / "nothing"), PROFILE).start(Constant())
    master, slave = os.openpty()  # a port with nobody answering
    try:
        with pytest.raises(DeviceError, match="no answer to the handshake"):
            SerialPlate(os.ttyname(slave), PROFILE).start(Constant())
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("url, fragment", [("bluetooth", "unknown device"), ("serial:", "needs a port"),
                                           ("audio?rate=fast", "whole number"), ("audio?latency=soon", "latency"),
                                           ("serial:/dev/ttyACM0?rate=500", "1000..12000"),
                                           ("serial:/dev/ttyACM0?frame_ms=30", "1..20")])
def test_bad_device_urls(url, fragment):
    with pytest.raises(DeviceError, match=fragment):
        parse_device_url(url)


def test_a_serial_plate_can_stream_slower_in_longer_frames(tmp_path):
    from ultraglide.devices.urls import open_device

    device = open_device(f"serial:{tmp_path / 'plate'}?rate=1000&frame_ms=4", PROFILE)  # opened only at start
    assert (device.rate_hz, device.batch_s) == (1000, 0.004)
    with pytest.raises(DeviceError, match="divide the control rate"):
        open_device(f"serial:{tmp_path / 'plate'}?rate=5000", PROFILE)


def test_play_on_serial_against_plate_sim_end_to_end(tmp_path):
    link = tmp_path / "plate"
    server = start_cli("plate-sim", "--link", link, stdout=subprocess.PIPE)
    try:
        banner = server.stdout.readline()
        assert str(link) in banner and "/dev/pts/" in banner
        result = run_cli("play", "grating-1mm", "--device", f"serial:{link}", "--profile", "sim-plate",
                         "--duration-s", "1.0", "--json")
        status = json.loads(result.stdout)
        assert status["setpoints_sent"] >= 12000 and status["disconnects"] == 0 and status["ramps"] == 2
        faults = status["faults"]
        assert set(faults) == set(p.FAULT_NAMES.values())  # every fault by name, with its count over the run
        # a clean run trips no watchdog (v1 reported two: before the host came and after it left), unless
        # this host could not send for longer than the watchdog's timeout (a stalled, overloaded machine)
        assert faults["watchdog"] <= status["send_stalls"]
        assert faults["trip"] == faults["over-limit"] == faults["bad-command"] == faults["overrun"] == 0
        assert set(status["device_faults"]) <= {"underrun", "watchdog"}  # underruns: only from late batches
        # a clean run exits 0; a watchdog (the machine, not the link) is a fault the run owns up to: 3
        assert result.returncode == (3 if faults["watchdog"] else 0), result.stderr
        assert status["report"]["exit_status"] == result.returncode
    finally:
        server.send_signal(signal.SIGINT)
        out, _ = server.communicate(timeout=10)
    assert server.returncode == 128 + signal.SIGINT  # stopped by Ctrl-C, as the shell reports it
    assert "setpoints lost 0" in out.replace(", ", " ") or " 0 setpoints lost" in out


def test_play_to_wav_device_in_real_time(tmp_path):
    """The recording is paced by the clock: it holds the whole 1 s swipe, and no more time than the command
    ran (a loaded machine starts the swipe late and ends it late: the recording is longer, never faster)."""
    out = tmp_path / "live.wav"
    started = time.perf_counter()
    run_cli("play", "grating-2mm", "--device", f"wav:{out}", "--duration-s", "1.0", check=True)
    elapsed = time.perf_counter() - started
    samples, rate = soundfile.read(out)
    window = rate // 1000  # 1 ms: 25 carrier periods
    envelope = np.abs(samples[: len(samples) // window * window]).reshape(-1, window).max(axis=1)
    active = np.flatnonzero(envelope > 0.01)
    swipe_s = (active[-1] - active[0] + 1) / 1000  # from the first touch's vibration to the lift's ramp
    assert rate == 96000 and 1.0 - 0.02 <= swipe_s <= len(samples) / rate <= elapsed, (swipe_s, len(samples), elapsed)
    sox = subprocess.run(["sox", str(out), "-n", "stat"], capture_output=True, text=True)
    assert sox.returncode == 0 and "Maximum amplitude" in sox.stderr


ASOUNDRC = """pcm.!default {{
    type plug
    slave {{ pcm "capture"; format FLOAT_LE; channels 1 }}
}}
pcm.capture {{
    type file
    slave.pcm "null"
    file "{path}"
    format "raw"
}}
"""


AUDIO_SCRIPT = """
import sys, time, numpy as np
from ultraglide.render.engine.sources import EnvelopeSource, offline_stage
from ultraglide.devices.output.stage import OutputStage
from ultraglide.devices.sinks.audio import AudioPlate
from ultraglide.devices.profiles import load_profile
from ultraglide.render.physics.friction_models import ExponentialModel
from ultraglide.render.paths import SwipePath
from ultraglide.render.renderer import Renderer
from ultraglide.textures.library import resolve_texture

def renderer():
    path = SwipePath("straight", 100.0, 0.5, (5.0, 25.0))
    return Renderer(resolve_texture("grating-1mm"), ExponentialModel(), load_profile("sim-plate"), trajectory=path)

reference = renderer()
expected = offline_stage(reference).pull(int((0.5 + reference.tail_s) * 96000) + 9600, None)
np.save(sys.argv[1], expected)
plate = AudioPlate(None, load_profile("sim-plate"), 25000.0)
stage = OutputStage(EnvelopeSource(renderer()), load_profile("sim-plate"), "audio", 96000, 25000.0)
plate.start(stage)  # built for this device, so it plays it as it is
deadline = time.monotonic() + 60
while (not stage.finished or stage.frames < len(expected)) and time.monotonic() < deadline:
    time.sleep(0.01)
plate.stop()
print(plate.rate_hz, plate.callbacks, len(plate.errors))
"""


def test_audio_output_through_real_portaudio_and_alsa(tmp_path):
    """The audio device through real PortAudio and ALSA: what reaches the PCM is what was rendered.

    ALSA's null PCM is not paced (it takes samples as fast as they come), so the source is a
    renderer on a recorded swipe, whose time base is its own sample count: the capture must then
    equal the offline render sample for sample."""
    capture = tmp_path / "capture.raw"
    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=capture))
    result = subprocess.run([sys.executable, "-c", AUDIO_SCRIPT, str(tmp_path / "expected.npy")], cwd=ROOT,
                            capture_output=True, text=True, env={**os.environ, "HOME": str(tmp_path)}, timeout=120)
    assert result.returncode == 0, result.stderr
    rate, callbacks, errors = map(int, result.stdout.split())
    assert rate == 96000 and callbacks > 10 and errors == 0
    captured = np.frombuffer(capture.read_bytes(), dtype="<f4")
    expected = np.load(tmp_path / "expected.npy")
    lag = int(np.argmax(np.correlate(captured[:20000], expected[:4000], "valid")))  # PortAudio's silent prefill
    assert np.all(captured[:lag] == 0)
    played = captured[lag:]
    n = min(len(played), len(expected))
    assert n > 0.5 * 96000
    assert np.max(np.abs(played[:n] - expected[:n])) < 1e-6  # bit-faithful through PortAudio
    spectrum = np.abs(np.fft.rfft(played[12000:60000] * np.hanning(48000)))
    assert np.argmax(spectrum) * 2 == pytest.approx(25000, abs=2)  # 2 Hz bins: the carrier
    envelope = np.abs(sps.hilbert(played[:n].astype(float)))
    assert envelope[:48].max() < 0.5 * np.median(envelope[12000:40000])  # ramps up, no click
    assert np.max(np.abs(played[-960:])) < 1e-3  # at rest when the stream closes


def test_play_on_the_audio_device_from_the_command_line(tmp_path):
    capture = tmp_path / "capture.raw"
    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=capture))
    env = {"HOME": str(tmp_path)}
    listing = json.loads(run_cli("devices", "--json", env=env, check=True).stdout)
    assert any(96000 in output["rates_hz"] for output in listing["audio"])
    status = json.loads(run_cli("play", "grating-1mm", "--device", "audio?latency=0.02&blocksize=256",
                                "--profile", "sim-plate",
                                "--duration-s", "0.3", "--json", env=env, check=True).stdout)
    assert status["rate_hz"] == 96000 and status["errors"] == []
    played = np.frombuffer(capture.read_bytes(), dtype="<f4")
    assert len(played) > 0 and np.max(np.abs(played)) <= 1.0
    assert np.max(np.abs(played[-960:])) < 1e-3  # rests at the end


def test_an_audio_device_with_no_clock_is_held_to_real_time(tmp_path):
    """ALSA's null PCM takes samples as fast as they come (about fifty times real time here): the file behind it
    holds the second played, not fifty, and the run says the device had no clock."""
    capture = tmp_path / "capture.raw"
    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=capture))
    result = run_cli("play", "grating-1mm", "--device", "audio", "--profile", "sim-plate", "--duration-s", "1",
                     env={"HOME": str(tmp_path)}, check=True)
    played_s = float(re.search(r"played ([\d.]+) s", result.stdout).group(1))
    captured_s = capture.stat().st_size / 4 / 96000
    # the lead allowed: twice the latency, 50 ms and 1 %; then the ramp down and the stream's last buffer
    assert 1.0 <= captured_s <= played_s + 0.25, (captured_s, played_s)
    assert "took samples faster than real time (it has no clock of its own" in result.stdout
    held = float(re.search(r"held it to real time \(([\d.]+) s of waiting\)", result.stdout).group(1))
    assert 0.5 <= held <= played_s


def test_audio_refuses_a_rate_that_cannot_carry_the_carrier(tmp_path):
    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=tmp_path / "c.raw"))
    result = run_cli("play", "grating-1mm", "--device", "audio?rate=48000", "--profile", "sim-plate",
                     "--duration-s", "0.2",
                     env={"HOME": str(tmp_path)})
    assert "cannot carry" in assert_one_line_error(result)


def test_a_failed_play_leaves_no_recording_and_no_temporary(tmp_path):
    out = tmp_path / "live.wav"
    result = run_cli("play", "no-such-texture", "--device", f"wav:{out}", "--duration-s", "0.2")
    assert "no texture file or library texture" in assert_one_line_error(result)
    result = run_cli("play", "grating-1mm", "--device", f"wav:{out}", "--carrier-hz", "35000", "--duration-s", "0.2")
    assert "outside" in assert_one_line_error(result)  # fails after the device was opened
    assert list(tmp_path.iterdir()) == []


def test_a_recorder_that_never_started_writes_nothing(tmp_path):
    from ultraglide.devices.sinks.paced import WavRecorder

    recorder = WavRecorder(tmp_path / "never.wav", PROFILE)
    recorder.stop()
    assert list(tmp_path.iterdir()) == []


def test_every_fault_over_a_run_is_counted():
    """Faults injected one after another: the host's counts over the run equal what was injected, and its
    report says each in words with the exit status the worst earns.

    The host's limiter is bound to the device's limit and the device's limiter keeps its drive within it,
    so to reach the device's trip the plate is 25 % stronger than the firmware believes (10 µm p-p at full
    scale, not 8), and a host that re-enables a plate that cut itself out (this one never does: the test
    plays that host with raw frames) asks it for more than its limit: the trip is the last line of defence."""
    plate = PtyPlate(PROFILE, truth=PlateTruth(25000.0, 200.0, full_scale_um_pp=10.0)).start()
    driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
    source = Constant(3.0)
    driver.start(source)
    sim = plate.simulator

    def playing():  # 3 µm of drive makes 3.75 µm on this plate
        t = driver.telemetry
        return t is not None and t.enabled and abs(t.measured_um_pp - 3.75) < 0.05 and driver.status()["connected"]

    assert wait_for(playing)
    for trips in (1, 2, 3):  # three drops of everything the host sends, each until the watchdog trips: the
        plate.inject(p.SIM_DROP, 600.0)  # simulator excuses its own stalls, so on a loaded machine no fixed length
        assert wait_for(lambda n=trips: sim.counters.watchdog_trips >= n, timeout=120)  # is sure to
        plate.end_injected()
        frames = sim.counters.frames_ok  # a frame heard again re-arms the watchdog: only then can a drop trip it
        assert wait_for(lambda f=frames: sim.counters.frames_ok > f and abs(sim.amplitude_um_pp - 3.75) < 0.05
                        and playing())
    driver.send(0x42)  # two frames the device must refuse
    driver.send(p.HEARTBEAT, b"\x01")
    assert wait_for(lambda: driver.counters.naks == 2)
    driver.command(p.SIM_FAULT, p.sim_fault_payload(p.SIM_OVERHEAT))  # cuts and disables the output
    assert wait_for(lambda: driver.telemetry is not None and not driver.telemetry.enabled
                    and driver.status()["output"] == "cut by the device")
    frames = sim.counters.frames_ok
    time.sleep(0.2)
    assert sim.counters.frames_ok - frames <= 2  # the host stopped streaming (a CLEAR_FAULTS may still go)
    driver.command(p.ENABLE, p.enable_payload(True))  # a host that re-enables, and asks 7 µm of a 6 µm plate
    for k in range(10):
        driver.send(p.SETPOINTS, p.setpoints_payload(240 * k, 12000, np.full(240, 7.0 / 8.0)))
    assert wait_for(lambda: driver.telemetry is not None and not driver.telemetry.enabled
                    and driver.fault_counts()["trip"] == 1)
    assert wait_for(lambda: driver.fault_counts() == sim.fault_counts())  # the host has heard it all
    counts = driver.fault_counts()
    # a trip beyond the three is a time the host's frames really stopped for longer than the watchdog's timeout
    assert 3 <= counts["watchdog"] <= 3 + plate.quiet_gaps, (counts, plate.quiet_gaps, driver.counters)
    assert (counts["bad-command"], counts["overheat"], counts["over-limit"], counts["trip"]) == (2, 1, 1, 1), counts
    assert counts["overrun"] == 0 and counts["underrun"] >= 3  # each drop also starved the buffer
    assert wait_for(lambda: driver.telemetry.faults == 0)  # the latched bits were read and cleared
    assert driver.status()["faults"] == counts and set(driver.status()["device_faults"]) >= {
        "watchdog", "bad-command", "overheat", "over-limit", "trip", "underrun"}
    driver.stop()
    plate.stop()
    assert driver.fault_counts() == counts  # the run's total, not the last telemetry frame's
    report = driver.report()
    assert report.exit_status == 5  # the plate cut its output: the worst of what happened
    words = "\n".join(report.lines)
    assert "the plate cut its output at " in words and "overheat" in words
    assert f"the plate raised watchdog {counts['watchdog']} times" in words
    assert "the plate refused 1 frame of command 0x42 (unknown command)" in words
    assert "the plate refused 1 frame of HEARTBEAT (wrong payload length)" in words
    assert "the plate raised trip 1 time" in words and "the plate raised over-limit 1 time" in words


def test_the_sim_device_waits_for_its_plate_however_late_it_answers():
    """The simulated plate is a thread of this process: on a loaded machine its answers come late, but they
    come. Here it reads nothing for 3 s (its own hang injection), past the protocol's 2 s for a plate on a
    port: sim still starts, and plays."""
    from ultraglide.devices.urls import open_device

    device = open_device("sim", PROFILE)
    device.plate.inject(p.SIM_HANG, 3.0)
    started = time.monotonic()
    device.start(Constant(1.0))
    try:
        assert time.monotonic() - started >= 3.0  # it did wait for the plate
        assert wait_for(lambda: device.plate.simulator.amplitude_um_pp > 0.5) and not device.driver.counters.errors
    finally:
        device.stop()


def test_the_sim_device_is_not_lost_when_its_plate_falls_silent_for_a_while():
    """A busy machine holds the simulated plate's threads (its telemetry stops) for longer than a plate on a
    port may fall silent (0.5 s): the plate is this process's, not lost. Here it hangs for 1.5 s mid-stream
    (no telemetry, nothing read); the demo on sim exited 4, 'plate lost ... no telemetry for 0.5 s', on a
    machine at load 13."""
    from ultraglide.devices.urls import open_device

    device = open_device("sim", PROFILE)
    device.start(Constant(1.0))
    try:
        assert wait_for(lambda: device.plate.simulator.amplitude_um_pp > 0.5)
        heard = device.driver.telemetry_frames
        device.plate.inject(p.SIM_HANG, 1.5)
        hung_s = time.monotonic()
        assert wait_for(lambda: device.driver.telemetry_frames > heard + 5 and time.monotonic() - hung_s > 1.5,
                        timeout=60)  # it talks again
        counters = device.driver.counters
        assert counters.silences == 0 and counters.disconnects == 0 and device.driver.status()["connected"]
        assert not counters.errors
    finally:
        device.stop()


def test_devices_says_what_is_known_of_a_serial_port():
    """pyserial describes a port with no USB device behind it as "n/a": the listing says what that means."""
    from ultraglide.apps.commands.devices import port_words

    words = port_words({"url": "serial:/dev/ttyS0", "description": "n/a", "hwid": "n/a"})
    assert "n/a" not in words and "nothing identified" in words and "not USB" in words
    assert port_words({"description": "STM32 Virtual ComPort", "hwid": "USB VID:PID=0483:5740 SER=3"}) == \
        "STM32 Virtual ComPort (USB VID:PID=0483:5740 SER=3)"
    listing = [line for line in run_cli("devices", check=True).stdout.splitlines() if not line.startswith("(")]
    urls = [line.split()[0] for line in listing]
    descriptions_at = {line.index(line.split()[1], len(line.split()[0])) for line in listing}
    assert urls[0] == "sim" and len(descriptions_at) == 1  # one column, however long a port's name
    assert not any(line.rstrip().endswith("n/a") for line in listing)
