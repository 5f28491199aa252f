"""Faults injected into the netduinoplus2 board under QEMU (``plate-sim --board qemu --board-fault KIND@SECONDS``,
the image's console command ``fault KIND``): each kind ends in a silent output and a reset, and the next boot
says why. A hung block interrupt or main loop is caught by the watchdog (QEMU models no IWDG: the QEMU image's
stand-in, SysTick at the highest priority checking the same two marks), which cannot fire before its 4 ms window;
a stack overflow or a hard fault by the fault handler at once. The image's layout (the stack below RAM's data)
is read from its ELF symbols. Marked ``qemu`` and ``slow``; one QEMU at a time (the lock of
test_firmware_qemu.py)."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time

import pytest
from conftest import ROOT
from qemu_board import injected, next_event, said_in_hello
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware.boards import build_images
from ultraglide.devices.firmware.qemu import QemuPlate

pytestmark = [
    pytest.mark.slow,
    pytest.mark.qemu,
    pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
                       reason="needs gcc-arm-none-eabi, libnewlib-arm-none-eabi and qemu-system-arm"),
]

WATCHDOG_MS = 4.0  # board.h BOARD_WATCHDOG_US
MISSES = 3  # BOARD_WATCHDOG_MISSES: looks in a row without both marks
CFSR_STKERR, CFSR_PRECISERR, CFSR_BFARVALID = 1 << 12, 1 << 9, 1 << 15  # ARMv7-M BusFault status bits


@pytest.fixture(scope="module")
def image():
    return build_images("netduinoplus2", ["qemu"])[0]


@pytest.mark.parametrize("kind", ["isr-hang", "main-hang"])
def test_a_hang_is_caught_by_the_watchdog_which_silences_the_output_and_resets(one_qemu, image, kind):
    with QemuPlate(image.elf_path) as plate:
        boot, happened, blanked = injected(plate, kind)
        assert boot["reset_reason"] == "watchdog" and boot["injected"] == kind and boot["watchdog"] == "stand-in-timer"
        assert happened["event"] == "watchdog_reset"
        # the mark that stopped: a hung block interrupt's (the main loop may have marked once before it was shut out,
        # never after); a hung main loop's alone, the block interrupt's still coming
        if kind == "isr-hang":
            assert happened["missing"][0] == "block interrupt"
        else:
            assert happened["missing"] == ["main loop"]
        assert MISSES <= happened["looks_missed"] <= MISSES + 3  # on time, on the board's own clock (1 ms a look)
        # the window runs from the last refresh, at most one look (1 ms) before the fault: never sooner than that
        assert blanked["injected"] == kind and blanked["after_fault_ms"] >= WATCHDOG_MS - 1.0
        stats = next_event(plate, ("stats",))  # and it runs again after the reset
        assert stats["blocks"] >= 900
        reply = said_in_hello(plate)  # and a host connecting now hears why it restarted
        assert reply.restart_reason == p.RESTART_WATCHDOG
        # the marks it saw (bit 0 the block interrupt's, bit 1 the main loop's): those its console did not call missing
        marks = {"block interrupt": 1, "main loop": 2}
        assert reply.restart_detail & 3 == 3 - sum(marks[name] for name in happened["missing"])
        assert ("the block interrupt's" in reply.restart_words()) == (kind == "isr-hang")


@pytest.mark.parametrize(("kind", "status_bits"), [("stack-overflow", CFSR_STKERR),
                                                   ("hard-fault", CFSR_PRECISERR | CFSR_BFARVALID)])
def test_a_fault_is_caught_by_its_handler_which_silences_the_output_first(one_qemu, image, kind, status_bits):
    with QemuPlate(image.elf_path) as plate:
        boot, happened, blanked = injected(plate, kind)
        assert boot["reset_reason"] == "fault" and boot["injected"] == kind
        assert happened["event"] == "board_fault" and happened["fault_status"] & status_bits == status_bits
        assert 0.0 <= blanked["after_fault_ms"] < WATCHDOG_MS  # the handler, not the watchdog
        assert next_event(plate, ("stats",))["blocks"] >= 900
        reply = said_in_hello(plate)
        assert (reply.restart_reason, reply.restart_detail) == (p.RESTART_FAULT, happened["fault_status"])
        assert reply.restart_words() == f"a fault handler reset it (fault status {happened['fault_status']:#010x})"


def test_plate_sim_board_fault_prints_what_the_board_did_as_json(one_qemu, image):
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--board", "netduinoplus2",
                                "--board-fault", "isr-hang@1.5", "--json"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=ROOT)
    events = []
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not any(e["event"] == "output_blanked" for e in events):
            line = process.stdout.readline()
            if not line:
                break
            events.append(json.loads(line))
    finally:
        process.send_signal(signal.SIGINT)
        status = process.wait(timeout=60)
    names = [e["event"] for e in events if e["event"] != "stats"]
    assert names[:2] == ["serving", "boot"]
    assert names[2:] == ["fault_injected", "boot", "watchdog_reset", "output_blanked"], names
    assert events[-1]["after_fault_ms"] >= WATCHDOG_MS - 1.0 and events[-1]["by"] == "watchdog_reset"
    assert status == 128 + signal.SIGINT


@pytest.mark.parametrize("argument", ["isr-hang", "isr-hang@", "nothing@1", "isr-hang@-1", "isr-hang@soon"])
def test_a_bad_board_fault_is_refused_in_one_line(argument):
    result = subprocess.run([sys.executable, "-m", "ultraglide", "plate-sim", "--board", "qemu", "--board-fault",
                             argument], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 2 and result.stdout == ""
    assert len(result.stderr.strip().splitlines()) <= 2 and "--board-fault" in result.stderr


def test_board_fault_is_refused_on_the_simulator():
    result = subprocess.run([sys.executable, "-m", "ultraglide", "plate-sim", "--board-fault", "isr-hang@1"],
                            capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 2 and result.stdout == ""  # usage: the house's UsageError after parsing
    assert len(result.stderr.strip().splitlines()) == 1 and "--board qemu" in result.stderr


def test_the_stack_sits_below_ram_s_data_so_an_overflow_faults(image):
    symbols = {}
    for line in subprocess.run(["arm-none-eabi-nm", image.elf_path], capture_output=True, text=True,
                               check=True).stdout.splitlines():
        address, _kind, name = line.split()
        symbols[name] = int(address, 16)
    assert symbols["_stack_bottom"] == 0x2000_0000  # the start of SRAM: below it nothing answers
    assert symbols["_stack_top"] - symbols["_stack_bottom"] == image.stack_bytes == 8192
    assert symbols["_stack_top"] <= symbols["_data_start"] < symbols["_bss_start"]
    assert symbols["_stack_top"] <= symbols["ug_reset_record"] < symbols["_data_start"]  # .noinit: not zeroed


def test_play_on_a_board_that_resets_itself_says_why_from_its_next_handshake(one_qemu, image, tmp_path):
    """A hung block interrupt mid-run: the board resets, the host finds the link silent and connects again, and the
    new handshake says the watchdog restarted it (HELLO_REPLY's restart_reason): a device fault in the report,
    beside the loss (exit status 4, the larger)."""
    from test_exits import Command

    with QemuPlate(image.elf_path) as plate:
        assert next_event(plate, ("boot",))["reset_reason"] == "power-on"
        command = Command(tmp_path, "play", "grating-1mm", "--device", f"serial:{plate.path}", "--profile",
                          "sim-plate", "--duration-s", "15", "--json")
        try:
            deadline = time.monotonic() + 120
            while next_event(plate, ("stats",), timeout=120)["setpoints"] < 2000:  # two seconds of the stream
                assert time.monotonic() < deadline and command.process.poll() is None, command.stderr
            plate.inject_fault("isr-hang")
            assert next_event(plate, ("boot",))["reset_reason"] == "watchdog"
            status = command.wait()
        finally:
            command.kill()
    report = json.loads(command.stdout)["report"]
    said = [line for line in report["lines"] if line.startswith("the plate driver restarted itself, its handshake at ")]
    assert len(said) == 1, report["lines"]
    assert "said: its watchdog expired (the block interrupt's" in said[0], said  # its mark missing, first of all
    assert status == report["exit_status"] == 4, (status, report["lines"])  # the loss outranks the fault
