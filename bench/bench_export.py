"""Export speed and memory: the whole ``ultraglide export`` command against sox.

Run: .venv/bin/python bench/bench_export.py [--minutes 10] [--runs 3]
Aim (issue 13): a 10-minute textured zig-zag at 96 kHz to a float32 WAV in at most 0.7x the time
`sox -n -r 96000 out.wav synth 600 sine 25000` takes; peak memory independent of the length.

sox and the export run alternately (sox, export, sox, export, ...), so a change in the machine's
load touches both alike; the figures are medians. Each run is a whole command in a fresh process
(imports, numba's cache, rendering, writing), timed by wall clock, with its CPU time (user + system,
all threads) and peak resident memory from os.wait4. Also: ``ultraglide --help``'s wall time.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time


def run(command: list[str]) -> tuple[float, float, float]:
    """Wall time (s), CPU time (s, user + system) and peak resident memory (MB) of one command."""
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(child.pid, 0)
    elapsed = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"{' '.join(command)} failed")
    return elapsed, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def load_average() -> str:
    return " ".join(f"{value:.1f}" for value in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--runs", type=int, default=3, help="runs of each command, alternating (default: 3)")
    options = parser.parse_args()
    seconds = int(options.minutes * 60)
    ultraglide = [sys.executable, "-m", "ultraglide"]
    export = ultraglide + ["export", "wood", "--path", "zigzag"]
    before = load_average()
    with tempfile.TemporaryDirectory() as directory:
        out = os.path.join(directory, "out.wav")
        run(export + ["--duration-s", "1", "-o", out])  # numba's cache filled, files in the page cache
        sox, ours = [], []
        for _ in range(options.runs):
            sox.append(run(["sox", "-n", "-r", "96000", out, "synth", str(seconds), "sine", "25000"]))
            ours.append(run(export + ["--duration-s", str(seconds), "-o", out]))
        _, _, short_mb = run(export + ["--duration-s", str(max(seconds // 10, 1)), "-o", out])
        helps = [run(ultraglide + ["--help"])[0] for _ in range(options.runs)]
    median = [statistics.median(column) for column in zip(*sox, strict=True)]
    mine = [statistics.median(column) for column in zip(*ours, strict=True)]
    ratios = [o[0] / s[0] for s, o in zip(sox, ours, strict=True)]
    print(f"{'':30} {'wall s':>8} {'CPU s':>8} {'peak MB':>8}")
    print(f"{'sox, plain carrier':30} {median[0]:8.2f} {median[1]:8.2f} {median[2]:8.0f}")
    print(f"{'ultraglide export, textured':30} {mine[0]:8.2f} {mine[1]:8.2f} {mine[2]:8.0f}   "
          f"({mine[0] / median[0]:.2f}x sox's median; pairwise {', '.join(f'{r:.2f}' for r in ratios)})")
    print(f"{'ultraglide, a tenth as long':30} {'':>8} {'':>8} {short_mb:8.0f}   (memory does not grow with length)")
    print(f"{'ultraglide --help':30} {statistics.median(helps):8.2f}")
    print(f"({seconds} s at 96 kHz, float32 WAV; medians of {options.runs} alternating runs; "
          f"load average {before} before, {load_average()} after, on {os.cpu_count()} CPUs)")


if __name__ == "__main__":
    main()
