"""A board image run under QEMU, its host link on a pseudo-terminal: ``plate-sim --board NAME``.

QEMU's ``netduinoplus2`` machine (or ``mps2-an386``, whose UART0 and UART1 stand where USART1 and USART2 do
here) runs the image; ``-serial pty`` puts USART1 (the protocol link) on a new
pty, which :class:`QemuPlate` serves behind a stable symlink as the simulated plate does, and ``-serial
stdio`` puts USART2 (the board's debug console: one line per event, see ``ports/common/port.c``) on
a pipe read here. QEMU dies with its parent (``PR_SET_PDEATHSIG``), so a killed command leaves no orphan,
and runs at SCHED_FIFO 1 where this process may grant it (nice -10 otherwise): the emulated board is
real-time work, and a normally scheduled QEMU on a busy machine lost tens of ms at a time.

The emulated link is slower than the board's: QEMU hands the firmware a byte per round trip between two of
its threads, each a wake-up: about 14 kB/s measured on this two-core machine at load 12 (the board's
rx_bytes counter while the host wrote as fast as the pty took), where a real 921 600 baud UART carries
92 kB/s. The host's default stream (12 000 setpoints/s in 1-2 ms frames, 25-34 kB/s) does not fit; a
slower one does: ``serial:PATH?rate=1000&frame_ms=4`` (7 kB/s, docs/firmware.md).

Example::

    with QemuPlate(image.elf_path) as plate:
        print(plate.path)            # drive it with --device serial:PATH
        event = plate.events.get()   # {"t_s": ..., "event": "enabled", ...}
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import queue
import re
import shutil
import signal
import socket
import struct
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.protocol import NAK_REASONS
from ultraglide.devices.sim.links import LinkClaim, link_path_for, place_link, remove_link

QEMU = "qemu-system-arm"
MACHINE = "netduinoplus2"
START_TIMEOUT_S = 20.0
STOP_TIMEOUT_S = 5.0
MAX_EVENTS = 10000
_PTY_LINE = re.compile(rb"char device redirected to (/dev/pts/\d+) \(label serial0\)")
_PR_SET_PDEATHSIG = 1
CONFIG_MAGIC = 0x5547_4550  # "UGEP"
QEMU_FIFO_PRIORITY = 1  # above every normal process (a loaded machine deschedules QEMU, and the board's time with
# it, for tens of ms: its plate runs dry, its buffer drifts), below the host engine's block thread (60)
FAULT_KINDS = ("isr-hang", "main-hang", "stack-overflow", "hard-fault")  # ports/common/ug_safety.h
QEMU_NICE = -10  # QEMU's USART passes a byte per round trip between two of its threads: each waits for a CPU
# QEMU's clock for each machine's image. Without -icount, QEMU's virtual clock is the host's: a processor thread the
# host deschedules (for tens of ms at a time on a loaded machine, SCHED_FIFO or not: RT throttling, other real-time
# threads, the hypervisor) lets the board's timers and watchdog count on while its processor runs nothing, and the
# board cannot tell that from a hang. With -icount the virtual clock advances 2^shift ns per instruction executed,
# and with real time only while the processor sleeps (sleep=on, WFI); align=on holds the processor back when it gets
# ahead of real time. A descheduled processor then stops the board's clock too: its watchdog expires only on a
# board that ran. The mps2-an386 image sleeps (WFI) between its interrupts, so QEMU's processor thread leaves its core
# to the host's other work then; a stall of the host while it sleeps is a jump of its clock, which its watchdog
# excuses and survives (ports/mps2-an386/board.c, watchdog_rearm). shift=4 (16 ns an
# instruction, a 62.5 MIPS processor) is about what QEMU runs the mps2-an386
# image at on this two-core machine (docs/performance.md): faster would let the board's clock fall behind real time
# (shift=3 ran it at 0.79-0.84 of real time under load), slower starves its main loop (shift=5: resets at once).
# The netduinoplus2's image keeps the host's clock and its stand-in watchdog (ports/netduinoplus2/board.h).
MACHINE_ICOUNT = {"mps2-an386": "shift=4,sleep=on,align=on"}


@dataclass(frozen=True)
class EmulatedPlate:
    """What the QEMU image's emulated plate is (its truth: resonance in Hz drifting by ``drift_hz_per_s``,
    quality factor) and the profile the firmware declares in HELLO_REPLY (µm peak-to-peak, Hz); written into
    the image's ``.emulation`` section (``ports/common/emulation_config.h``) in a copy of the ELF file."""

    resonance_hz: float
    q: float
    drift_hz_per_s: float
    profile_resonance_hz: float
    profile_q: float
    full_scale_um_pp: float
    max_amplitude_um_pp: float
    max_drive_um_pp: float
    carrier_min_hz: float
    carrier_max_hz: float

    @classmethod
    def of(cls, profile, resonance_hz: float | None = None, q: float | None = None,
           drift_hz_per_s: float = 0.0) -> EmulatedPlate:
        return cls(resonance_hz or profile.resonance_hz, q or profile.q, drift_hz_per_s, profile.resonance_hz,
                   profile.q, profile.full_scale_um_pp, profile.max_amplitude_um_pp,
                   profile.max_drive_um_pp or profile.max_amplitude_um_pp, profile.carrier_min_hz,
                   profile.carrier_max_hz)

    def words(self) -> list[int]:
        """The block as little-endian 32-bit words: the magic, then each field as an IEEE binary32."""
        floats = [self.resonance_hz, self.q, self.drift_hz_per_s, self.profile_resonance_hz, self.profile_q,
                  self.full_scale_um_pp, self.max_amplitude_um_pp, self.max_drive_um_pp, self.carrier_min_hz,
                  self.carrier_max_hz]
        return [CONFIG_MAGIC] + [struct.unpack("<I", struct.pack("<f", value))[0] for value in floats]

    def write_into(self, elf_path: str) -> None:
        """Write the block into the ``.emulation`` section of the ELF file at ``elf_path`` (a copy)."""
        block = b"".join(struct.pack("<I", word) for word in self.words())
        with open(elf_path, "r+b") as elf:
            offset, size = _section(elf, ".emulation")
            if size != len(block):
                raise DeviceError(f"{elf_path}: its emulation block is {size} bytes, not {len(block)}: rebuild it")
            elf.seek(offset)
            elf.write(block)


def _section(elf, wanted: str) -> tuple[int, int]:
    """File offset and size of a section of a 32-bit little-endian ELF file, by name."""
    header = elf.read(52)
    if header[:6] != b"\x7fELF\x01\x01":
        raise DeviceError(f"{elf.name} is not a 32-bit little-endian ELF image")
    shoff, = struct.unpack_from("<I", header, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", header, 0x2E)
    elf.seek(shoff)
    sections = [struct.unpack_from("<10I", elf.read(shentsize)) for _ in range(shnum)]
    names_offset = sections[shstrndx][4]
    for name, _type, _flags, _addr, offset, size, *_rest in sections:
        elf.seek(names_offset + name)
        if elf.read(len(wanted) + 1) == wanted.encode() + b"\0":
            return offset, size
    raise DeviceError(f"{elf.name} has no {wanted} section: is it the qemu variant?")


def _prepare_child() -> None:  # runs in the child between fork and exec
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)  # QEMU dies with its parent
    os.setpgrp()  # the terminal's Ctrl-C goes to the command, which stops QEMU in order
    try:  # where allowed: the emulated board is real-time work, as the engine is (render/engine/realtime.py)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(QEMU_FIFO_PRIORITY))
    except OSError:
        with contextlib.suppress(OSError):
            os.nice(QEMU_NICE)


def restart_events(boot: dict) -> list[dict]:
    """What a boot line after a reset says happened before it, as plate-sim's events: ``watchdog_reset`` (the
    hardware watchdog or its stand-in expired: a mark was missing) or ``board_fault`` (a fault handler ran, with the
    fault status register), then ``output_blanked`` with ``after_fault_ms``, the time the board measured on its
    own clock from an injected fault to the moment its output was silenced (the emulated DAC stopped and held at
    mid-scale); none for a power-on."""
    reason = boot.get("reset_reason")
    if reason in (None, "power-on"):
        return []
    t_s = boot["t_s"]
    found: list[dict] = []
    if reason == "watchdog":
        event = {"t_s": t_s, "event": "watchdog_reset"}
        for key in ("marks_seen", "looks_missed", "pc"):
            if key in boot:
                event[key] = boot[key]
        event["missing"] = [name for bit, name in ((1, "block interrupt"), (2, "main loop"))
                            if not boot.get("marks_seen", 0) & bit]
    elif reason == "fault":
        event = {"t_s": t_s, "event": "board_fault", "fault_status": boot.get("fault_status", 0)}
    else:
        event = {"t_s": t_s, "event": "reset", "reason": reason}
    if "injected" in boot:
        event["injected"] = boot["injected"]
    found.append(event)
    if isinstance(boot.get("silent_after_us"), int):
        found.append({"t_s": t_s, "event": "output_blanked", "after_fault_ms": boot["silent_after_us"] / 1000.0,
                      "injected": boot.get("injected"), "by": event["event"]})
    return found


def parse_event(line: str, t_s: float) -> dict | None:
    """One debug-console line of the board (``ev NAME key=value ...``) as an event dict, or None for other
    lines. Numbers become ints or floats; ``t_s`` is the board's own clock where the line gives it (the core's
    events, as plate-sim's), else ``t_s`` here (seconds since QEMU started); a refusal's NAK reason is put in
    words, as plate-sim puts it."""
    parts = line.strip().split()
    if len(parts) < 2 or parts[0] != "ev":
        return None
    event: dict = {"t_s": round(t_s, 4), "event": parts[1]}
    for part in parts[2:]:
        key, _, value = part.partition("=")
        try:
            event[key] = int(value)
        except ValueError:
            try:
                event[key] = float(value)
            except ValueError:
                event[key] = value
    if event.get("fault") == "bad-command" and isinstance(event.get("reason"), int):
        event["reason"] = NAK_REASONS.get(event["reason"], str(event["reason"]))
    return event


def _qmp_answer(replies, greeting: bool = False) -> dict:
    """QEMU's next answer on its machine protocol (its greeting, or a command's return), events passed over."""
    for line in replies:
        message = json.loads(line)
        if greeting and "QMP" in message:
            return message
        if "error" in message:
            raise ValueError(message["error"].get("desc", "an error"))
        if "return" in message:
            return message
    raise ValueError("QEMU closed its machine protocol")


class QemuPlate:
    """The board image running in QEMU; ``path`` is the link to give ``--device serial:PATH``.

    ``plate``: the emulated plate and declared profile (default: the image's own, the sim-plate profile).
    ``events`` receives the board's events (dicts with ``t_s`` and ``event``) and ``lines`` every line of
    its debug console. ``icount_shift``: run with QEMU's instruction counting (each instruction 2^shift ns of
    virtual time), for budgets; None runs the machine's own clock (``MACHINE_ICOUNT``: instruction counting held to
    real time for the mps2-an386, the host's clock for the netduinoplus2). ``machine``: QEMU's machine for
    the image (``boards.BOARD_INFO[board].machine``: ``netduinoplus2`` or ``mps2-an386``); the first ``-serial``
    is the board's link UART (USART1, UART0), the second its debug console (USART2, UART1).
    """

    def __init__(self, elf_path: str, link_path: str | None = None, icount_shift: int | None = None,
                 plate: EmulatedPlate | None = None, machine: str = MACHINE):
        if shutil.which(QEMU) is None:
            raise DeviceError(f"{QEMU} is not installed: install qemu-system-arm (apt-get; ./run tests does)")
        if not os.path.isfile(elf_path):
            raise DeviceError(f"no firmware image at {elf_path}: build it with `ultraglide firmware build`")
        self.elf_path = elf_path
        self.path, self._own_dir = link_path_for(link_path, "ultraglide-qemu-")
        self._claim = LinkClaim(self.path) if self._own_dir is None else None  # a path given: no other simulator's
        self.pty_name = ""
        self.icount_shift = icount_shift
        self.plate = plate
        self.machine = machine
        self.events: queue.Queue = queue.Queue(MAX_EVENTS)
        self.lines: queue.Queue = queue.Queue(MAX_EVENTS)
        # the raw reading behind each CLOCK reply (``ev clock_read``, 20 a second while a host listens), kept apart:
        # in ``events`` and ``lines`` they would fill those within minutes for a reader that drains neither
        self.clock_reads: queue.Queue = queue.Queue(MAX_EVENTS)
        self.process: subprocess.Popen | None = None
        self._started_at = 0.0
        self._reader: threading.Thread | None = None
        self._stderr_reader: threading.Thread | None = None
        self._stderr = b""
        self._booted = threading.Event()
        self._qmp_dir: str | None = None  # QEMU's machine protocol socket: the reset button (press_reset)

    def __repr__(self) -> str:
        state = f"pid {self.process.pid}" if self.process and self.process.poll() is None else "stopped"
        return f"QemuPlate({self.elf_path!r} on {self.path}, {state})"

    def command(self) -> list[str]:
        command = [QEMU, "-M", self.machine, "-nographic", "-monitor", "none", "-serial", "pty", "-serial", "stdio",
                   "-kernel", self.elf_path]
        if self._qmp_dir is not None:
            command += ["-qmp", f"unix:{os.path.join(self._qmp_dir, 'qmp.sock')},server=on,wait=off"]
        if self.icount_shift is not None:
            command += ["-icount", f"shift={self.icount_shift}"]
        elif self.machine in MACHINE_ICOUNT:
            command += ["-icount", MACHINE_ICOUNT[self.machine]]
        return command

    def start(self) -> QemuPlate:
        if self.plate is not None:  # QEMU runs a copy of the image with the plate's truth written in
            if self._own_dir is None:
                self._own_dir = tempfile.mkdtemp(prefix="ultraglide-qemu-")
            copy = os.path.join(self._own_dir, os.path.basename(self.elf_path))
            shutil.copyfile(self.elf_path, copy)
            self.plate.write_into(copy)
            self.elf_path = copy
        self._qmp_dir = tempfile.mkdtemp(prefix="ultraglide-qmp-")
        self.process = subprocess.Popen(self.command(), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, preexec_fn=_prepare_child)
        self._started_at = time.perf_counter()
        try:
            self.pty_name = self._wait_for_pty()
        except BaseException:
            self.stop()
            raise
        self._reader = threading.Thread(target=self._read_console, name="qemu-console", daemon=True)
        self._reader.start()
        try:
            self._wait_for_boot()
        except BaseException:
            self.stop()
            raise
        place_link(self.pty_name, self.path)
        return self

    def _wait_for_boot(self) -> None:
        """The link is published only once the firmware has booted: QEMU's USART drops bytes that arrive
        before the firmware enables it, so a host's single HELLO sent earlier would go unanswered."""
        deadline = time.monotonic() + START_TIMEOUT_S
        while not self._booted.wait(0.1):
            if not self.alive:
                raise DeviceError(f"QEMU stopped before the firmware booted (exit status {self.process.returncode})")
            if time.monotonic() > deadline:
                raise DeviceError(f"the firmware under QEMU did not boot within {START_TIMEOUT_S:g} s")

    def _wait_for_pty(self) -> str:
        """QEMU names the pty on its standard output as it starts, before the console's first byte."""
        assert self.process is not None and self.process.stdout is not None
        self._stderr_reader = threading.Thread(target=self._drain_stderr, name="qemu-stderr", daemon=True)
        self._stderr_reader.start()
        found: list[str] = []
        reader = threading.Thread(target=lambda: found.append(self.process.stdout.readline().decode(errors="replace")),
                                  daemon=True)
        reader.start()
        reader.join(START_TIMEOUT_S)
        line = found[0] if found else ""
        match = _PTY_LINE.search(line.encode())
        if match:
            return match.group(1).decode()
        if self.process.poll() is not None or not reader.is_alive():
            self.process.wait(STOP_TIMEOUT_S)
            message = self._stderr.decode(errors="replace").strip().splitlines()
            raise DeviceError(f"QEMU stopped at start: {message[-1] if message else line.strip() or 'no message'}")
        raise DeviceError(f"QEMU did not name its pseudo-terminal within {START_TIMEOUT_S:g} s")

    def _drain_stderr(self) -> None:
        assert self.process is not None and self.process.stderr is not None
        # stop() closes the pipe once QEMU has exited; should the read still be under way then (QEMU's stderr held
        # open by a child), the closed file ends it here rather than as the thread's exception
        with contextlib.suppress(ValueError, OSError):
            for line in self.process.stderr:
                self._stderr = (self._stderr + line)[-4096:]

    def _read_console(self) -> None:
        assert self.process is not None and self.process.stdout is not None
        for raw in self.process.stdout:
            text = raw.decode(errors="replace").rstrip("\r\n")
            t_s = time.perf_counter() - self._started_at
            event = parse_event(text, t_s)
            if event is not None and event["event"] == "clock_read":
                with contextlib.suppress(queue.Full):
                    self.clock_reads.put_nowait(event)
                continue
            with contextlib.suppress(queue.Full):
                self.lines.put_nowait(text)
            if event is not None:
                for each in [event, *(restart_events(event) if event["event"] == "boot" else [])]:
                    with contextlib.suppress(queue.Full):
                        self.events.put_nowait(each)
                if event["event"] in ("boot", "error"):
                    self._booted.set()

    def inject_fault(self, kind: str) -> None:
        """Make the board fail in one of FAULT_KINDS (its debug console's ``fault KIND`` command, QEMU image only):
        ``isr-hang`` the block interrupt stops, ``main-hang`` the main loop stops, ``stack-overflow`` the main
        loop recurses off the bottom of its stack, ``hard-fault`` it reads where nothing answers. The board then
        resets (by its watchdog or its fault handler) and its next boot line says why (``restart_events``)."""
        if kind not in FAULT_KINDS:
            raise DeviceError(f"no board fault {kind!r}: the kinds are {', '.join(FAULT_KINDS)}")
        if self.process is None or self.process.stdin is None or not self.alive:
            raise DeviceError("the board is not running: start it before injecting a fault")
        try:
            self.process.stdin.write(f"fault {kind}\n".encode())
            self.process.stdin.flush()
        except OSError as error:
            raise DeviceError(f"could not reach the board's console: {error.strerror or error}") from error

    def press_reset(self) -> None:
        """Reset the board as its reset button does: QEMU's ``system_reset`` (over its machine protocol), which
        resets the processor and every device but keeps the RAM, as a board whose power stays on. The firmware has
        no say in it, so it leaves no reset record; the next boot line says what the board could tell
        (``reset_reason`` ``pin``, ``reset_from=ram`` on a board that reads no reset-cause register)."""
        if self.process is None or self._qmp_dir is None or not self.alive:
            raise DeviceError("the board is not running: start it before pressing its reset")
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as qmp:
                qmp.settimeout(STOP_TIMEOUT_S)
                qmp.connect(os.path.join(self._qmp_dir, "qmp.sock"))
                replies = qmp.makefile("r", encoding="utf-8")
                _qmp_answer(replies, greeting=True)
                for command in ("qmp_capabilities", "system_reset"):
                    qmp.sendall(json.dumps({"execute": command}).encode() + b"\n")
                    _qmp_answer(replies)
        except (OSError, ValueError) as error:
            raise DeviceError(f"could not reset the board through QEMU: {error}") from error

    def elapsed_s(self) -> float:
        return time.perf_counter() - self._started_at

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self) -> int | None:
        """Stop QEMU (SIGTERM, then SIGKILL after 5 s) and remove the link; returns QEMU's exit status."""
        status = None
        if self.process is not None:
            if self.process.poll() is None:
                self.process.terminate()
                try:
                    self.process.wait(STOP_TIMEOUT_S)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()
            status = self.process.returncode
            for reader in (self._reader, self._stderr_reader):  # both pipes at their end before they are closed
                if reader is not None:
                    reader.join(STOP_TIMEOUT_S)
            for stream in (self.process.stdin, self.process.stdout, self.process.stderr):
                with contextlib.suppress(OSError, ValueError):
                    if stream is not None:
                        stream.close()
        remove_link(self.path, self.pty_name or None)  # only the link it made
        if self._qmp_dir is not None:
            shutil.rmtree(self._qmp_dir, ignore_errors=True)
            self._qmp_dir = None
        if self._claim is not None:
            self._claim.release()
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)
            self._own_dir = None
        return status

    def __enter__(self) -> QemuPlate:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
