"""The firmware core's work per event in instructions, counted by valgrind's callgrind on this machine (x86-64,
gcc -O2): the budgets handed to the board port, which measures the same core on its target (bench_firmware.py).

    .venv/bin/python bench/bench_firmware_core.py

Builds bench/firmware_core_budget.c with the core and the simulator's port, runs it under callgrind, and prints
the largest instruction count of each operation over its repetitions (a SETPOINTS frame from its UART bytes
to the buffer; a 1 ms carrier block of 48 drive and 192 DAC samples; an ADC block; a tick), then what the
fastest stream the protocol allows costs a second (48 000 setpoints/s in 2 ms frames of 96 values, with 1 ms
carrier and ADC blocks and 1000 ticks).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "devices" / "firmware"


def main() -> int:
    for tool in ("gcc", "valgrind"):
        if shutil.which(tool) is None:
            print(f"bench_firmware_core: needs {tool} (apt-get install {tool})", file=sys.stderr)
            return 1
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        program = work / "budget"
        sources = sorted(str(path) for path in (FIRMWARE / "core").glob("*.c")) + [str(FIRMWARE / "ports/sim/ug_sim.c")]
        subprocess.run(["gcc", "-std=c11", "-O2", "-g", f"-I{FIRMWARE / 'include'}", f"-I{FIRMWARE / 'core'}",
                        f"-I{FIRMWARE / 'ports' / 'sim'}", *sources, str(ROOT / "bench" / "firmware_core_budget.c"),
                        "-lm", "-o", str(program)], check=True)
        subprocess.run(["valgrind", "--tool=callgrind", "--collect-atstart=yes", f"--callgrind-out-file={work}/cg.%p",
                        str(program)], check=True, capture_output=True, cwd=work)
        worst: dict[str, int] = defaultdict(int)
        counts: dict[str, int] = defaultdict(int)
        for dump in work.glob("cg.*"):
            text = dump.read_text(errors="replace")
            label = re.search(r"^desc: Trigger: Client Request: (.+)$", text, re.M)
            total = re.search(r"^(?:summary|totals): (\d+)", text, re.M)
            if label and total:
                worst[label.group(1)] = max(worst[label.group(1)], int(total.group(1)))
                counts[label.group(1)] += 1
    order = ["SETPOINTS 12 values", "SETPOINTS 240 values", "SETPOINTS 96 values at 48 kHz",
             "carrier block open loop", "carrier block amplitude loop", "ADC block open loop",
             "ADC block amplitude loop", "tick and poll", "tick and poll with a frame to send",
             "SETPOINTS_FORCE 12 values", "SETPOINTS_FORCE 240 values", "carrier block loop, force correction",
             "ADC block loop, force correction"]
    print(f"{'operation':44} {'instructions (worst of n)':>28}")
    for label in order:
        print(f"{label:44} {worst[label]:>20} (n={counts[label]})")
    per_second = (500 * worst["SETPOINTS 96 values at 48 kHz"] + 1000 * worst["carrier block amplitude loop"]
                  + 1000 * worst["ADC block amplitude loop"] + 1000 * worst["tick and poll with a frame to send"])
    print(f"the fastest stream (48 000 setpoints/s in 2 ms frames), the loop on, every tick sending a frame: "
          f"{per_second / 1e6:.1f} M instructions a second on x86-64")
    return 0


if __name__ == "__main__":
    sys.exit(main())
