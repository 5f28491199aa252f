"""The netduinoplus2 board image: its cross build (``ultraglide firmware build``) and its runs under QEMU
(``ultraglide plate-sim --board qemu``), with its UART on a real pseudo-terminal. Marked ``qemu`` and
``slow``; skipped where the cross compiler or QEMU is missing (``./run tests`` installs both)."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys

import pytest
from conftest import ROOT, assert_one_line_error, run_cli, wait_for
from ultraglide.devices.firmware.boards import build_images, map_sizes

pytestmark = [
    pytest.mark.slow,
    pytest.mark.qemu,
    pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
                       reason="needs gcc-arm-none-eabi, libnewlib-arm-none-eabi and qemu-system-arm"),
]


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


def test_plate_sim_on_qemu_prints_the_link_first_and_stops_qemu_on_sigterm():
    board = Board("--json")
    try:
        serving = json.loads(board.first)
        assert serving["event"] == "serving" and serving["board"] == "netduinoplus2"
        assert os.path.realpath(serving["path"]) == serving["pty"] and serving["pty"].startswith("/dev/pts/")
        assert wait_for(lambda: board.qemu_pids())
        qemu = board.qemu_pids()[0]
        boot = json.loads(board.process.stdout.readline())
        assert boot["event"] == "boot"
    finally:
        board.process.send_signal(signal.SIGTERM)
        status = board.process.wait(timeout=60)
    assert status == 128 + signal.SIGTERM
    assert not alive(qemu)
    assert not os.path.lexists(serving["path"])
    assert "stopped (SIGTERM)" in board.process.stderr.read()


def test_killing_plate_sim_leaves_no_qemu_behind():
    board = Board()
    assert "on " in board.first
    assert wait_for(lambda: board.qemu_pids())
    qemu = board.qemu_pids()[0]
    board.process.kill()  # SIGKILL: no clean-up runs in the command; the kernel must take QEMU with it
    board.process.wait(timeout=30)
    assert wait_for(lambda: not alive(qemu), timeout=30), "QEMU outlived its parent"


def test_the_emulated_plate_runs_with_the_truth_given_on_the_command_line():
    board = Board("--json", "--resonance-hz", "24000", "--q", "150")
    try:
        assert json.loads(board.first)["resonance_hz"] == 24000
        boot = json.loads(board.process.stdout.readline())
        assert (boot["event"], boot["plate_resonance_hz"], boot["plate_q"]) == ("boot", 24000, 150)  # read back
    finally:
        board.process.send_signal(signal.SIGINT)
        assert board.process.wait(timeout=60) == 128 + signal.SIGINT


def test_budget_measurement_reads_a_loop_of_known_length_exactly():
    from ultraglide.devices.firmware.budgets import CALIBRATION, measure

    figures = measure()
    name, instructions = CALIBRATION
    assert figures[name] == pytest.approx(instructions, abs=2)  # 1000 × (subs, bne) + the call, counted by QEMU
    assert 250 * 3 < figures["dac_block_250"] < 250 * 40  # a few instructions a sample, not a few hundred
