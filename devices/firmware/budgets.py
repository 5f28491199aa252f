"""The firmware's time budgets on the target, measured: the ``bench`` image under QEMU's instruction counting.

``-icount shift=0`` makes every guest instruction take 1 ns of virtual time; the image times each piece of
real-time work with SysTick (which counts the 168 MHz core clock of virtual time) over many calls and prints
instructions per call on its debug console (``ports/netduinoplus2/bench.c``); a two-instruction loop of known
length calibrates the reading. Cycles are *estimated* from instructions: QEMU counts instructions, not cycles,
and a Cortex-M4 takes one cycle for most instructions, two or more for loads, taken branches and divisions, and
waits on flash behind the ART accelerator; :data:`CYCLES_PER_INSTRUCTION` = 2 is a conservative bound.

Example::

    figures = measure()            # {"dac_block_250": 3265.0, ...} instructions per call
"""

from __future__ import annotations

import re
import shutil
import subprocess

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.firmware.boards import build_images

CORE_HZ = 168_000_000
CYCLES_PER_INSTRUCTION = 2.0
CALIBRATION = ("calibration_2000", 2006)  # 1000 turns of subs/bne, the call's own instructions: 2006 by hand
RUN_TIMEOUT_S = 120.0
_LINE = re.compile(r"^bench (\S+) reps=(\d+) instructions=([\d.]+)")


def measure(out_dir: str | None = None) -> dict[str, float]:
    """Instructions per call of each benchmark in the bench image, run under QEMU with ``-icount shift=0``."""
    if shutil.which("qemu-system-arm") is None:
        raise DeviceError("qemu-system-arm is not installed: install it (apt-get; ./run tests does)")
    image = build_images("netduinoplus2", ["bench"], out_dir=out_dir)[0]
    command = ["qemu-system-arm", "-M", "netduinoplus2", "-nographic", "-monitor", "none", "-serial", "null",
               "-serial", "stdio", "-icount", "shift=0", "-kernel", image.elf_path]
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               text=True)
    figures: dict[str, float] = {}
    try:
        timer = _kill_after(process, RUN_TIMEOUT_S)
        for line in process.stdout:
            if line.startswith("bench done"):
                break
            found = _LINE.match(line)
            if found:
                figures[found.group(1)] = float(found.group(3))
        timer.cancel()
    finally:
        process.kill()
        process.wait()
        process.stdout.close()
    if not figures:
        raise DeviceError("the bench image printed no figures under QEMU")
    return figures


def _kill_after(process: subprocess.Popen, seconds: float):
    import threading

    timer = threading.Timer(seconds, process.kill)
    timer.daemon = True
    timer.start()
    return timer


def cycles(instructions: float) -> float:
    """The cycle estimate for an instruction count (see the module's docstring)."""
    return instructions * CYCLES_PER_INSTRUCTION
