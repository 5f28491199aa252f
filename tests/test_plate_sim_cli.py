"""``ultraglide plate-sim`` in a process of its own: its event log, its options, its clean-up on signals;
and the host's one-line refusals and fault summary on the command line."""

import dataclasses
import json
import math
import os
import queue
import re
import select
import signal
import struct
import subprocess
import threading
import time

import pytest
from conftest import assert_one_line_error, run_cli, start_cli, wait_for
from test_devices import Constant
from ultraglide.apps.commands.play import describe_faults
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.serial.plate import SerialPlate

PROFILE = load_profile("sim-plate")


class Server:
    """``ultraglide plate-sim`` in a process of its own; its stdout lines collected by a thread."""

    def __init__(self, *args):
        self.process = start_cli("plate-sim", *args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.lines: queue.SimpleQueue = queue.SimpleQueue()
        self.seen: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.process.stdout:
            self.lines.put(line.rstrip("\n"))

    def wait_line(self, matches, timeout=30.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                continue
            self.seen.append(line)
            if matches(line):
                return line
        raise AssertionError(f"no such line within {timeout} s; saw {self.seen}")

    def finish(self, signum) -> int:
        """Send ``signum`` and wait for the end; its exit status (what it wrote on stderr in ``err``)."""
        self.process.send_signal(signum)
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:  # (seen once beside two hogs, after SIGINT): where was it?
            said = self.process.stacks(self.process.stderr)
            self.kill()
            raise AssertionError(f"plate-sim did not end within 30 s of signal {signum}; its threads:\n{said}") \
                from None
        self.reader.join(timeout=30)  # every line it printed, to the end
        while not self.lines.empty():
            self.seen.append(self.lines.get())
        self.err = self.process.stderr.read()
        return self.process.returncode

    def kill(self):
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(timeout=10)


def test_plate_sim_logs_every_event_as_json_and_removes_its_link_on_sigterm(tmp_path):
    link = tmp_path / "plate"
    server = Server("--link", link, "--json")
    try:
        banner = json.loads(server.wait_line(lambda line: '"serving"' in line))
        assert banner["path"] == str(link) and banner["pty"].startswith("/dev/pts/")
        driver = SerialPlate(str(link), PROFILE, ack_timeout_s=10)
        driver.start(Constant(3.0))
        server.wait_line(lambda line: '"stream_started"' in line)
        assert wait_for(lambda: driver.telemetry is not None and abs(driver.telemetry.measured_um_pp - 3.0) < 0.05)
        driver.command(p.SIM_FAULT, p.sim_fault_payload(p.SIM_DROP, 300))  # silence: the watchdog trips
        server.wait_line(lambda line: '"watchdog"' in line)
        server.wait_line(lambda line: '"stream_started"' in line)  # the drop is over: setpoints arrive again
        assert wait_for(lambda: driver.telemetry is not None and abs(driver.telemetry.measured_um_pp - 3.0) < 0.05)
        driver.command(p.SIM_FAULT, p.sim_fault_payload(p.SIM_OVERHEAT))
        server.wait_line(lambda line: '"overheat"' in line)
        driver.stop()
        server.wait_line(lambda line: '"disconnected"' in line)
        assert server.finish(signal.SIGTERM) == 128 + signal.SIGTERM, server.err  # as a shell reports it
    finally:
        server.kill()
    assert not os.path.lexists(link)  # the pty's symlink went with it
    events = [json.loads(line) for line in server.seen]
    assert all(isinstance(e["t_s"], float) and e["t_s"] >= 0 and isinstance(e["event"], str) for e in events)
    names = [e["event"] for e in events]
    for expected in ("connected", "carrier", "enabled", "stream_started", "watchdog", "stream_stopped", "fault",
                     "disabled", "disconnected", "stopped"):
        assert expected in names, names
    assert next(e for e in events if e["event"] == "carrier")["carrier_hz"] == 25000.0
    assert {"watchdog", "overheat"} <= {e.get("fault") for e in events}
    assert next(e for e in events if e["event"] == "disabled")["reason"] == "overheat"
    assert events[-1]["event"] == "stopped" and events[-1]["faults"]["watchdog"] == 1


def test_plate_sim_speaks_in_words_and_cleans_up_on_sighup(tmp_path):
    link = tmp_path / "plate"
    server = Server("--link", link)
    try:
        assert str(link) in server.wait_line(lambda line: line.startswith("simulated plate"))
        driver = SerialPlate(str(link), PROFILE, ack_timeout_s=10)
        driver.start(Constant(1.0))
        line = server.wait_line(lambda line: "enabled" in line)
        assert re.fullmatch(r"\s*\d+\.\d{3} s  enabled", line), line
        driver.stop()
        server.wait_line(lambda line: "disconnected" in line)
        assert server.finish(signal.SIGHUP) == 128 + signal.SIGHUP, server.err
    finally:
        server.kill()
    assert not os.path.lexists(link)
    assert any(line.startswith("stopped:") and "0 watchdog trips" in line for line in server.seen), server.seen


def test_plate_sim_plays_its_own_resonance_not_the_profiles(tmp_path):
    link = tmp_path / "plate"
    f0, q = 25250.0, 100.0
    server = Server("--link", link, "--json", "--resonance-hz", f0, "--q", q)
    try:
        banner = json.loads(server.wait_line(lambda line: '"serving"' in line))
        assert (banner["resonance_hz"], banner["q"]) == (f0, q)
        driver = SerialPlate(str(link), PROFILE, ack_timeout_s=10)  # believes 25 kHz: drives there
        driver.start(Constant(4.0))
        gain = 1 / math.sqrt(1 + (2 * q * (25000.0 - f0) / f0) ** 2)  # 0.451: two half-bandwidths off
        assert wait_for(lambda: driver.telemetry is not None
                        and driver.telemetry.measured_um_pp == pytest.approx(4.0 * gain, rel=0.01)), driver.telemetry
        driver.stop()
        assert server.finish(signal.SIGINT) == 128 + signal.SIGINT, server.err
    finally:
        server.kill()


def test_a_play_keeps_a_plate_sim_with_a_fast_clock_fed(tmp_path):
    """``plate-sim --clock-ppm 4000``: a plate that plays 4 ms a second more than the host sends. Over a 4 s
    ``play`` that is 16 ms against its 10.5 ms buffer, which without the host's correction runs dry after 2.3-2.6
    s (the plate raises underrun and holds its last value): the host reads the buffer's depth from telemetry and
    moves its lead, and the run's report says it did and why. (Between corrections the buffer runs up to the
    5 ms deadband below its depth, so on a loaded machine a gap of the host's shorter than the 10 ms it counts as
    late may still starve it: seen once in five runs beside QEMU's tests.)"""
    link = tmp_path / "plate"
    server = Server("--link", link, "--json", "--clock-ppm", "4000")
    try:
        assert json.loads(server.wait_line(lambda line: '"serving"' in line))["clock_ppm"] == 4000
        played = run_cli("play", "grating-1mm", "--device", f"serial:{link}", "--profile", "sim-plate",
                         "--duration-s", "4", "--json")
        assert played.returncode == 0, played.stderr
        report = json.loads(played.stdout)
        assert report["depth_corrections"] >= 1, report
        assert any("its clock against the host's" in line for line in report["report"]["lines"]), report["report"]
        assert server.finish(signal.SIGINT) == 128 + signal.SIGINT, server.err
    finally:
        server.kill()


def test_plate_sim_refuses_a_bad_option_in_one_line():
    assert "--q" in assert_one_line_error(run_cli("plate-sim", "--q", "0"))
    assert "ppm" in assert_one_line_error(run_cli("plate-sim", "--clock-ppm", "1e6"))
    assert "QEMU's clock" in assert_one_line_error(run_cli("plate-sim", "--board", "qemu", "--clock-ppm", "50"))


def test_the_host_refuses_a_v1_device_in_one_line():
    master, slave = os.openpty()
    name = os.ttyname(slave)
    stop = threading.Event()

    def old_firmware():  # answers HELLO as a v1 plate driver did
        decoder = p.FrameDecoder()
        while not stop.is_set():
            if not select.select([master], [], [], 0.05)[0]:
                continue
            for frame in decoder.feed(os.read(master, 4096)):
                if frame.kind == p.HELLO:
                    v1 = struct.pack("<BfffI", 1, 25000.0, 8.0, 6.0, 48000) + b"old plate"
                    os.write(master, p.encode_frame(p.HELLO_REPLY, 1, v1))

    thread = threading.Thread(target=old_firmware, daemon=True)
    thread.start()
    try:
        result = run_cli("play", "grating-1mm", "--device", f"serial:{name}", "--profile", "sim-plate",
                         "--duration-s", "0.2")
        line = assert_one_line_error(result)
        assert "speaks protocol v1" in line and "v2" in line and "update the firmware" in line
    finally:
        stop.set()
        thread.join(timeout=5)
        os.close(master)
        os.close(slave)


def test_play_names_the_runs_faults_in_words():
    result = run_cli("play", "grating-1mm", "--duration-s", "0.3", check=True)  # the built-in simulated plate
    (summary,) = [line for line in result.stdout.splitlines() if line.startswith("device faults: ")]
    assert summary == "device faults: none" or "×" in summary
    words = describe_faults({"watchdog": 2, "trip": 0, "underrun": 1})
    assert words == ("device faults: 2 × watchdog trip (no valid frame for 100 ms; output ramped to zero); "
                     "1 × buffer underrun (last value held)")
    assert describe_faults({name: 0 for name in p.FAULT_NAMES.values()}) == "device faults: none"


def test_the_host_refuses_a_carrier_the_device_cannot_make(tmp_path):
    """The carrier range comes in HELLO_REPLY: a carrier outside it is refused before anything is enabled."""
    link = tmp_path / "plate"
    server = Server("--link", link, "--json")
    try:
        server.wait_line(lambda line: '"serving"' in line)
        wide = dataclasses.replace(PROFILE, carrier_max_hz=30000.0)  # the host's profile is wrong
        driver = SerialPlate(str(link), wide, carrier_hz=29000.0, ack_timeout_s=10)
        with pytest.raises(DeviceError, match="outside what the plate driver accepts, 20000-28000 Hz"):
            driver.start(Constant(1.0))
        assert server.finish(signal.SIGINT) == 128 + signal.SIGINT, server.err
    finally:
        server.kill()
    assert "enabled" not in [json.loads(line)["event"] for line in server.seen]


def test_a_link_in_a_missing_directory_is_one_line(tmp_path):
    result = run_cli("plate-sim", "--link", tmp_path / "missing" / "plate", timeout=60)
    line = assert_one_line_error(result)
    assert f"{tmp_path / 'missing'} does not exist" in line and "--link" in line
    assert list(tmp_path.iterdir()) == []


def test_plate_sim_speaks_v2_when_told_and_names_a_rule_it_cannot_break(tmp_path):
    link = tmp_path / "plate"
    server = Server("--link", link, "--json", "--max-version", "2", "--break", "nak-order")
    try:
        banner = json.loads(server.wait_line(lambda line: '"serving"' in line))
        assert (banner["max_version"], banner["breaks"]) == (2, ["R-NAK-ORDER"])
        driver = SerialPlate(str(link), PROFILE, ack_timeout_s=10)
        driver.start(Constant(2.0))  # a v3 host drives a v2 device
        assert driver.device.version == 2 and not driver.device.has_amplitude_loop
        assert wait_for(lambda: driver.telemetry is not None and abs(driver.telemetry.measured_um_pp - 2.0) < 0.05)
        assert driver.telemetry.version == 2
        driver.stop()
        assert server.finish(signal.SIGTERM) == 128 + signal.SIGTERM, server.err
    finally:
        server.kill()
    line = assert_one_line_error(run_cli("plate-sim", "--break", "R-NOTHING", timeout=60))
    assert "no rule 'R-NOTHING' to break" in line and "R-WATCHDOG" in line
