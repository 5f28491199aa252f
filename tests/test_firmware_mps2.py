"""The mps2-an386 board (ports/mps2-an386: ARM's MPS2 with the AN386 image, CMSDK UARTs, timers and watchdog)
under QEMU's ``mps2-an386`` machine: it builds with -Werror beside the netduinoplus2, boots and says so, passes
the host's conformance run, and its CMSDK watchdog (whose first expiry is the NMI) catches a hung block
interrupt or main loop, silencing the output and resetting the board; a stack overflow (the MPU's guard) or a
hard fault is caught by the fault handler at once; and a host connecting after any of them hears why the board
restarted in its handshake (HELLO_REPLY's restart_reason and restart_detail, as tests/test_firmware_faults.py
hears the netduinoplus2). Marked ``qemu`` and ``slow``; one QEMU at a time (the lock of
test_firmware_qemu.py). QEMU runs the image with its instruction counter (qemu.MACHINE_ICOUNT): while the board runs,
its clock moves with the instructions it runs, so a loaded machine that deschedules QEMU does not expire its
watchdog, and a hang (which keeps the processor busy) is caught exactly one window after the last refresh on both
marks; while it sleeps (WFI) its clock keeps real time, so a stall of QEMU then is a jump, which the watchdog
excuses and survives."""

from __future__ import annotations

import contextlib
import json
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time

import pytest
from conftest import ROOT
from qemu_board import injected, next_event, said_in_hello
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware.boards import BOARD_INFO, FIRMWARE_DIR, build_images
from ultraglide.devices.firmware.qemu import QemuPlate

pytestmark = [
    pytest.mark.slow,
    pytest.mark.qemu,
    pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
                       reason="needs gcc-arm-none-eabi, libnewlib-arm-none-eabi and qemu-system-arm"),
]

BOARD = "mps2-an386"
WATCHDOG_MS = 3.0  # board.h BOARD_WATCHDOG_US
BLOCK_MS = 1.0  # the block interrupt's period (TIMER0)
NMI_MS = 0.1  # from the watchdog's expiry to the NMI handler's stopping the output: a few hundred instructions
# From an injected hang to a silent output, at most: a hung block interrupt stops before its first block, after the
# last refresh; a hung main loop may have set its mark just before it stopped, so the next block interrupt (within a
# block, and a block's run) still refreshes once after the fault. The aim is 5 ms (docs/performance.md).
SILENT_WITHIN_MS = {"isr-hang": WATCHDOG_MS + NMI_MS, "main-hang": WATCHDOG_MS + 2 * BLOCK_MS}
EXCUSES = 3  # BOARD_WATCHDOG_EXCUSES: windows restarted in a row for QEMU's own stalls, at most
CFSR_DACCVIOL, CFSR_MMARVALID = 1 << 1, 1 << 7  # ARMv7-M fault status: the MPU refused a data access
CFSR_PRECISERR, CFSR_BFARVALID = 1 << 9, 1 << 15  # a bus fault at a known address


@pytest.fixture(scope="module")
def image():
    return build_images(BOARD, ["qemu"])[0]


def started(image) -> QemuPlate:
    return QemuPlate(image.elf_path, machine=BOARD_INFO[BOARD].machine)


@pytest.mark.parametrize(("board", "variants"), [("netduinoplus2", ["hardware", "qemu"]), (BOARD, ["qemu"])])
def test_both_boards_build_with_every_warning_an_error(tmp_path, board, variants):
    """Each board's Makefile compiles every source with -Wall -Wextra -Werror (make echoes the commands) and
    no warning is printed; the image's flash is what binutils' size reads (text + data)."""
    result = subprocess.run(["make", "--no-print-directory", "-f", str(FIRMWARE_DIR / "ports" / board / "Makefile"),
                             f"O={tmp_path}", *variants], capture_output=True, text=True, timeout=600, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    compiles = [line for line in result.stdout.splitlines() if line.startswith("arm-none-eabi-gcc") and " -c " in line]
    assert compiles and all("-Werror" in line and "-Wall" in line and "-Wextra" in line for line in compiles)
    assert "warning" not in (result.stdout + result.stderr).lower()
    for variant in variants:
        built = build_images(board, [variant], out_dir=str(tmp_path))[0]
        size = subprocess.run(["arm-none-eabi-size", built.elf_path], capture_output=True, text=True,
                              check=True).stdout.splitlines()[1].split()
        assert built.flash_bytes == int(size[0]) + int(size[1])


def test_the_board_boots_and_says_which_board_and_watchdog(one_qemu, image):
    with started(image) as plate:
        boot = next_event(plate, ("boot",))
        assert (boot["board"], boot["variant"], boot["watchdog"], boot["reset_reason"]) == \
            (BOARD, "qemu", "cmsdk", "power-on")
        assert boot["watchdog_us"] == WATCHDOG_MS * 1000 and boot["sample_rate_hz"] == 48000
        assert boot["max_amplitude_um_pp"] == 6.0  # sim-plate, the image's own emulation block
        stats = next_event(plate, ("stats",))  # a second on the board's clock: the blocks ran, the watchdog was fed
        assert stats["blocks"] >= 900 and stats["watchdog_looks"] >= 100
        assert next_event(plate, ("stats",))["blocks"] >= 1900  # and no reset in between (a boot would say so)
        assert all(e["event"] != "boot" for e in list(plate.events.queue))
        reply = said_in_hello(plate)  # a host hears that nothing but power brought it up, told from the RAM (bit 0:
        assert reply.features & p.FEATURE_RESET_STATED  # the board has no reset-cause register; test_restart_reason)
        assert (reply.restart_reason, reply.restart_detail) == (p.RESTART_POWER_ON, p.RESTART_DETAIL_FROM_RAM)
        assert reply.restart_words() == "power-on (told from its RAM: the board has no reset-cause register)"


@pytest.mark.parametrize("kind", ["isr-hang", "main-hang"])
def test_a_hang_is_caught_by_the_cmsdk_watchdogs_nmi_which_silences_and_resets(one_qemu, image, kind):
    with started(image) as plate:
        boot, happened, blanked = injected(plate, kind)
        assert boot["reset_reason"] == "watchdog" and boot["injected"] == kind and boot["watchdog"] == "cmsdk"
        assert happened["event"] == "watchdog_reset"
        # the mark that stopped: a hung block interrupt's (the injection's console line marks the main loop's once
        # from inside it); a hung main loop's alone, the block interrupt's still coming
        assert happened["missing"] == (["block interrupt"] if kind == "isr-hang" else ["main loop"])
        # the window runs from the last refresh on both marks, which may be a few blocks before the fault (a block
        # whose main-loop mark was not yet set does not refresh): never excused, since a hang keeps the processor
        # busy and QEMU's clock then moves only with its instructions
        assert blanked["injected"] == kind
        assert 0.0 < blanked["after_fault_ms"] <= SILENT_WITHIN_MS[kind]
        assert happened["looks_missed"] <= EXCUSES  # the NMIs excused in a row before this one
        assert next_event(plate, ("stats",))["blocks"] >= 900  # and it runs again after the reset
        reply = said_in_hello(plate)  # and a host connecting now hears why it restarted
        assert reply.restart_reason == p.RESTART_WATCHDOG
        # the marks it saw (bit 0 the block interrupt's, bit 1 the main loop's): those its console did not call
        # missing; bits 8-15 the NMIs excused in a row before it (its console's looks_missed)
        marks = {"block interrupt": 1, "main loop": 2}
        assert reply.restart_detail & 3 == 3 - sum(marks[name] for name in happened["missing"])
        assert (reply.restart_detail >> 8) & 0xFF == happened["looks_missed"]
        assert ("the block interrupt's mark missing" in reply.restart_words()) == (kind == "isr-hang")
        assert ("the main loop's mark missing" in reply.restart_words()) == (kind == "main-hang")


def test_qemu_stopped_by_its_host_makes_the_clock_jump_and_a_hang_after_it_is_still_caught(one_qemu, image):
    """QEMU stopped by its host for 50 ms (SIGSTOP, then SIGCONT), twenty times, as a loaded machine deschedules it.
    The board sleeps between its interrupts (WFI), and under QEMU's instruction counter a sleeping board's clock keeps
    real time: a stop that finds it asleep is a jump of its clock by the stop's 50 ms, past both of the watchdog's
    expiries (3 ms each), and the second stops QEMU's model of the counter. The board is never reset (the NMI excuses
    a late expiry), and a block interrupt that hangs afterwards is still caught within one window: the excuse
    restarted the counter. (Before it did, the board ran on with no watchdog after such a jump: the hang was never
    caught.) A stop that finds the board busy pauses its clock instead: of twenty, some find it asleep."""
    with started(image) as plate:
        assert next_event(plate, ("boot",))["reset_reason"] == "power-on"
        first = next_event(plate, ("stats",))
        stats = first
        for _ in range(20):
            plate.process.send_signal(signal.SIGSTOP)
            time.sleep(0.05)  # the stall itself: what a loaded host does to QEMU, not a wait for anything
            plate.process.send_signal(signal.SIGCONT)
            later = next_event(plate, ("stats", "boot"))  # a second of the board's clock, or a reset
            assert later["event"] == "stats" and later["blocks"] > stats["blocks"], later  # it ran on: no reset
            stats = later
        # the clock jumped (more than BOARD_STALL_BLOCKS blocks due at once: skipped), and the watchdog excused it
        assert stats["skipped_ms"] > first["skipped_ms"] and stats["watchdog_stalls"] > first["watchdog_stalls"], stats
        plate.inject_fault("isr-hang")
        assert next_event(plate, ("fault_injected",))["kind"] == "isr-hang"
        boot = next_event(plate, ("boot",))
        assert (boot["reset_reason"], boot["injected"]) == ("watchdog", "isr-hang")
        assert 0.0 < next_event(plate, ("output_blanked",))["after_fault_ms"] <= SILENT_WITHIN_MS["isr-hang"]


@pytest.mark.parametrize(("kind", "status_bits"), [("stack-overflow", CFSR_DACCVIOL | CFSR_MMARVALID),
                                                   ("hard-fault", CFSR_PRECISERR | CFSR_BFARVALID)])
def test_a_fault_is_caught_by_its_handler_which_silences_the_output_first(one_qemu, image, kind, status_bits):
    with started(image) as plate:
        boot, happened, blanked = injected(plate, kind)
        assert boot["reset_reason"] == "fault" and boot["injected"] == kind
        assert happened["event"] == "board_fault" and happened["fault_status"] & status_bits == status_bits
        assert 0.0 <= blanked["after_fault_ms"] < WATCHDOG_MS - 1.0  # the handler, not the watchdog
        assert next_event(plate, ("stats",))["blocks"] >= 900
        reply = said_in_hello(plate)  # the fault's status (CFSR) as the handler read it, in the handshake
        assert (reply.restart_reason, reply.restart_detail) == (p.RESTART_FAULT, happened["fault_status"])
        assert reply.restart_words() == f"a fault handler reset it (fault status {happened['fault_status']:#010x})"


def test_plate_sim_board_fault_on_the_board_prints_what_it_did_as_json(one_qemu):
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--board", BOARD,
                                "--board-fault", "isr-hang@1.5", "--json"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=ROOT)
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in process.stdout], daemon=True).start()
    events = []
    try:
        deadline = time.monotonic() + 120  # the command's start (Python, the image's build or lookup, QEMU, a boot)
        while time.monotonic() < deadline and not any(e["event"] == "output_blanked" for e in events):
            with contextlib.suppress(queue.Empty):
                events.append(json.loads(lines.get(timeout=0.5)))
                if events[-1]["event"] == "fault_injected":  # from here on the board's, not the machine's start-up
                    deadline = time.monotonic() + 30
    finally:
        process.send_signal(signal.SIGINT)
        status = process.wait(timeout=60)
    names = [e["event"] for e in events if e["event"] != "stats"]
    assert names == ["serving", "boot", "fault_injected", "boot", "watchdog_reset", "output_blanked"], \
        [(e["event"], e["t_s"]) for e in events]
    assert events[0]["board"] == BOARD and events[-1]["by"] == "watchdog_reset"
    assert 0.0 < events[-1]["after_fault_ms"] <= SILENT_WITHIN_MS["isr-hang"]
    assert status == 128 + signal.SIGINT


def test_play_on_the_board_that_resets_itself_says_why_from_its_next_handshake(one_qemu, image, tmp_path):
    """A hung block interrupt mid-run on the mps2-an386: the CMSDK watchdog's NMI resets the board, the host finds
    the link silent and connects again, and the new handshake says the watchdog restarted it (HELLO_REPLY's
    restart_reason): a device fault in the report, beside the loss (exit status 4, the larger). ``play``'s own
    defaults otherwise: the stream's rate is what the board's handshake says its link carries."""
    from test_exits import Command

    with started(image) as plate:
        assert next_event(plate, ("boot",))["reset_reason"] == "power-on"
        command = Command(tmp_path, "play", "grating-1mm", "--device", f"serial:{plate.path}", "--profile",
                          "sim-plate", "--duration-s", "15", "--json")
        try:
            deadline = time.monotonic() + 120
            while next_event(plate, ("stats",), timeout=120)["setpoints"] < 2000:  # two seconds of the stream
                assert time.monotonic() < deadline and command.process.poll() is None, command.stderr
            plate.inject_fault("isr-hang")
            boot = next_event(plate, ("boot",))
            assert (boot["reset_reason"], boot["injected"]) == ("watchdog", "isr-hang")
            status = command.wait()
        finally:
            command.kill()
    report = json.loads(command.stdout)["report"]
    said = [line for line in report["lines"] if line.startswith("the plate driver restarted itself, its handshake at ")]
    assert len(said) == 1, report["lines"]
    assert "said: its watchdog expired (the block interrupt's mark missing)" in said[0], said
    assert status == report["exit_status"] == 4, (status, report["lines"])  # the loss outranks the fault
