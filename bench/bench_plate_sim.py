"""What the simulated plate costs: the firmware core in the loop (C) and the plate's physics (Python).

    .venv/bin/python bench/bench_plate_sim.py

1. In this process, a 12 kHz stream in 1 ms frames played for 10 s of the simulator's time as fast as it goes:
   CPU per second of simulated time, open loop and with the amplitude loop on (0.25 ms physics blocks).
2. ``ultraglide plate-sim`` in its own process: its CPU while nothing is connected (it wakes for telemetry
   only), and while ``ultraglide play grating-1mm --device serial:LINK`` streams to it for 10 s (the real link,
   the real host, 1 ms frames of 12 values, 2 ms output ticks).
Prints the load average beside the figures: other work on the machine slows both.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.plate import PlateSimulator

ROOT = Path(__file__).resolve().parent.parent
TICKS = os.sysconf("SC_CLK_TCK")


def in_process(loop: bool, seconds: float = 10.0) -> float:
    """CPU seconds per simulated second: frames in, 2 ms advances, telemetry out."""
    sim = PlateSimulator(load_profile("sim-plate"))
    seq = 0

    def send(kind: int, payload: bytes) -> None:
        nonlocal seq
        seq += 1
        sim.receive(p.encode_frame(kind, seq, payload))

    if loop:
        send(p.SET_LOOP, b"\x01")
    send(p.ENABLE, p.enable_payload(True))
    frames = [p.encode_frame(p.SETPOINTS, k, p.setpoints_payload(12 * k, 12000, 0.3 + 0.2 * np.sin(np.arange(12) + k)))
              for k in range(int(seconds * 1000))]
    t = sim._clock
    started = time.process_time()
    for k, frame in enumerate(frames):
        sim.receive(frame)
        if k % 2:
            t += 0.002
            sim.advance(t)
    return (time.process_time() - started) / seconds


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def plate_sim_process() -> tuple[float, float]:
    with tempfile.TemporaryDirectory() as folder:
        link = Path(folder) / "plate"
        server = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--link", str(link), "--json"],
                                  stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=ROOT)
        try:
            json.loads(server.stdout.readline())
            time.sleep(2.0)  # imports done, serving
            before, wall = cpu_seconds(server.pid), time.monotonic()
            time.sleep(10.0)
            idle = (cpu_seconds(server.pid) - before) / (time.monotonic() - wall)
            before, wall = cpu_seconds(server.pid), time.monotonic()
            subprocess.run([sys.executable, "-m", "ultraglide", "play", "grating-1mm", "--device", f"serial:{link}",
                            "--profile", "sim-plate", "--duration-s", "10"], check=True, capture_output=True, cwd=ROOT,
                           timeout=120)
            streaming = (cpu_seconds(server.pid) - before) / (time.monotonic() - wall)
        finally:
            server.terminate()
            server.wait(timeout=30)
    return idle, streaming


def main() -> int:
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    for loop in (False, True):
        cost = in_process(loop)
        print(f"in process, {'amplitude loop' if loop else 'open loop':14}: {1000 * cost:6.1f} ms of CPU a second "
              f"({100 * cost:.1f} % of a core)")
    idle, streaming = plate_sim_process()
    print(f"plate-sim process, idle       : {100 * idle:.1f} % of a core")
    print(f"plate-sim process, play 12 kHz: {100 * streaming:.1f} % of a core (including the play's start-up)")
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
