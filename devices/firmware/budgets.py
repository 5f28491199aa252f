"""The firmware's time budgets on the target, measured: the ``bench`` image under QEMU's instruction counting.

``-icount shift=0`` makes every guest instruction take 1 ns of virtual time, and the image reads its board's
bench clock before and after each piece of real-time work: the netduinoplus2's TIM5, which counts virtual
nanoseconds under QEMU 7.2 (``ports/netduinoplus2/board.h``), so the difference is the instructions it ran; the
mps2-an386's TIMER1, which counts its 25 MHz PCLK, so each count is 40 instructions and a figure is known to 40
(:data:`RESOLUTION`). A two-instruction loop of known length calibrates the reading.
The image plays the protocol's fastest stream, 48 000 setpoints/s, for a second each way it can
arrive (240-value frames in open loop and in the amplitude loop, 48-value 1 ms frames) through the same port
glue the board image runs (``ports/common/bench.c``). Cycles are *estimated* from instructions: QEMU
counts instructions, not cycles; a Cortex-M4 takes one cycle for most instructions, two or more for loads,
taken branches, divisions and square roots, and waits on flash behind the ART accelerator;
:data:`CYCLES_PER_INSTRUCTION` = 2 is a conservative bound for this code.

Example::

    run = measure()                # run.figures["block_loop_48"]: Figure(calls=1000, mean=..., max=...)
    stream_load(run.figures, "loop_48").headroom
"""

from __future__ import annotations

import re
import shutil
import subprocess
import threading
from dataclasses import dataclass, field

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.firmware.boards import BOARD_INFO, build_images
from ultraglide.devices.firmware.qemu import parse_event

CORE_HZ = 168_000_000  # the netduinoplus2's; each board's in BOARD_CORE_HZ
BOARD_CORE_HZ = {"netduinoplus2": 168_000_000, "mps2-an386": 25_000_000}  # the boards' board.h BOARD_CORE_HZ
RESOLUTION = {"netduinoplus2": 1, "mps2-an386": 40}  # instructions a count of the bench clock (BOARD_BENCH_PER_COUNT)
CYCLES_PER_INSTRUCTION = 2.0
CALIBRATION = ("calibration_2006", 2003)  # bl, mov.w, 1000 x (subs, bne), bx: counted in its disassembly
RUN_TIMEOUT_S = 120.0
ISR_CYCLES = 36  # an interrupt's entry (12 cycles) and return (12, no FPU state stacked) and its handler's own
# register reads and tests (about 12): the work QEMU's figures leave out, estimated from the Cortex-M4 manual
_LINE = re.compile(r"^bench (\S+) calls=(\d+) mean=([\d.]+) max=(\d+) total=(\d+)")


@dataclass(frozen=True)
class Figure:
    """One piece of work timed over ``calls`` calls: instructions per call (mean and worst) and in all."""

    calls: int
    mean: float
    max: int
    total: int

    def __repr__(self) -> str:
        return f"Figure({self.calls} calls: {self.mean:.1f} instructions a call, worst {self.max})"


@dataclass(frozen=True)
class BenchRun:
    """The bench image's figures by name, and the core's counters at its end (``setpoints``, ``overrun``, ...:
    every value of the streams it played must have been buffered, none overrun, none late), and its boot line as
    an event (``{"event": "boot", "board": ..., "variant": "bench", ...}``; empty if it printed none)."""

    figures: dict
    counters: dict
    boot: dict = field(default_factory=dict)


def measure(out_dir: str | None = None, board: str = "netduinoplus2") -> BenchRun:
    """Each benchmark of ``board``'s bench image, run under QEMU with ``-icount shift=0``."""
    if shutil.which("qemu-system-arm") is None:
        raise DeviceError("qemu-system-arm is not installed: install it (apt-get; ./run tests does)")
    image = build_images(board, ["bench"], out_dir=out_dir)[0]
    command = ["qemu-system-arm", "-M", BOARD_INFO[board].machine, "-nographic", "-monitor", "none", "-serial", "null",
               "-serial", "stdio", "-icount", "shift=0", "-kernel", image.elf_path]
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               text=True)
    figures: dict[str, Figure] = {}
    counters: dict[str, int] = {}
    boot: dict = {}
    timer = threading.Timer(RUN_TIMEOUT_S, process.kill)
    timer.daemon = True
    timer.start()
    try:
        for line in process.stdout:
            if line.startswith("bench done"):
                counters = {key: int(value) for key, value in re.findall(r"(\w+)=(\d+)", line)}
                break
            if line.startswith("ev boot ") and not boot:
                boot = parse_event(line, 0.0) or {}
            found = _LINE.match(line)
            if found:
                name, calls, mean, worst, total = found.groups()
                figures[name] = Figure(int(calls), float(mean), int(worst), int(total))
    finally:
        timer.cancel()
        process.kill()
        process.wait()
        process.stdout.close()
    if not figures or not counters:
        raise DeviceError("the bench image did not finish under QEMU")
    return BenchRun(figures, counters, boot)


def cycles(instructions: float) -> float:
    """The cycle estimate for an instruction count (see the module's docstring)."""
    return instructions * CYCLES_PER_INSTRUCTION


@dataclass(frozen=True)
class Load:
    """The CPU a second of the fastest stream takes on the target, for one way it arrives (``mode``)."""

    mode: str
    frame_instructions: int     # one SETPOINTS frame, worst: handed over from the DMA's buffer, decoded, buffered
    frame_values: int
    frames_per_s: float
    block_instructions: int     # one 1 ms block, worst: sensing, the core's ADC and DAC blocks, its tick
    instructions_per_s: float   # frames, blocks, the polls after them and the bytes sent back
    isr_cycles_per_s: float     # the interrupts' entries, returns and register reads (estimated: ISR_CYCLES)
    core_hz: int = CORE_HZ      # the board's processor clock

    @property
    def cycles_per_s(self) -> float:
        return cycles(self.instructions_per_s) + self.isr_cycles_per_s

    @property
    def cpu_share(self) -> float:
        return self.cycles_per_s / self.core_hz

    @property
    def headroom(self) -> float:
        return 1.0 / self.cpu_share


def stream_load(figures: dict[str, Figure], mode: str, rate_hz: int = 48_000, core_hz: int = CORE_HZ) -> Load:
    """The hardware image's load for a second of a ``rate_hz`` stream in ``mode`` (``open_240``, ``loop_240``,
    ``open_48``, ``loop_48``): every frame and every block at its worst; the polls after the blocks and the bytes
    queued for the host as measured over that second; an interrupt a block and one a frame (the link's idle line)."""
    poll, handed = figures[f"frame_poll_{mode}"], figures[f"rx_frame_{mode}"]
    block, tick, tx = figures[f"block_{mode}"], figures[f"tick_poll_{mode}"], figures[f"tx_chunk_{mode}"]
    values = int(mode.rsplit("_", 1)[1])
    frames_per_s = rate_hz / values
    frame = handed.max + poll.max
    per_s = frames_per_s * frame + 1000 * block.max + tick.total + tx.total
    return Load(mode, frame, values, frames_per_s, block.max, per_s, (1000 + frames_per_s) * ISR_CYCLES, core_hz)
