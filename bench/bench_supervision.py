"""How fast a lost engine is made safe (issue 45): from the engine's death or freeze to the plate disabled and to
the command's exit.

Run: .venv/bin/python bench/bench_supervision.py [--runs 3]

Each run starts ``ultraglide play grating-1mm --duration-s 60`` as a user would (a process of its own) and, once it
plays, kills (SIGKILL: dead) or stops (SIGSTOP: frozen) its engine process, the time taken just before the signal
is sent. Two devices:

* **pty plate**: ``--device serial:PATH``, the simulated plate served on a real pty in this process, every frame it
  decodes stamped as it arrives: the time to the ENABLE 0 the command sends after its engine is gone;
* **sim**: ``--device sim``, the simulated plate inside the engine (it ends with the engine's process: disabled at
  the death itself); the time to the command's exit, and its own words for when it noticed.

The signal goes once the command has said which plate it plays on (its replay has begun) and its envelope log has
2 MB in it. (A loss before that, while the first touch reports are still being made, numba loading the
trajectory's path, ends the run as fast: they are made on a thread of their own, apps/commands/play.py.)

Aims (issue 45): dead 100 ms, frozen 250 ms, both to the plate disabled and to the command's exit (its status 7
read by this process). Prints a table with both, and the machine's load average before and after (figures from
a loaded machine are inflated: the command's threads wait for a core); with ``--json``, the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
AIMS_MS = {"dead": 100.0, "frozen": 250.0}


def engine_of(pid: int, timeout_s: float = 120.0) -> int:
    """The command's engine: its child that is not multiprocessing's resource tracker."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        found = []
        for entry in os.listdir("/proc"):
            if not entry.isdigit():
                continue
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
                cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid and b"resource_tracker" not in cmdline:
                found.append(int(entry))
        if len(found) == 1:
            return found[0]
        time.sleep(0.05)
    raise RuntimeError("the command's engine never appeared")


class StampedPlate:
    """The simulated plate on a pty, every ENABLE 0 it decodes stamped (perf_counter s)."""

    def __init__(self):
        from ultraglide.devices import protocol as p
        from ultraglide.devices.profiles import load_profile
        from ultraglide.devices.sim.pty_plate import PtyPlate

        self.plate = PtyPlate(load_profile("sim-plate")).start()
        self.disables: list[float] = []
        simulator = self.plate.simulator
        receive, decoder = simulator.receive, p.FrameDecoder()
        off = p.enable_payload(False)

        def stamped(data):
            now = time.perf_counter()
            replies = receive(data)
            for frame in decoder.feed(data):
                if frame.kind == p.ENABLE and frame.payload == off:
                    self.disables.append(now)
            return replies

        simulator.receive = stamped

    def close(self) -> None:
        self.plate.stop()


def one_run(device: str, how: str, plate: StampedPlate | None) -> dict:
    folder = Path(tempfile.mkdtemp(prefix="ultraglide-bench-supervision-"))
    log = folder / "env.csv"
    url = f"serial:{plate.plate.path}" if plate is not None else "sim"
    command = subprocess.Popen([sys.executable, "-m", "ultraglide", "play", "grating-1mm", "--device", url,
                                "--profile", "sim-plate",

                                "--duration-s", "60", "--envelope-csv", str(log)], cwd=ROOT,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ended: list[float] = []
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(command.stdout), daemon=True)
    reader.start()
    try:
        engine = engine_of(command.pid)
        part = folder / "env.csv.part"
        deadline = time.monotonic() + 120
        # replaying the swipe for a few seconds: the command said which plate (it does once its engine is ready and
        # its first touch reports are made, which on sim can take seconds of numba compiling after the engine plays)
        while not (any(line.startswith("plate:") for line in lines) and part.exists()
                   and part.stat().st_size > 2_000_000):
            if time.monotonic() > deadline or command.poll() is not None:
                raise RuntimeError(f"play never played: {command.stderr.read() if command.poll() is not None else ''}")
            time.sleep(0.02)
        waiter = threading.Thread(target=lambda: (command.wait(), ended.append(time.perf_counter())), daemon=True)
        waiter.start()
        before = len(plate.disables) if plate is not None else 0
        sent = time.perf_counter()
        os.kill(engine, signal.SIGKILL if how == "dead" else signal.SIGSTOP)
        waiter.join(60)
        reader.join(10)
        out = "".join(lines)
    finally:
        if command.poll() is None:
            command.kill()
            command.wait()
    disabled = plate.disables[before] - sent if plate is not None and len(plate.disables) > before else None
    safe_words = " / ".join(line for line in out.splitlines() if line.startswith(("made safe by ultraglide",
                                                                                  "the engine ")))
    return {"device": device, "engine": how, "status": command.returncode,
            "to_disabled_ms": None if disabled is None else 1000 * disabled,
            "to_exit_ms": 1000 * (ended[0] - sent) if ended else None, "said": safe_words}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = []
    load_before = os.getloadavg()[0]
    plate = StampedPlate()
    try:
        for device in ("pty plate", "sim"):
            for how in ("dead", "frozen"):
                for _ in range(args.runs):
                    results.append(one_run(device, how, plate if device == "pty plate" else None))
                    print(json.dumps(results[-1]), file=sys.stderr, flush=True)
    finally:
        plate.close()
    load = f"load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after, {os.cpu_count()} cores"
    if args.json:
        print(json.dumps({"runs": results, "load": load}, indent=2))
        return 0
    print(load)
    print(f"{'device':10} {'engine':7} {'runs':>4} {'to plate disabled, ms':>24} {'to exit, ms':>18}  aim")
    for device in ("pty plate", "sim"):
        for how in ("dead", "frozen"):
            rows = [r for r in results if r["device"] == device and r["engine"] == how]
            disabled = [r["to_disabled_ms"] for r in rows if r["to_disabled_ms"] is not None]
            exits = [r["to_exit_ms"] for r in rows if r["to_exit_ms"] is not None]
            span = f"{np.median(disabled):.0f} (max {max(disabled):.0f})" if disabled else "- (in the engine)"
            print(f"{device:10} {how:7} {len(rows):4d} {span:>24} "
                  f"{f'{np.median(exits):.0f} (max {max(exits):.0f})' if exits else '-':>18}  "
                  f"{AIMS_MS[how]:.0f} ms; exit statuses {sorted({r['status'] for r in rows})}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
