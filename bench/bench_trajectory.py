"""Trajectory CSVs: reading speed (rows/s) and peak memory for 72 k and 10 M rows (issue 13).

Writes two touch logs to a temporary directory, then measures, each in its own process so that
peak memory (ru_maxrss) belongs to that step alone:

* check: ``check_touch_log``, the streaming pass that parses and checks every row;
* render: the same, then the finger state at 12 kHz over the whole log in 1 s blocks, as
  ``export`` asks for it (the window moving forward through the file);
* export: ``ultraglide export --trajectory`` to an int16 WAV, the real command;
* play: ``ultraglide play --trajectory --device null``, the real command, 10 M rows only (it runs
  in real time: that log spans 20 s).

Run: ``.venv/bin/python bench/bench_trajectory.py [72k] [10M] [--quick]`` (a few minutes; ``--quick``
skips play).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

LOGS = {  # rows, span of the log in seconds
    "72k": (72_000, 600.0),  # ten minutes of a 120 Hz touch panel
    "10M": (10_000_000, 20.0),  # far denser than any panel, to stress rows, not seconds
}


def write_log(path: Path, rows: int, span_s: float) -> None:
    """A swipe back and forth across 80 mm with a varying force, ``rows`` rows over ``span_s``."""
    with open(path, "w") as stream:
        stream.write("# bench_trajectory.py\nt_s,x_mm,y_mm,force_n\n")
        for first in range(0, rows, 500_000):
            k = np.arange(first, min(rows, first + 500_000))
            t = 1000.0 + k * (span_s / rows)
            phase = 2 * np.pi * t / 4.0
            np.savetxt(stream, np.column_stack([t, 40 + 35 * np.sin(phase), 25 + 10 * np.cos(phase),
                                                0.5 + 0.2 * np.sin(3 * phase)]), fmt="%.6f", delimiter=",")


def step(kind: str, path: str) -> None:
    """Run one measurement in this process and print its figures."""
    from ultraglide.render.touch_log import check_touch_log

    started, cpu = time.perf_counter(), time.process_time()
    log = check_touch_log(path)
    checked, checked_cpu = time.perf_counter() - started, time.process_time() - cpu
    figures = (f"check {log.rows / checked / 1e6:.2f} M rows/s ({checked:.2f} s; "
               f"{log.rows / checked_cpu / 1e6:.2f} M rows per CPU second)")
    if kind == "render":
        trajectory = log.trajectory()
        started, cpu = time.perf_counter(), time.process_time()
        offsets = np.arange(12_000) / 12_000.0
        t = 0.0
        while t <= trajectory.end_s:
            trajectory.state(t + offsets)
            t += 1.0
        took, took_cpu = time.perf_counter() - started, time.process_time() - cpu
        figures += (f", then the finger at 12 kHz over {trajectory.end_s:g} s of log in {took:.2f} s "
                    f"({took_cpu:.2f} CPU s)")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  {kind:7} {figures}; peak {peak_mb:.0f} MB", flush=True)
    print(f"          (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)", flush=True)


def run_cli(args: list[str]) -> tuple[float, float, float]:
    """Wall time (s), CPU time (s) and peak memory (MB) of ``ultraglide ARGS`` in a subprocess."""
    started = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", *args], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    error = process.stderr.read().decode().strip()
    if process.returncode:
        print(f"  failed: {error}")
    return time.perf_counter() - started, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main() -> None:
    if len(sys.argv) == 3:
        step(sys.argv[1], sys.argv[2])
        return
    quick = "--quick" in sys.argv
    only = [name for name in LOGS if name in sys.argv] or list(LOGS)
    with tempfile.TemporaryDirectory() as directory:
        for name in only:
            rows, span_s = LOGS[name]
            path = Path(directory) / f"{name}.csv"
            write_log(path, rows, span_s)
            print(f"{name}: {rows:,} rows over {span_s:g} s, {path.stat().st_size / 1e6:.0f} MB of CSV", flush=True)
            for kind in ("check", "render"):
                subprocess.run([sys.executable, __file__, kind, str(path)], check=True)
            out = Path(directory) / "out.wav"
            took, cpu, peak = run_cli(["export", "grating-1mm", "--trajectory", str(path), "-o", str(out),
                                       "--format", "int16"])
            print(f"  export  {took:.1f} s ({cpu:.1f} CPU s) for {span_s:g} s of 96 kHz audio; peak {peak:.0f} MB",
                  flush=True)
            out.unlink(missing_ok=True)
            if name == "10M" and not quick:
                took, cpu, peak = run_cli(["play", "grating-1mm", "--trajectory", str(path), "--device", "null"])
                print(f"  play    {took:.1f} s ({cpu:.1f} CPU s; the log spans {span_s:g} s); peak {peak:.0f} MB",
                      flush=True)
            path.unlink()


if __name__ == "__main__":
    main()
