"""The netduinoplus2 board image: its cross build (``ultraglide firmware build``), its budgets, and its runs
under QEMU (``ultraglide plate-sim --board qemu``) with its UART on a real pseudo-terminal: the protocol
answered by the firmware core on the board, a texture played from the host never above the limit (read back
from the firmware's own tap of its link), the watchdog on the board's clock, a plate sweep finding the emulated
plate's resonance; and ``plate check`` passing against it and against the mps2-an386's image. Marked ``qemu`` and
``slow``; skipped where the cross compiler or QEMU is missing (``./run tests`` installs both).

QEMU's USART hands the firmware one byte per round trip between two of its threads (about 14 kB/s measured at
load 12 on this two-core machine; see devices/firmware/qemu.py), so streams here run at 1 000 setpoints/s in 10 ms
frames (3.9 kB/s); the commands run with their defaults, the board stating in its handshake what its link carries
and the host fitting its stream to it (1 000 setpoints/s in 4 ms frames, 6.75 kB/s); one QEMU at a time (a file
lock), since two would share this machine's two cores."""

from __future__ import annotations

import collections
import contextlib
import json
import math
import os
import queue
import random
import re
import select
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
import tty

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli, wait_for
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware.boards import BOARD_INFO, build_images, map_sizes
from ultraglide.devices.firmware.qemu import EmulatedPlate, QemuPlate
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.devices.serial.plate import SerialPlate
from xvfb_demo import XvfbDemo, tools_missing

pytestmark = [
    pytest.mark.slow,
    pytest.mark.qemu,
    pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
                       reason="needs gcc-arm-none-eabi, libnewlib-arm-none-eabi and qemu-system-arm"),
]

RATE = 1000  # setpoints a second the tests stream (the board takes 1 000-48 000)
BATCH_S = 0.01  # ... in 10 ms frames: 39 bytes each, 3.9 kB/s, well within QEMU's emulated USART
NAME = "ultraglide netduinoplus2 (QEMU)"
LINK_BYTES_PER_S = 14000  # what the QEMU image states its emulated USART carries (ports/netduinoplus2/board.h)


@pytest.fixture(scope="module")
def image():
    return build_images("netduinoplus2", ["qemu"])[0]


def elf_sizes(elf: str) -> tuple[int, int]:
    """Flash and RAM bytes from the ELF file's sections as binutils' size lists them (``-A``: name, size,
    address), an independent reading of what the linker map says: flash holds the sections addressed there
    and the initial image of .data; RAM holds every section addressed in SRAM."""
    out = subprocess.run(["arm-none-eabi-size", "-A", elf], capture_output=True, text=True, check=True).stdout
    flash = ram = 0
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[1].isdigit() and parts[2].isdigit():
            name, size, address = parts[0], int(parts[1]), int(parts[2])
            if 0x0800_0000 <= address < 0x0810_0000:
                flash += size
            elif 0x2000_0000 <= address < 0x2002_0000:
                ram += size
                flash += size if name == ".data" else 0
    return flash, ram


def test_firmware_build_prints_each_image_with_the_sizes_binutils_reads(tmp_path):
    result = run_cli("firmware", "build", "-o", tmp_path, "--json", check=True)
    report = json.loads(result.stdout)
    assert [image["variant"] for image in report["images"]] == ["hardware", "qemu"]
    for image in report["images"]:
        assert os.path.dirname(image["elf"]) == str(tmp_path)
        assert (image["flash_bytes"], image["ram_bytes"]) == elf_sizes(image["elf"])
        assert image["stack_bytes"] >= 8192
        with open(image["bin"], "rb") as binary:  # the raw image starts with the vector table: SP then reset PC
            sp, pc = int.from_bytes(binary.read(4), "little"), int.from_bytes(binary.read(4), "little")
        assert 0x2000_0000 < sp <= 0x2002_0000 and sp % 8 == 0
        assert 0x0800_0000 <= pc < 0x0810_0000 and pc & 1  # a Thumb address in flash
    words = run_cli("firmware", "build", "-o", tmp_path, check=True).stdout
    assert re.search(r"hardware\s+\S+hardware\.elf\n\s+flash \d+ bytes", words)


@pytest.mark.parametrize("kind", ["fifo", "device node", "link", "objects folder a file"])
def test_firmware_build_into_a_folder_refuses_what_is_not_its_own_output(tmp_path, kind):
    """``firmware build -o DIR`` writes images, maps and objects under names of its own; one of those names taken
    by a named pipe (the linker would wait on it forever), a device node (it would take the image) or a link (the
    file it points to would be overwritten) is refused in one line, before anything is built, and left as it was."""
    elf = tmp_path / "ultraglide-netduinoplus2-hardware.elf"
    elsewhere = tmp_path / "someone-elses.txt"
    elsewhere.write_text("theirs\n")
    if kind == "fifo":
        os.mkfifo(elf)
    elif kind == "device node":
        if os.geteuid() != 0:
            pytest.skip("mknod needs root")
        os.mknod(elf, 0o666 | stat.S_IFCHR, os.stat("/dev/null").st_rdev)
    elif kind == "link":
        elf.with_suffix(".map").symlink_to(elsewhere)
    else:
        (tmp_path / "qemu").write_text("not a folder\n")
    before = {path.name: path.lstat() for path in tmp_path.iterdir()}
    line = assert_one_line_error(run_cli("firmware", "build", "-o", tmp_path, timeout=120))
    assert "where the build writes" in line and str(tmp_path) in line
    assert {path.name: path.lstat() for path in tmp_path.iterdir()} == before  # nothing made, nothing touched
    assert elsewhere.read_text() == "theirs\n"


def test_map_sizes_reads_sections_where_they_live():
    text = """
.isr_vector     0x08000000      0x188
.text           0x08000188     0x1000
.data           0x20000000       0x10 load address 0x08001188
.bss            0x20000010      0x200 load address 0x08001198
.stack          0x20000210     0x2000 load address 0x08001198
"""
    assert map_sizes(text) == (0x188 + 0x1000 + 0x10, 0x10 + 0x200 + 0x2000, 0x2000)


def test_firmware_build_without_the_cross_compiler_says_what_to_install(tmp_path):
    bare = tmp_path / "bin"
    bare.mkdir()
    for tool in ("make",):
        os.symlink(shutil.which(tool), bare / tool)
    result = run_cli("firmware", "build", "-o", tmp_path / "out", env={"PATH": str(bare)})
    line = assert_one_line_error(result)
    assert "arm-none-eabi-gcc" in line and "gcc-arm-none-eabi" in line


def test_build_cache_is_reused_while_the_sources_stay_the_same(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    first = build_images("netduinoplus2", ["qemu"])[0]
    stamp = os.stat(first.elf_path).st_mtime_ns
    second = build_images("netduinoplus2", ["qemu"])[0]
    assert second.elf_path == first.elf_path and os.stat(second.elf_path).st_mtime_ns == stamp


class Board:
    """``ultraglide plate-sim --board qemu`` in a subprocess."""

    def __init__(self, *args, env=None):
        self.process = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--board", "qemu", *args],
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                                        env={**os.environ, **(env or {})})
        self.first = self.process.stdout.readline()

    def qemu_pids(self) -> list[int]:
        """QEMU processes started by this command (children of its process)."""
        pids = []
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    with open(f"/proc/{entry}/stat") as stat:
                        fields = stat.read().rsplit(")", 1)[1].split()
                    with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                        command = cmdline.read()
                except OSError:
                    continue
                if int(fields[1]) == self.process.pid and b"qemu-system-arm" in command:
                    pids.append(int(entry))
        return pids


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_plate_sim_on_qemu_prints_the_link_first_and_stops_qemu_on_sigterm(one_qemu):
    board = Board("--json")
    try:
        serving = json.loads(board.first)
        assert serving["event"] == "serving" and serving["board"] == "netduinoplus2"
        assert os.path.realpath(serving["path"]) == serving["pty"] and serving["pty"].startswith("/dev/pts/")
        assert wait_for(lambda: board.qemu_pids())
        qemu = board.qemu_pids()[0]
        boot = json.loads(board.process.stdout.readline())
        assert (boot["event"], boot["board"], boot["variant"]) == ("boot", "netduinoplus2", "qemu")
    finally:
        board.process.send_signal(signal.SIGTERM)
        status = board.process.wait(timeout=60)
    assert status == 128 + signal.SIGTERM
    assert not alive(qemu)
    assert not os.path.lexists(serving["path"])
    assert "stopped (SIGTERM)" in board.process.stderr.read()


def test_killing_plate_sim_leaves_no_qemu_behind(one_qemu):
    board = Board()
    assert "on " in board.first
    assert wait_for(lambda: board.qemu_pids())
    qemu = board.qemu_pids()[0]
    board.process.kill()  # SIGKILL: no clean-up runs in the command; the kernel must take QEMU with it
    board.process.wait(timeout=30)
    assert wait_for(lambda: not alive(qemu), timeout=30), "QEMU outlived its parent"


def test_the_emulated_plate_runs_with_the_truth_given_on_the_command_line(one_qemu):
    board = Board("--json", "--resonance-hz", "24000", "--q", "150")
    try:
        assert json.loads(board.first)["resonance_hz"] == 24000
        boot = json.loads(board.process.stdout.readline())
        assert (boot["event"], boot["plate_resonance_hz"], boot["plate_q"]) == ("boot", 24000, 150)  # read back
    finally:
        board.process.send_signal(signal.SIGINT)
        assert board.process.wait(timeout=60) == 128 + signal.SIGINT


@pytest.mark.parametrize("board", ["netduinoplus2", "mps2-an386"])
def test_budgets_count_a_loop_of_known_length_and_the_fastest_stream_plays_whole(one_qemu, board):
    """Each board's budget image (ports/common/bench.c) under -icount shift=0: the netduinoplus2's TIM5 counts every
    instruction, the mps2-an386's TIMER1 (25 MHz PCLK) one count in 40, so its figures are known to 40 either way."""
    from ultraglide.devices.firmware.budgets import BOARD_CORE_HZ, CALIBRATION, RESOLUTION, measure, stream_load

    run = measure(board=board)
    assert (run.boot["board"], run.boot["variant"]) == (board, "bench")  # its boot line says what it is, once
    name, instructions = CALIBRATION
    step = RESOLUTION[board]
    calibration = run.figures[name]
    if step == 1:
        assert calibration.mean == instructions and calibration.max == instructions  # QEMU counts exactly
    else:  # each reading falls anywhere within its count: the calibration within a count of the loop's length
        assert abs(calibration.mean - instructions) <= step and abs(calibration.max - instructions) <= step
    assert run.counters["setpoints"] == 240_000  # four seconds of 48 000 setpoints/s and the parts' 48 000
    assert run.counters["overrun"] == run.counters["late"] == run.counters["lost"] == run.counters["underruns"] == 0
    block = run.figures["block_loop_48"]
    assert 240 * 20 < block.max < 240 * 400  # tens of instructions a DAC sample, not thousands
    load = stream_load(run.figures, "loop_48", core_hz=BOARD_CORE_HZ[board])
    assert load.frames_per_s == 1000 and load.cycles_per_s > 1000 * block.max  # every block and frame counted
    # the longest section with the block interrupt masked, streaming and for a command (ENABLE 0 blanks both DAC
    # halves inside its own), within the bound ug_port.h states and issue 39's aim of 500: for a clock of 40
    # instructions a count, the section's least possible length within the bound and its greatest within the aim
    stated = re.search(r"(\d+) for ENABLE 0", (ROOT / "devices/firmware/include/ug_port.h").read_text())
    commands = run.figures["masked_commands"]
    assert commands.calls >= 3 and 0 < commands.max, commands
    assert commands.max - (step - 1) <= int(stated.group(1)) <= 500 and commands.max + (step - 1) <= 500, commands
    streaming = [figure for key, figure in run.figures.items() if key.startswith("masked_") and figure is not commands]
    assert streaming and all(0 < figure.max and figure.max + (step - 1) <= 500 for figure in streaming), streaming


# ---- the firmware on the board, through the pty -----------------------------------------------------------

class Link:
    """The board's pty opened raw, frames decoded as they come (a reader thread), frames sent by the test."""

    def __init__(self, path: str):
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        self.frames: queue.Queue = queue.Queue()
        self.seq = 0
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        decoder = p.FrameDecoder()
        while not self._stop.is_set():
            if select.select([self.fd], [], [], 0.05)[0]:
                try:
                    data = os.read(self.fd, 4096)
                except OSError:
                    return
                for frame in decoder.feed(data):
                    self.frames.put(frame)

    def send(self, kind: int, payload: bytes = b"") -> int:
        self.seq = (self.seq + 1) & 0xFFFF
        os.write(self.fd, p.encode_frame(kind, self.seq, payload))
        return self.seq

    def expect(self, kinds, timeout: float = 20.0) -> p.Frame:
        """The next frame of one of ``kinds`` (telemetry and sensors in between are dropped)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                frame = self.frames.get(timeout=0.1)
                if frame.kind in kinds:
                    return frame
        raise AssertionError(f"no frame of kind {kinds} within {timeout} s")

    def hello(self, version: int = 3) -> p.HelloReply:
        """HELLO until answered: QEMU's pty passes bytes about a second after it is opened."""
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            self.send(p.HELLO, p.hello_payload(version))
            with contextlib.suppress(AssertionError):
                return p.parse_hello_reply(self.expect((p.HELLO_REPLY,), timeout=1.5).payload)
        raise AssertionError("the board never answered HELLO")

    def answer(self, kind: int, payload: bytes = b"") -> int | None:
        """Send a command; the NAK's reason, or None for its ACK."""
        seq = self.send(kind, payload)
        frame = self.expect((p.ACK, p.NAK))
        if frame.kind == p.ACK:
            assert p.parse_ack(frame.payload) == seq
            return None
        acked, reason = p.parse_nak(frame.payload)
        assert acked == seq
        return reason

    def close(self) -> None:
        self._stop.set()
        self._reader.join(timeout=5)
        os.close(self.fd)


def stats(plate: QemuPlate, condition=lambda s: True, timeout: float = 30.0) -> dict:
    """The board's next statistics line (it prints one a second) that meets ``condition``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(queue.Empty):
            event = plate.events.get(timeout=0.2)
            if event["event"] == "stats" and condition(event):
                return event
    raise AssertionError(f"no statistics line meeting the condition within {timeout} s")


def collect(plate: QemuPlate, until, timeout: float = 30.0) -> list[dict]:
    """The board's events in order, until ``until(events)`` holds."""
    found: list[dict] = []
    deadline = time.monotonic() + timeout
    while not until(found):
        assert time.monotonic() < deadline, f"the board's events within {timeout} s: {found}"
        with contextlib.suppress(queue.Empty):
            found.append(plate.events.get(timeout=0.2))
    return found


def events_of(plate: QemuPlate, name: str, count: int = 1, timeout: float = 30.0) -> list[dict]:
    found = []
    deadline = time.monotonic() + timeout
    while len(found) < count and time.monotonic() < deadline:
        with contextlib.suppress(queue.Empty):
            event = plate.events.get(timeout=0.2)
            if event["event"] == name:
                found.append(event)
    assert len(found) == count, f"{len(found)} '{name}' events of {count} within {timeout} s"
    return found


def test_the_board_answers_with_the_profile_written_into_it_and_reports_on_time(one_qemu, image):
    profile = PlateProfile("qemu-test", 24500.0, 150.0, 10.0, 5.0, max_drive_um_pp=7.0, carrier_min_hz=21000.0,
                           carrier_max_hz=27000.0)
    with QemuPlate(image.elf_path, plate=EmulatedPlate.of(profile)) as plate:
        link = Link(plate.path)
        try:
            reply = link.hello()
            assert (reply.version, reply.resonance_hz, reply.full_scale_um_pp, reply.max_amplitude_um_pp,
                    reply.max_drive_um_pp) == (3, 24500.0, 10.0, 5.0, 7.0)
            assert (reply.carrier_min_hz, reply.carrier_max_hz, reply.min_setpoint_rate_hz,
                    reply.max_setpoint_rate_hz) == (21000.0, 27000.0, 1000, 48000)
            assert (reply.watchdog_ms, reply.buffer_ms, reply.sensors, reply.sensor_rate_hz, reply.features) == \
                (100, 250, p.SENSOR_AMPLITUDE, 1000,
                 p.FEATURE_AMPLITUDE_LOOP | p.FEATURE_LINK_STATED | p.FEATURE_RESET_STATED | p.FEATURE_CLOCK_STATED)
            assert (reply.link_bytes_per_s, reply.q) == (LINK_BYTES_PER_S, 150.0)  # its link, and the plate's Q
            assert (reply.restart_reason, reply.restart_detail) == (p.RESTART_POWER_ON, 1)  # QEMU started it, RAM said
            assert reply.name == NAME
            assert link.hello(version=2).version == 2  # a v2 host gets v2
            assert link.hello(version=3).version == 3
            assert link.answer(p.SIM_FAULT, p.sim_fault_payload(p.SIM_DROP, 10)) == p.NAK_UNSUPPORTED  # a board
            assert link.answer(p.SET_CARRIER, p.carrier_payload(30000.0)) == p.NAK_BAD_VALUE
            assert link.answer(p.SET_CARRIER, p.carrier_payload(24400.0)) is None
            refused = events_of(plate, "fault")[0]
            assert (refused["fault"], refused["command"], refused["reason"]) == \
                ("bad-command", p.SIM_FAULT, "not supported by this device")
            # TELEMETRY 50 times a second and SENSORS with no sample left out, on the board's own clock: the
            # SENSORS samples (1 kHz) number the time between two of them. At rest v3 sends 7.7 kB/s, more than
            # QEMU's USART passes on a heavily loaded machine (a few kB/s): then the core's transmit ring fills
            # and it drops whole frames, counting them. A gap is allowed only when the board's own count says
            # so, and the two seconds measured start again after it.
            first = last = None
            telemetry = 0
            dropped = 0
            deadline = time.monotonic() + 120
            while last is None or last.first_sample - first.first_sample < 2000:
                assert time.monotonic() < deadline, "no two seconds of SENSORS without a dropped frame"
                frame = link.expect((p.TELEMETRY, p.SENSORS))
                if frame.kind == p.SENSORS:
                    sensors = p.parse_sensors(frame.payload)
                    if last is not None and sensors.first_sample != last.first_sample + len(last.samples):
                        counted = stats(plate, lambda s, before=dropped: s["tx_dropped"] > before)
                        dropped = counted["tx_dropped"]  # the board says it dropped frames: measure again
                        first = last = None
                        telemetry = 0
                        continue
                    first, last = first or sensors, sensors
                elif first is not None:
                    telemetry += 1
                    measured = p.parse_telemetry(frame.payload)
                    assert measured.carrier_hz == 24400.0 and not measured.enabled
            seconds = (last.first_sample - first.first_sample) / 1000.0
            assert telemetry / seconds == pytest.approx(p.TELEMETRY_HZ, rel=p.TELEMETRY_TOLERANCE)
        finally:
            link.close()


# The boards' blocks (1 ms: 48 drive samples at 48 kHz, one 1 kHz sensor sample) run by a free-running clock
# (ports/*/board.c): the netduinoplus2's TIM5 counts QEMU's virtual nanoseconds, the mps2-an386's TIMER1 its 25 MHz
# PCLK.
CLOCK_TICKS_PER_BLOCK = {"netduinoplus2": 1_000_000, "mps2-an386": 25_000}
BLOCK_DRIVE = 48


@pytest.mark.parametrize("board", ["netduinoplus2", "mps2-an386"])
def test_clock_replies_say_where_the_board_is_within_its_block(one_qemu, board):
    """Issue 43: each CLOCK_REPLY states, besides the blocks run, the drive samples its ADC took of the block under
    way, read from the board's own clock. 200 requests at random times; for each, the board's console tells the raw
    reading its port took to answer (``ev clock_read``: the clock's count, its count when the next block falls due,
    the blocks run). From those counts the test works out the samples taken past the last block's end (whole ones;
    at most 47, since a block due and not yet run is not yet the core's, and the reply is never ahead): the reply's
    fraction says exactly as many, and its whole samples advance one a block with the board's blocks; and a block
    had seldom fallen due without having run. The requests fell all over the block, so a port that says 0 (as both
    boards did, up to a block behind) fails."""
    image = build_images(board, ["qemu"])[0]
    per_block = CLOCK_TICKS_PER_BLOCK[board]
    pauses = random.Random(43)
    found = []
    with QemuPlate(image.elf_path, machine=BOARD_INFO[board].machine) as plate:
        link = Link(plate.path)
        try:
            assert link.hello().features & p.FEATURE_CLOCK_STATED
            reads = None
            for _ in range(200):
                threading.Event().wait(pauses.uniform(0.0, 0.003))  # a random place in the block, not a wait
                seq = link.send(p.CLOCK)
                reply = p.parse_clock_reply(link.expect((p.CLOCK_REPLY,)).payload)
                assert reply.asked_seq == seq
                read = plate.clock_reads.get(timeout=30.0)
                assert reads is None or read["reads"] == reads + 1  # one reading a request: this one's
                reads = read["reads"]
                found.append((read, reply))
        finally:
            link.close()
    taken, late = [], 0
    for read, reply in found:
        elapsed = (read["ticks"] - (read["due"] - per_block)) % 2**32  # the clock's count past the last block's end
        late += elapsed >= per_block
        taken.append(min(elapsed * BLOCK_DRIVE // per_block, BLOCK_DRIVE - 1))
        stated = reply.fraction * BLOCK_DRIVE / 65536  # the reply's drive samples past its sensor sample
        assert stated <= taken[-1] < stated + 0.01, (read, reply)
    offsets = {(reply.sample - read["blocks"]) % 2**32 for read, reply in found}
    assert len(offsets) == 1, offsets  # a sensor sample a block: the reply's whole samples are the board's blocks
    # the requests fell all over the block (the board's block interrupt takes the first ~0.2 ms of the mps2-an386's
    # blocks, when its main loop cannot answer): a port that says 0 is a quarter of a block behind or more in most
    # and the core had its blocks on time: a block due runs before the core answers (board_run_due_blocks), though
    # QEMU's timer that runs them fires late on a loaded host (without, 27-98 % of the requests found one due)
    assert late <= len(found) // 20, late
    taken = np.array(taken)
    assert len(np.unique(taken)) >= 16 and np.mean(taken >= BLOCK_DRIVE // 4) >= 0.5, np.bincount(taken)


class Recorded:
    """A recorded envelope (µm p-p at ``control_rate_hz``) as a device's source; finished once played."""

    def __init__(self, values: np.ndarray, control_rate_hz: int):
        self.values = values
        self.control_rate_hz = control_rate_hz
        self.at = 0

    def pull(self, n, now_s):
        out = np.zeros(n)
        part = self.values[self.at:self.at + n]
        out[:len(part)] = part
        self.at += n
        return out

    def request_stop(self):
        self.at = max(self.at, len(self.values))

    @property
    def finished(self):
        return self.at >= len(self.values)


def texture_envelope(texture: str, profile: PlateProfile, seconds: float, rate_hz: int) -> np.ndarray:
    """A swipe across ``texture`` rendered by the real renderer (12 kHz), averaged down to ``rate_hz``."""
    from ultraglide.render.engine.sources import EnvelopeSource
    from ultraglide.render.paths import SwipePath
    from ultraglide.render.physics.friction_models import ExponentialModel
    from ultraglide.render.renderer import Renderer
    from ultraglide.textures.library import resolve_texture

    path = SwipePath("straight", 100.0, seconds, (5.0, 25.0))
    source = EnvelopeSource(Renderer(resolve_texture(texture), ExponentialModel(), profile, trajectory=path))
    control = 12000
    blocks = [source.pull(240, None).copy() for _ in range(int(seconds * control) // 240)]
    return np.concatenate(blocks).reshape(-1, control // rate_hz).mean(axis=1)


def test_the_board_plays_a_texture_from_the_host_never_above_the_limit(one_qemu, image):
    profile = PlateProfile("qemu-plain", 25000.0, 200.0, 8.0, 4.0)  # limit 4 of 8 µm p-p, no overdrive
    limit_code = round(4.0 / 8.0 * 65535)
    envelope = texture_envelope("grating-1mm", profile, 3.0, RATE)
    assert envelope.max() == pytest.approx(4.0) and envelope.min() < 1.0  # the renderer held it at the limit
    with QemuPlate(image.elf_path, plate=EmulatedPlate.of(profile)) as plate:
        boot = events_of(plate, "boot")[0]
        assert boot["limit_code"] == limit_code
        driver = SerialPlate(plate.path, profile, control_rate_hz=RATE, batch_s=BATCH_S, ack_timeout_s=20)
        source = Recorded(envelope, RATE)
        driver.start(source)
        assert wait_for(lambda: source.finished, timeout=120)
        driver.stop()
        sent = driver.counters.setpoints_sent

        def accounted(stats: dict) -> int:  # the values the core has taken from its receive ring, each one way
            return stats["setpoints"] + stats["late_setpoints"] + stats["overrun_setpoints"] + \
                stats["discarded_setpoints"]

        # the tap decodes in the UART's interrupt, the core in its main loop: a once-a-second snapshot may catch a
        # last frame between the two, so the wait is for one where the core has taken all the tap saw (a value
        # lost by the core never gives one: the wait fails, with the events)
        seen = collect(plate, lambda events: any(e["event"] == "stats" and e["tap_setpoints"] >= sent
                                                 and accounted(e) >= e["tap_setpoints"] for e in events), timeout=60)
        board = seen[-1]
    # what the board's link received (its own tap: an independent decoder of the bytes USART1 took)
    zeros = board["tap_setpoints"] - sent  # the host's own zero frames (at enable and rest) are not in its count
    assert 0 <= zeros <= 64  # every value the host sent arrived
    assert accounted(board) == board["tap_setpoints"]  # and the core accounted for each once, none twice
    assert board["setpoints"] >= 0.9 * len(envelope)
    assert board["max_setpoint_code"] <= limit_code and board["setpoints_above_limit"] == 0
    assert board["max_setpoint_code"] >= 0.99 * limit_code  # the texture reached the limit: the test means something
    # what the plate did: the board's measurement and the emulated plate's own swing
    assert board["peak_um_pp"] <= 4.0 * 1.005 and board["plate_peak_um_pp"] <= 4.0 * 1.005
    assert board["peak_um_pp"] >= 0.9 * 4.0 * (1 - 1 / math.e)  # it did drive the plate
    assert board["trips"] == board["crc_errors"] == board["naks"] == 0, str(board)
    # A plate held at its limit measures on both sides of it (the ADC's quantisation: 0.04 % rms at 4 µm p-p): the
    # board may raise over-limit, once an excursion, but only within the sensing's tolerance
    over = [e["measured_um_pp"] for e in seen if e["event"] == "fault" and e["fault"] == "over-limit"]
    assert len(over) == board["over_limits"] and all(value <= 4.0 * 1.002 for value in over), over


def test_the_watchdog_ramps_the_plate_down_on_the_boards_clock(one_qemu, image):
    profile = load_profile("sim-plate")
    with QemuPlate(image.elf_path, plate=EmulatedPlate.of(profile)) as plate:
        link = Link(plate.path)
        try:
            link.hello()
            assert link.answer(p.ENABLE, p.enable_payload(True)) is None
            for first in range(0, 400, 10):  # 0.4 s at 1 kHz: 3 µm p-p, then silence
                link.send(p.SETPOINTS, p.setpoints_payload(first, RATE, np.full(10, 3.0 / 8.0)))
                time.sleep(BATCH_S)
            # Every silence ends a stream of SETPOINTS: the board says the stream stopped 50 ms after the last of
            # them and fires its watchdog 100 ms after it (a loaded machine may pause this test long enough
            # for an earlier silence: any will do), both on the board's own clock.
            seen = collect(plate, lambda events: any(event["event"] == "watchdog" for event in events))
            fired = seen[-1]
            stopped = [event for event in seen if event["event"] == "stream_stopped"][-1]
            assert fired["t_s"] - stopped["t_s"] == pytest.approx(0.050, abs=0.0025)
            time.sleep(0.5)  # (only to let the last silence's ramp, 20 ms, end: the frames below are read live)
            while not link.frames.empty():
                link.frames.get()
            telemetry = [p.parse_telemetry(link.expect((p.TELEMETRY,)).payload) for _ in range(3)]
            assert all(t.enabled and t.playback == p.PLAYBACK_PREFILL for t in telemetry)  # still on, at rest
            assert telemetry[-1].measured_um_pp < 0.01 and telemetry[-1].fault_counts[0] >= 1
            assert link.answer(p.ENABLE, p.enable_payload(False)) is None
        finally:
            link.close()


def test_a_plate_sweep_finds_the_emulated_plates_resonance_not_the_profiles(one_qemu, image):
    from ultraglide.devices.characterisation.sweep import TelemetrySweeper, sweep

    believed = load_profile("sim-plate")  # 25 kHz, Q 200
    truth = EmulatedPlate.of(believed, resonance_hz=24800.0, q=150.0)
    with QemuPlate(image.elf_path, plate=truth) as plate:
        driver = SerialPlate(plate.path, believed, control_rate_hz=RATE, batch_s=BATCH_S, carrier_hz=24000.0,
                             ack_timeout_s=20)
        sweeper = TelemetrySweeper(driver, believed)
        sweeper.source.control_rate_hz = RATE  # its steady drive, at the stream's rate
        sweeper.start(24000.0)
        try:
            points, fit = sweep(sweeper, 24000.0, 26000.0, 21, lambda message: None)
        finally:
            sweeper.stop()
    assert fit.resonance_hz == pytest.approx(24800.0, abs=20.0)
    assert fit.q == pytest.approx(150.0, rel=0.1)
    assert fit.peak_um_pp == pytest.approx(8.0, rel=0.03)  # the full scale, from the board's measured amplitude
    assert sweeper.unsettled <= 2


def test_plate_sim_on_qemu_logs_the_boards_events_and_its_counts(one_qemu, tmp_path):
    board = Board("--json", "--link", str(tmp_path / "plate"))
    try:
        serving = json.loads(board.first)
        profile = load_profile("sim-plate")
        driver = SerialPlate(serving["path"], profile, control_rate_hz=RATE, batch_s=BATCH_S, ack_timeout_s=20)
        replies = []
        driver.add_clock_listener(lambda *reply: replies.append(reply))  # CLOCK asked every 50 ms while it streams
        source = Recorded(np.full(RATE, 2.0), RATE)  # a second at 2 µm p-p
        driver.start(source)
        assert wait_for(lambda: source.finished, timeout=120)
        driver.stop()
        sent = driver.counters.setpoints_sent
        lines = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            lines.append(json.loads(board.process.stdout.readline()))
            if lines[-1]["event"] == "disabled":
                break
    finally:
        board.process.send_signal(signal.SIGTERM)
        out, err = board.process.communicate(timeout=60)
    assert board.process.returncode == 128 + signal.SIGTERM
    lines += [json.loads(line) for line in out.splitlines()]
    names = [event["event"] for event in lines]
    for expected in ("boot", "hello", "carrier", "enabled", "stream_started", "stream_stopped", "disabled"):
        assert expected in names, names
    assert len(replies) >= 5 and "clock_read" not in names  # the reading behind each CLOCK reply is the tests'
    assert next(e for e in lines if e["event"] == "stream_started")["rate_hz"] == RATE
    assert next(e for e in lines if e["event"] == "disabled")["reason"] == "host"
    stopped = lines[-1]
    assert stopped["event"] == "stopped" and 0 <= stopped["tap_setpoints"] - sent <= 64
    assert stopped["peak_um_pp"] == pytest.approx(2.0, rel=0.01)  # held at 2 µm p-p long enough to settle


# ---- the host's commands against `plate-sim --board qemu` ------------------------------------------------------

# QEMU's USART passes a few kB/s on a loaded machine (see the module's docstring): the board says so in its
# handshake, and the host streams 1 000 setpoints/s (each the mean of 12 of the renderer's, never above them) in 4 ms
# frames, 6.75 kB/s, with no option given.
FITTED = {"rate_hz": 1000, "frame_ms": 4.0, "bytes_per_s": 6750.0, "link_bytes_per_s": LINK_BYTES_PER_S,
          "chosen_by": "device"}
LOST_BOUND = 0.02  # setpoints the board may count lost or late, as a fraction of those sent: a host or a QEMU
# descheduled on a loaded machine skips ahead rather than send a backlog (the board counts what it skipped)


class ServedBoard:
    """``ultraglide plate-sim --board BOARD --json`` serving ``link`` (``board``: ``qemu``, the netduinoplus2, unless
    given): its lines read as they come (a thread), its closing line once stopped."""

    def __init__(self, link, *args, board: str = "qemu"):
        self.board = board
        self.process = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--board", board, "--json",
                                         "--link", str(link), *map(str, args)], stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True, cwd=ROOT)
        self.lines: queue.Queue = queue.Queue()
        self.seen: collections.Counter = collections.Counter()  # the events read so far, by name
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        try:
            self.serving = self.next("serving")
        except BaseException:  # not served in time: the command and its QEMU go, not left running past the test
            self.process.kill()
            self.process.wait(timeout=60)
            raise
        self.url = f"serial:{self.serving['path']}"  # no options: the link decides the stream

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.put(json.loads(line))

    def next(self, name: str, timeout: float = 60.0) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                event = self.lines.get(timeout=0.2)
                self.seen[event["event"]] += 1
                if event["event"] == name:
                    return event
            assert self.process.poll() is None, self.process.stderr.read()
        raise AssertionError(f"no '{name}' line from plate-sim --board {self.board} within {timeout} s")

    def stop(self) -> dict:
        """SIGTERM; the closing line (the board's counts as of its last statistics line after the stop). The events
        read are counted by name in ``seen``."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        self.process.wait(timeout=60)
        self._reader.join(timeout=10)
        found = None
        while not self.lines.empty():
            event = self.lines.get()
            self.seen[event["event"]] += 1
            found = event if event["event"] == "stopped" else found
        return found


def plain_profile(tmp_path) -> tuple[str, int]:
    """A profile with no overdrive (the drive ceiling is the limit, 4 of 8 µm p-p), and the limit's code."""
    path = tmp_path / "plain.toml"
    path.write_text('name = "plain"\nresonance_hz = 25000.0\nq = 200.0\nfull_scale_um_pp = 8.0\n'
                    'max_amplitude_um_pp = 4.0\ncarrier_min_hz = 20000.0\ncarrier_max_hz = 28000.0\n')
    return str(path), round(4.0 / 8.0 * 65535)


def test_play_on_the_board_with_its_defaults_plays_a_texture_it_receives_never_above_the_limit(one_qemu, tmp_path):
    profile, limit_code = plain_profile(tmp_path)
    board = ServedBoard(tmp_path / "plate", "--profile", profile)  # the board's firmware believes this plate
    try:
        assert board.next("boot")["limit_code"] == limit_code  # the board's own reading of the limit
        # `play TEXTURE --device serial:PATH --duration-s 3`, as the issue has it, and --json to read the run
        result = run_cli("play", "grating-1mm", "--device", board.url, "--duration-s", "3", "--json")
        assert result.returncode == 0, result.stdout + result.stderr
        status = json.loads(result.stdout)
        assert (status["device_name"], status["protocol_version"]) == (NAME, 3)
        assert status["report"]["verdict"] == "clean", status["report"]
        assert status["stream"] == FITTED and "stream: 1000 setpoints/s in 4 ms frames" in status["notes"][-1]
        assert "no --profile or --rig: plate: ultraglide netduinoplus2 (QEMU) (as the plate driver describes it" \
            in result.stderr and "limit 4 µm p-p" in result.stderr  # the plate the board believes, said
        assert status["limit_um_pp"] == 4.0
        # what the board counted lost or late, beyond what the host skipped itself after a stall of its own (a
        # loaded machine: it skips ahead rather than send a backlog, and the board counts the skipped as lost)
        lost = status["device_lost_setpoints"] - status["setpoints_skipped"] + status["device_late_setpoints"]
        figures = {key: status[key] for key in ("device_lost_setpoints", "device_late_setpoints", "setpoints_skipped",
                                                "setpoints_sent", "host_stalls", "late_frames")}
        assert lost <= LOST_BOUND * status["setpoints_sent"], (figures, status["report"]["lines"])
        sent = status["setpoints_sent"]
        assert sent + status["setpoints_skipped"] >= 0.9 * 3 * 1000  # three seconds at 1 000 setpoints/s (what a
        # host stalled by a loaded machine skipped to keep its latency included)
    finally:
        stopped = board.stop()
    assert board.process.returncode == 128 + signal.SIGTERM
    # the board's own tap of its link: every value the host sent arrived (and the host's zeros at enable and
    # rest), none above the limit's code, the highest at it (the texture does reach the limit)
    assert 0 <= stopped["tap_setpoints"] - sent <= 64, stopped
    assert stopped["setpoints_above_limit"] == 0 and stopped["max_setpoint_code"] <= limit_code, stopped
    assert stopped["max_setpoint_code"] >= 0.9 * limit_code, stopped
    assert stopped["plate_peak_um_pp"] <= 4.0 * 1.005 and stopped["trips"] == stopped["crc_errors"] == 0, stopped


@pytest.mark.skipif(bool(tools_missing()), reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
def test_the_demo_on_the_board_with_its_defaults_plays_a_swipe_never_above_the_limit(one_qemu, tmp_path):
    """``demo --device serial:PATH`` with no profile, under Xvfb, a texture swiped with the mouse: the board's own
    tap saw the swipe's setpoints, none above the limit of the plate it describes."""
    profile, limit_code = plain_profile(tmp_path)
    board = ServedBoard(tmp_path / "plate", "--profile", profile)
    try:
        assert board.next("boot")["limit_code"] == limit_code
        with XvfbDemo("--device", board.url) as demo:
            demo.wait_for("^renderer ready", 120)
            demo.xdo("mousemove", 110, 100, "click", 1)  # the gallery's first tile
            demo.wait_for("^frame drawn: texture", 30)
            board.next("enabled", 60)  # the serial driver greeted the board and enabled it
            demo.drag([(x, 300) for x in range(200, 1000, 8)], rate_hz=60.0)
            status = demo.quit(60)
            said = "".join(demo.stdout) + demo.demo.stderr.read()
    finally:
        stopped = board.stop()
    assert status == 0, (said, stopped, dict(board.seen))  # (the board's counts: late blocks, resets ...)
    assert "as the plate driver describes it" in said and "limit 4 µm p-p" in said, said  # its plate, said
    assert stopped["setpoints"] > 0 and stopped["trips"] == 0, stopped
    assert 0.2 * limit_code <= stopped["max_setpoint_code"] <= limit_code, stopped  # the swipe played, bounded
    assert stopped["setpoints_above_limit"] == 0 and stopped["plate_peak_um_pp"] <= 4.0 * 1.005, stopped


def test_latency_on_the_board(one_qemu, tmp_path):
    board = ServedBoard(tmp_path / "plate")
    try:
        board.next("boot")
        result = run_cli("latency", "--device", board.url, "--steps", "20", "--json")  # no profile: the board's
        assert result.returncode == 0, result.stdout + result.stderr
        report = json.loads(result.stdout)
        stream = board.next("stream_started")
    finally:
        stopped = board.stop()
    assert report["steps"] == 20 and report["block_ms"] == pytest.approx(4.0)  # one pull a frame
    # the host's part: at most a frame's wait and the render; the device's: the plate's buffer (its 10 ms prefill)
    # and a frame, as the host keeps it (where QEMU was starved, the board's buffer drifted and the host moved its
    # lead within a 5 ms deadband), for a step that found the plate streaming. One after 50 ms of zeros (a loaded
    # machine's slow rest) woke the plate, which plays the lead sent at once on arrival, and so does a frame a
    # starved host sent after the plate's buffer ran dry: those only within the lead
    assert 0 < report["engine_ms"]["p50"] <= 4.0 + 2.0
    woke = report["steps_from_rest"]
    assert 0 <= woke <= 20 and board.seen["enabled"] >= woke, (report, board.seen)  # the board's own ENABLEs
    deadband_ms = 0.0 if report["depth_corrections"] == 0 else 5.0
    streaming, from_rest = report["device_streaming_ms"], report["device_from_rest_ms"]
    if woke < 20 and report["late_frames"] == 0:
        assert streaming["p50"] == pytest.approx(10.0, abs=2.0 + deadband_ms), report
    for part in (streaming, from_rest, report["device_ms"]):
        assert part is None or 0.0 <= part["p50"] <= 10.0 + 2.0 + deadband_ms, report
    if report["late_frames"]:
        assert any("later than the plate's" in line for line in report["report"]["lines"]), report["report"]
    if report["depth_corrections"]:
        assert any("drifted from its depth" in line for line in report["report"]["lines"]), report["report"]
    assert stream["rate_hz"] == 1000 and stopped["setpoints"] > 0 and stopped["trips"] == 0


def test_plate_sweep_on_the_board_measures_the_emulated_plate(one_qemu, tmp_path):
    board = ServedBoard(tmp_path / "plate", "--resonance-hz", "24800", "--q", "150")  # unlike its profile
    try:
        board.next("boot")
        result = run_cli("plate", "sweep", "--device", board.url,  # no profile: the one the board states
                         "--from-hz", "24000", "--to-hz", "26000",
                         "--steps", "21", "-o", tmp_path / "measured.toml", "--json")
    finally:
        board.stop()
    assert result.returncode == 0, result.stdout + result.stderr
    fit = json.loads(result.stdout)
    measured = load_profile(str(tmp_path / "measured.toml"))
    assert measured.resonance_hz == pytest.approx(24800.0, abs=20.0)
    assert fit["resonance_hz"] == pytest.approx(measured.resonance_hz, abs=0.01)
    assert measured.q == pytest.approx(150.0, rel=0.1)
    assert measured.full_scale_um_pp == pytest.approx(8.0, rel=0.03)  # the emulated plate's gain, read by the ADC
    assert measured.max_amplitude_um_pp == 6.0  # the limit is kept


@pytest.mark.parametrize(("board_option", "board_name"), [("qemu", "netduinoplus2"), ("mps2-an386", "mps2-an386")])
def test_plate_check_passes_against_the_board(one_qemu, tmp_path, board_option, board_name):
    """The host's conformance run (docs/protocol.md) against the firmware core on each emulated board: every rule it
    can check without driving the plate over its limit passes, and the plate itself never moved past 15 % of that
    limit (the one the board states on its debug console as it boots)."""
    board = ServedBoard(tmp_path / "plate", board=board_option)
    try:
        boot = board.next("boot")
        result = run_cli("plate", "check", "--device", board.url, "--json", timeout=600)  # with its defaults
    finally:
        stopped = board.stop()
    assert boot["board"] == board_name
    report = json.loads(result.stdout)
    assert result.returncode == 0, [rule for rule in report["rules"] if rule["verdict"] == "fail"]
    assert report["device"]["name"] == f"ultraglide {board_name} (QEMU)"
    assert report["failed"] == 0 and report["aborted"] is None
    limit = boot["max_amplitude_um_pp"]  # sim-plate's, the image's own emulation block: its handshake says the same
    assert report["device"]["max_amplitude_um_pp"] == pytest.approx(limit, abs=0.001)
    verdicts = {rule["rule"]: rule["verdict"] for rule in report["rules"]}
    assert {rule for rule, verdict in verdicts.items() if verdict != "pass"} <= {"R-OVER-LIMIT", "R-TRIP"}
    assert stopped["plate_peak_um_pp"] <= 0.15 * limit * 1.005 and stopped["trips"] == 0
