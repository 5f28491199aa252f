"""Export speed and memory: the whole ``ultraglide export`` command against sox.

Run: .venv/bin/python bench/bench_export.py [--minutes 10]
Aim (issue 4): a 10-minute textured swipe at 96 kHz to float32 WAV within 1.5x of the time
`sox -n -r 96000 out.wav synth 600 sine 25000` takes; peak memory independent of the length.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time


def run(command: list[str]) -> tuple[float, float]:
    """Wall time (s) and peak resident memory (MB) of one command (os.wait4: that child alone)."""
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(child.pid, 0)
    elapsed = time.perf_counter() - start
    if status != 0:
        raise SystemExit(f"{' '.join(command)} failed")
    return elapsed, usage.ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--minutes", type=float, default=10.0)
    minutes = parser.parse_args().minutes
    seconds = int(minutes * 60)
    ultraglide = [sys.executable, "-m", "ultraglide", "export", "wood", "--path", "zigzag"]
    with tempfile.TemporaryDirectory() as directory:
        out = os.path.join(directory, "out.wav")
        sox_s, sox_mb = min(run(["sox", "-n", "-r", "96000", out, "synth", str(seconds), "sine", "25000"])
                            for _ in range(3))
        ours_s, ours_mb = min(run(ultraglide + ["--duration-s", str(seconds), "-o", out]) for _ in range(3))
        _, short_mb = run(ultraglide + ["--duration-s", str(max(seconds // 10, 1)), "-o", out])
    print(f"{'':28} {'time s':>8} {'peak MB':>8}")
    print(f"{'sox, plain carrier':28} {sox_s:8.2f} {sox_mb:8.0f}")
    print(f"{'ultraglide export, textured':28} {ours_s:8.2f} {ours_mb:8.0f}   ({ours_s / sox_s:.2f}x sox)")
    print(f"{'ultraglide, a tenth as long':28} {'':>8} {short_mb:8.0f}   (memory does not grow with length)")
    print(f"({seconds} s at 96 kHz, float32 WAV, best of 3)")


if __name__ == "__main__":
    main()
