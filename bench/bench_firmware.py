"""The firmware's time budgets on the target (netduinoplus2, Cortex-M4F at 168 MHz), measured under QEMU.

Run: .venv/bin/python bench/bench_firmware.py [--json]
QEMU's -icount counts the instructions of each piece of real-time work (devices/firmware/budgets.py,
ports/netduinoplus2/bench.c); cycles are estimated at 2 a instruction (a conservative bound, stated as an
estimate); the load is each piece's cycles at the rate the fastest stream the protocol allows makes it run.
"""

from __future__ import annotations

import json
import sys

from ultraglide.devices.firmware.budgets import CORE_HZ, cycles, measure

BLOCKS_PER_S = 1000  # carrier refills a second: 250-sample blocks at 250 kHz
LINK_BYTES_PER_S = 92_160  # a 921 600 baud UART full in both directions, 10 bits a byte
# how often each piece runs at the worst the protocol and board allow
RATES = {
    "calibration_2000": None,
    "dac_block_250": BLOCKS_PER_S,
    "emulated_plate_step": BLOCKS_PER_S,  # QEMU image only
    "uart_frame_80": LINK_BYTES_PER_S / 80,  # telemetry and replies queued, a frame of 80 bytes at a time
}


def main() -> None:
    figures = measure()
    rows = []
    load = 0.0
    for name, instructions in figures.items():
        rate = RATES.get(name)
        share = cycles(instructions) * rate / CORE_HZ if rate else None
        load += share or 0.0
        rows.append({"name": name, "instructions": instructions, "cycles_estimate": cycles(instructions),
                     "calls_per_s": rate, "cpu_share": share})
    result = {"core_hz": CORE_HZ, "rows": rows, "cpu_share_total": load,
              "headroom": (1.0 / load) if load else None}
    if "--json" in sys.argv:
        print(json.dumps(result))
        return
    print(f"{'work':24} {'instructions':>12} {'cycles (est.)':>14} {'calls/s':>9} {'CPU at 168 MHz':>15}")
    for row in rows:
        share = f"{100 * row['cpu_share']:.3f} %" if row["cpu_share"] is not None else "(calibration)"
        calls = f"{row['calls_per_s']:.0f}" if row["calls_per_s"] else ""
        print(f"{row['name']:24} {row['instructions']:12.1f} {row['cycles_estimate']:14.0f} {calls:>9} {share:>15}")
    print(f"total {100 * load:.2f} % of the CPU: headroom {result['headroom']:.0f}x")


if __name__ == "__main__":
    main()
