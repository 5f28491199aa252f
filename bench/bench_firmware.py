"""The firmware's time budgets on its target (netduinoplus2: STM32F405, Cortex-M4F at 168 MHz; mps2-an386: Cortex-M4F
at 25 MHz), measured under QEMU.

Run: .venv/bin/python bench/bench_firmware.py [--board netduinoplus2|mps2-an386] [--json]
QEMU's -icount counts the instructions of each piece of real-time work in the bench image, which plays the
protocol's fastest stream (48 000 setpoints/s) for a second through the board's own port glue
(devices/firmware/budgets.py, ports/common/bench.c). The mps2-an386's bench clock counts 40 instructions at a time
(its 25 MHz PCLK at 1 ns an instruction): its figures are known to 40 instructions. Cycles are estimated at 2 an
instruction (a conservative bound, stated as an estimate), plus the interrupts' entries and returns; the load is a
second of that stream on the hardware image (its link by DMA), every frame and every block taken at its worst.
"""

from __future__ import annotations

import argparse
import json

from ultraglide.devices.firmware.budgets import BOARD_CORE_HZ, CALIBRATION, RESOLUTION, cycles, measure, stream_load

MODES = {"open_240": "240-value frames, open loop", "loop_240": "240-value frames, amplitude loop",
         "open_48": "48-value frames (1 ms), open loop", "loop_48": "48-value frames (1 ms), amplitude loop"}
PARTS = ("part_sense_240", "part_core_adc_block_48", "part_core_dac_block_240", "part_dac_codes_240",
         "part_core_tick", "part_core_status")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--board", choices=tuple(BOARD_CORE_HZ), default="netduinoplus2")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    core_hz = BOARD_CORE_HZ[args.board]
    run = measure(board=args.board)
    figures = run.figures
    loads = [stream_load(figures, mode, core_hz=core_hz) for mode in MODES]
    worst = min(loads, key=lambda load: load.headroom)
    if args.json:
        print(json.dumps({"board": args.board, "core_hz": core_hz, "resolution": RESOLUTION[args.board],
                          "figures": {name: vars(f) for name, f in figures.items()},
                          "counters": run.counters,
                          "loads": [{**vars(load), "cycles_per_s": load.cycles_per_s, "cpu_share": load.cpu_share,
                                     "headroom": load.headroom} for load in loads]}))
        return
    name, expected = CALIBRATION
    print(f"{args.board}: each figure to {RESOLUTION[args.board]} instruction(s) (its bench clock)")
    print(f"calibration: {figures[name].mean:.0f} instructions counted for {expected} in the loop's disassembly")
    print(f"{'work (instructions)':34} {'calls':>6} {'mean':>9} {'worst':>7} {'cycles, est.':>13}")
    for key, figure in figures.items():
        if key != name and (key.endswith("loop_48") or key.startswith("part_")) and not key.startswith(("tx_bytes",
                                                                                                       "masked")):
            print(f"{key:34} {figure.calls:6d} {figure.mean:9.1f} {figure.max:7d} {cycles(figure.max):13.0f}")
    print(f"\n{'a second at 48 000 setpoints/s':38} {'frame worst':>11} {'block worst':>11} {'CPU':>8} {'headroom':>9}")
    for load in loads:
        print(f"{MODES[load.mode]:38} {load.frame_instructions:11d} {load.block_instructions:11d} "
              f"{100 * load.cpu_share:7.1f}% {load.headroom:8.2f}x")
    masked = {mode: figures[f"masked_{mode}"] for mode in MODES if f"masked_{mode}" in figures}
    for mode, figure in masked.items():
        print(f"longest masked section (block interrupt held off), {MODES[mode]}: {figure.max} instructions "
              f"({figure.calls} sections)")
    if "masked_commands" in figures:
        print(f"longest masked section of a command (ENABLE 0 silencing the output, SET_LOOP, ENABLE 1): "
              f"{figures['masked_commands'].max} instructions")
    print(f"the streams: {run.counters['setpoints']} values buffered, {run.counters['overrun']} overrun, "
          f"{run.counters['underruns']} underruns")
    print(f"worst case: {MODES[worst.mode]}, {100 * worst.cpu_share:.1f} % of the CPU at {core_hz / 1e6:g} MHz: "
          f"{worst.headroom:.2f}x headroom (2 cycles an instruction)")


if __name__ == "__main__":
    main()
