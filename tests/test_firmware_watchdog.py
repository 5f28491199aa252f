"""The boards' fail-safe logic compiled for the host: the STM32's independent watchdog (IWDG) started and refreshed
by the register sequence of its reference manual (RM0090 §19), read back from a recording register file, not from
the firmware's own description of it; the two marks (block interrupt, main loop) that alone let it be refreshed;
the reset record that tells the next boot why the board restarted; the fault-injection command of the QEMU images.
QEMU models no IWDG, so this is where its sequence is checked; the watchdog's effect under QEMU (the stand-in on
netduinoplus2) is in test_firmware_faults.py."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "devices" / "firmware"
SHIM = Path(__file__).resolve().parent / "firmware" / "register_shim.c"
IWDG = 0x4000_3000
KR, PR, RLR, SR = IWDG + 0x0, IWDG + 0x4, IWDG + 0x8, IWDG + 0xC
READ = 0xFFFF_FFFF  # the shim's mark of a read in its log


class Record(ctypes.Structure):
    _fields_ = [(name, ctypes.c_uint32) for name in
                ("magic", "reason", "detail", "injected", "fault_at", "silent_after_us", "where", "check")]


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("needs a host C compiler (gcc)")
    library = tmp_path_factory.mktemp("safety") / "libsafety.so"
    flags = ["-std=c11", "-Wall", "-Wextra", "-Werror", "-Wshadow", "-O2", "-shared", "-fPIC",
             "-DUG_HOST_REGISTERS", "-DUG_HOST_BUILD"]
    sources = [FIRMWARE / "ports" / "common" / "ug_safety.c", FIRMWARE / "ports" / "netduinoplus2" / "iwdg.c", SHIM]
    subprocess.run(["gcc", *flags, f"-I{FIRMWARE / 'ports' / 'common'}", *map(str, sources), "-o", str(library)],
                   check=True)
    lib = ctypes.CDLL(str(library))
    u32, p32 = ctypes.c_uint32, ctypes.POINTER(ctypes.c_uint32)
    for name, restype, argtypes in [
        ("ug_iwdg_start", u32, [u32, u32]), ("ug_iwdg_refresh", None, []),
        ("ug_iwdg_divider", None, [u32, u32, p32, p32]),
        ("shim_registers_reset", None, [u32, u32]), ("shim_registers_count", u32, []),
        ("shim_registers_address", u32, [u32]), ("shim_registers_value", u32, [u32]),
        ("ug_marks_block", None, []), ("ug_marks_main", None, []), ("ug_marks_take", ctypes.c_bool, []),
        ("ug_reset_note", None, [u32, u32, u32]), ("ug_reset_note_injection", None, [u32, u32]),
        ("ug_reset_take", u32, [ctypes.POINTER(Record)]), ("ug_reset_name", ctypes.c_char_p, [u32]),
        ("ug_inject_parse", u32, [ctypes.c_char_p]), ("ug_inject_name", ctypes.c_char_p, [u32]),
    ]:
        function = getattr(lib, name)
        function.restype, function.argtypes = restype, argtypes
    return lib


def register_log(lib) -> list[tuple[int, int]]:
    return [(lib.shim_registers_address(i), lib.shim_registers_value(i)) for i in range(lib.shim_registers_count())]


def divider(lib, timeout_us: int, lsi_hz: int) -> tuple[int, int]:
    pr, rlr = ctypes.c_uint32(), ctypes.c_uint32()
    lib.ug_iwdg_divider(timeout_us, lsi_hz, ctypes.byref(pr), ctypes.byref(rlr))
    return pr.value, rlr.value


def test_the_iwdg_starts_by_the_reference_manuals_sequence(lib):
    lib.shim_registers_reset(3, 0b11)  # PVU and RVU read busy three times, as while the LSI domain takes them
    rlr = lib.ug_iwdg_start(4000, 32000)
    log = register_log(lib)
    writes = [(address, value) for address, value in log if value != READ]
    # unlock, prescaler /4 (code 0), reload 32 (4 ms at 32 kHz / 4 = 8 kHz), then start, then reload the counter
    assert writes == [(KR, 0x5555), (PR, 0), (RLR, 32), (KR, 0xCCCC), (KR, 0xAAAA)]
    assert rlr == 32
    reads = [i for i, (address, value) in enumerate(log) if value == READ]
    assert [log[i][0] for i in reads] == [SR] * 4  # polled until PVU and RVU cleared (3 busy, 1 clear)
    start = log.index((KR, 0xCCCC))
    assert all(i < start for i in reads) and log.index((RLR, 32)) < reads[0]  # waited after writing, before start


def test_the_iwdg_refresh_is_the_reload_key_alone(lib):
    lib.shim_registers_reset(0, 0)
    lib.ug_iwdg_refresh()
    assert register_log(lib) == [(KR, 0xAAAA)]


@pytest.mark.parametrize(("timeout_us", "lsi_hz", "expected"), [
    (4000, 32000, (0, 32)),         # 32 kHz / 4 = 8 kHz: 32 ticks
    (1_000_000, 32000, (1, 4000)),  # /4 would need 8000 > 4095 ticks: /8, 4000 ticks
    (32_000_000, 32000, (6, 4000)),  # /256: 125 Hz, 4000 ticks
    (100, 32000, (0, 1)),           # less than a tick: one tick, the shortest there is
])
def test_the_iwdg_divider_takes_the_smallest_prescaler_that_fits(lib, timeout_us, lsi_hz, expected):
    pr, rlr = divider(lib, timeout_us, lsi_hz)
    assert (pr, rlr) == expected
    assert 1 <= rlr <= 4095
    if timeout_us >= 1000:  # never longer than asked, and within one tick of it
        tick_us = 1e6 * (4 << pr) / lsi_hz
        assert timeout_us - tick_us < rlr * tick_us <= timeout_us


def test_the_watchdog_is_fed_only_when_both_marks_were_set(lib):
    assert not lib.ug_marks_take()
    lib.ug_marks_block()
    assert not lib.ug_marks_take()  # the main loop has not run: no refresh
    lib.ug_marks_main()
    assert lib.ug_marks_take()      # both since the last refresh
    assert not lib.ug_marks_take()  # ... and both are needed again
    lib.ug_marks_main()
    lib.ug_marks_main()
    assert not lib.ug_marks_take()  # the block interrupt has not run
    lib.ug_marks_block()
    assert lib.ug_marks_take()


def test_the_reset_record_says_why_the_board_restarted_once(lib):
    record = Record()
    assert lib.ug_reset_take(ctypes.byref(record)) == 0 and record.silent_after_us == 0xFFFFFFFF  # power-on
    lib.ug_reset_note(1, 0x0301, 0)  # the watchdog expired, no injection before it
    assert lib.ug_reset_take(ctypes.byref(record)) == 1
    assert (record.detail, record.injected, record.silent_after_us) == (0x0301, 0, 0xFFFFFFFF)
    assert lib.ug_reset_take(ctypes.byref(record)) == 0  # read once: the next boot is a power-on again
    lib.ug_reset_note_injection(4, 123_456)  # a hard fault injected at the board's clock 123 456
    lib.ug_reset_note(2, 0x8200, 88)
    assert lib.ug_reset_take(ctypes.byref(record)) == 2
    assert (record.injected, record.fault_at, record.silent_after_us, record.detail) == (4, 123_456, 88, 0x8200)
    assert [lib.ug_reset_name(i).decode() for i in range(5)] == ["power-on", "watchdog", "fault", "software", "pin"]


def test_a_record_that_did_not_survive_reads_as_a_power_on(lib):
    lib.ug_reset_note(1, 0, 0)
    record = Record.in_dll(lib, "ug_reset_record")
    record.detail ^= 0x10  # one bit of RAM changed while the power was off: the check word no longer matches
    out = Record()
    assert lib.ug_reset_take(ctypes.byref(out)) == 0


def test_a_board_without_a_reset_cause_register_tells_a_reset_with_power_kept_by_its_ram(lib, tmp_path):
    """ug_reset_take_from_ram on a fresh copy of the library (its RAM zero, as QEMU's at power-on): a power-on, then
    a reset that kept the RAM (reason 4, the pin), each with detail bit 0 (told from RAM); a record of the firmware's
    own wins over the mark; the mark's words disturbed (RAM after a power cut) read as a power-on again."""
    copy = tmp_path / "fresh.so"
    shutil.copyfile(lib._name, copy)
    fresh = ctypes.CDLL(str(copy))  # another path: a second instance with its own zeroed statics
    fresh.ug_reset_take_from_ram.restype, fresh.ug_reset_take_from_ram.argtypes = ctypes.c_uint32, [
        ctypes.POINTER(Record)]
    fresh.ug_reset_note.argtypes = [ctypes.c_uint32] * 3
    out = Record()
    assert fresh.ug_reset_take_from_ram(ctypes.byref(out)) == 0 and (out.reason, out.detail) == (0, 1)  # power-on
    assert fresh.ug_reset_take_from_ram(ctypes.byref(out)) == 4 and (out.reason, out.detail) == (4, 1)  # power kept
    fresh.ug_reset_note(2, 0x8200, 0)  # a fault handler's reset: its record, not the RAM's mark
    assert fresh.ug_reset_take_from_ram(ctypes.byref(out)) == 2 and out.detail == 0x8200
    assert fresh.ug_reset_take_from_ram(ctypes.byref(out)) == 4  # and the next reset by the button is the pin again
    mark = (ctypes.c_uint32 * 2).in_dll(fresh, "ug_power_mark")
    assert (mark[0], mark[1]) == (0x55475057, 0xAAB8AFA8)  # "UGPW" and its complement, armed for the next boot
    mark[1] ^= 1 << 7  # one bit of RAM changed while the power was off
    assert fresh.ug_reset_take_from_ram(ctypes.byref(out)) == 0 and out.detail == 1


@pytest.mark.parametrize(("line", "kind"), [
    (b"fault isr-hang", 1), (b"fault main-hang\n", 2), (b"fault stack-overflow\r\n", 3), (b"fault hard-fault", 4),
    (b"fault isr-hangs", 0), (b"fault", 0), (b"faults isr-hang", 0), (b"", 0), (b"fault nothing", 0),
])
def test_the_fault_command_names_one_kind(lib, line, kind):
    assert lib.ug_inject_parse(line) == kind
    if kind:
        assert lib.ug_inject_name(kind).decode() == line.split()[1].decode()
