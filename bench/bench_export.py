"""Export speed and memory: the whole ``ultraglide export`` command against sox.

Run: .venv/bin/python bench/bench_export.py [--minutes 10] [--runs 3]
Aim (issues 13 and 21): a 10-minute export at 96 kHz to a float32 WAV in at most 0.7x the time
`sox -n -r 96000 out.wav synth 600 sine 25000` takes, for both sources of finger positions: a
procedural zig-zag (``--path zigzag``) and a recorded touch log replayed (``--trajectory``, a
120 Hz log of 72 000 rows for 10 minutes, made here: a finger sweeping to and fro across the
texture, with the panel's timing jitter and a varying force); peak memory independent of the length.

sox and the two exports run in turn (sox, zig-zag, log, sox, ...), so a change in the machine's
load touches all alike; the figures are medians. Each run is a whole command in a fresh process
(imports, numba's cache, rendering, writing), timed by wall clock, with its CPU time (user + system,
all threads) and peak resident memory from os.wait4. Also: ``ultraglide --help``'s wall time. A first
short export, not timed, leaves numba's cache and Python's bytecode (``__pycache__``) as an
installed package has them, even where PYTHONDONTWRITEBYTECODE is set.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time


def run(command: list[str], env: dict | None = None) -> tuple[float, float, float]:
    """Wall time (s), CPU time (s, user + system) and peak resident memory (MB) of one command."""
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    _, status, usage = os.wait4(child.pid, 0)
    elapsed = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"{' '.join(command)} failed")
    return elapsed, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def write_touch_log(path: str, seconds: float, rate_hz: float = 120.0) -> int:
    """A touch log as a panel records one: ``rate_hz`` reports with ±1 ms of jitter, a finger sweeping 64 mm to
    and fro every 1.4 s and drifting slowly up and down the texture, pressing 0.3-0.7 N. Returns its rows."""
    import numpy as np

    rng = np.random.default_rng(7)
    t = np.sort(np.arange(int(seconds * rate_hz)) / rate_hz + rng.uniform(-0.001, 0.001, int(seconds * rate_hz)))
    x = 40.0 + 32.0 * np.sin(2 * np.pi * t / 1.4)
    y = 26.0 + 15.0 * np.sin(2 * np.pi * t / 23.0)
    force = 0.5 + 0.2 * np.sin(2 * np.pi * t / 7.0)
    with open(path, "w") as stream:
        stream.write("t_s,x_mm,y_mm,force_n\n")
        np.savetxt(stream, np.column_stack([t - t[0], x, y, force]), fmt="%.5f", delimiter=",")
    return len(t)


def load_average() -> str:
    return " ".join(f"{value:.1f}" for value in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--runs", type=int, default=3, help="runs of each command, in turn (default: 3)")
    options = parser.parse_args()
    seconds = int(options.minutes * 60)
    ultraglide = [sys.executable, "-m", "ultraglide"]
    before = load_average()
    with tempfile.TemporaryDirectory() as directory:
        out = os.path.join(directory, "out.wav")
        log = os.path.join(directory, "touches.csv")
        rows = write_touch_log(log, seconds)
        exports = {"zig-zag (--path zigzag)": ultraglide + ["export", "wood", "--path", "zigzag",
                                                             "--duration-s", str(seconds)],
                   "touch log (--trajectory)": ultraglide + ["export", "wood", "--trajectory", log]}
        # numba's cache, and Python's bytecode of every module the command imports, as an installed package has it
        # (pip compiles it at install): a shell with PYTHONDONTWRITEBYTECODE set would otherwise have every run
        # compile our modules from source again (0.1 s of CPU), which no user's command does
        writing = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
        run(ultraglide + ["export", "wood", "--path", "zigzag", "--duration-s", "1", "-o", out], env=writing)
        sox: list = []
        ours: dict[str, list] = {name: [] for name in exports}
        for _ in range(options.runs):
            sox.append(run(["sox", "-n", "-r", "96000", out, "synth", str(seconds), "sine", "25000"]))
            for name, command in exports.items():
                ours[name].append(run(command + ["-o", out]))
        _, _, short_mb = run(ultraglide + ["export", "wood", "--path", "zigzag", "--duration-s",
                                           str(max(seconds // 10, 1)), "-o", out])
        helps = [run(ultraglide + ["--help"])[0] for _ in range(options.runs)]
    median = [statistics.median(column) for column in zip(*sox, strict=True)]
    print(f"{'':34} {'wall s':>8} {'CPU s':>8} {'peak MB':>8}")
    print(f"{'sox, plain carrier':34} {median[0]:8.2f} {median[1]:8.2f} {median[2]:8.0f}")
    for name, runs in ours.items():
        mine = [statistics.median(column) for column in zip(*runs, strict=True)]
        ratios = [o[0] / s[0] for s, o in zip(sox, runs, strict=True)]
        print(f"{'export, ' + name:34} {mine[0]:8.2f} {mine[1]:8.2f} {mine[2]:8.0f}   "
              f"({mine[0] / median[0]:.2f}x sox's median; pairwise {', '.join(f'{r:.2f}' for r in ratios)})")
    print(f"{'export, zig-zag a tenth as long':34} {'':>8} {'':>8} {short_mb:8.0f}   "
          "(memory does not grow with length)")
    print(f"{'ultraglide --help':34} {statistics.median(helps):8.2f}")
    print(f"({seconds} s at 96 kHz, float32 WAV, the log {rows} rows at 120 Hz; medians of {options.runs} runs in "
          f"turn; load average {before} before, {load_average()} after, on {os.cpu_count()} CPUs)")


if __name__ == "__main__":
    main()
