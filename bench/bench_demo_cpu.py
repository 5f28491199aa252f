"""The demo's cost under Xvfb: time to the first drawn frame, and CPU while idle and while dragging.

Run: .venv/bin/python bench/bench_demo_cpu.py [--seconds 10] [--runs 3] [--device sim null]
Aims (issue 11): first frame within 1.5 s of launch; at most 10 % of one core while nothing moves;
at most 60 % of one core while a finger drags at 120 Hz, the renderer and device included.

A real X server (Xvfb) and real pointer events (one xdotool process moving the pointer 120 times a
second, sweeping 600 px back and forth over a texture). CPU is the user + system time from /proc of
the whole process tree over the interval (the demo, its engine process with the renderer, the device
and, for ``sim``, the simulated plate's firmware), as a share of one core; "UI" is the demo's main
thread (event loop and drawing), "engine" the engine process and its children.
Time to first frame is measured outside: from launching the process to reading the line it prints
once the first frame is flipped.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from xvfb_demo import XvfbDemo, tools_missing  # noqa: E402


def measure(device: str, seconds: float) -> dict:
    with XvfbDemo("--device", device) as demo:
        _, first_s = demo.wait_for("first frame drawn", 60)
        first_frame_s = first_s - demo.launched_s
        _, ready_s = demo.wait_for("^renderer ready", 60)
        time.sleep(1.0)  # let the start-up settle before measuring
        cpu, ui, own, wall = demo.tree_cpu_s(), demo.main_thread_cpu_s(), demo.cpu_s(), time.perf_counter()
        time.sleep(seconds)
        wall_idle = time.perf_counter() - wall
        idle, idle_ui = (demo.tree_cpu_s() - cpu) / wall_idle, (demo.main_thread_cpu_s() - ui) / wall_idle
        idle_demo = (demo.cpu_s() - own) / wall_idle
        demo.xdo("key", "t")
        demo.wait_for("^frame drawn: texture", 30)
        steps = int(seconds * 120)
        points = [(round(640 + 300 * math.sin(2 * math.pi * i / 240)), 320) for i in range(steps)]  # 1 Hz sweeps
        cpu, ui, own, wall = demo.tree_cpu_s(), demo.main_thread_cpu_s(), demo.cpu_s(), time.perf_counter()
        demo.drag(points)
        wall_drag = time.perf_counter() - wall
        drag, drag_ui = (demo.tree_cpu_s() - cpu) / wall_drag, (demo.main_thread_cpu_s() - ui) / wall_drag
        drag_demo = (demo.cpu_s() - own) / wall_drag
        demo.quit()
    return {"first_frame_s": first_frame_s, "ready_s": ready_s - demo.launched_s, "idle": idle, "idle_ui": idle_ui,
            "idle_engine": idle - idle_demo, "drag": drag, "drag_ui": drag_ui, "drag_engine": drag - drag_demo,
            "drag_rate_hz": steps / wall_drag}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--device", nargs="+", default=["sim", "null"])
    args = parser.parse_args()
    if tools_missing():
        sys.exit(f"bench_demo_cpu: needs {', '.join(tools_missing())} (./run tests installs them)")
    for device in args.device:
        runs = [measure(device, args.seconds) for _ in range(args.runs)]
        med = {key: statistics.median(run[key] for run in runs) for key in runs[0]}
        print(f"--device {device}, median of {args.runs} runs of {args.seconds:g} s each:")
        firsts = ", ".join(f"{run['first_frame_s']:.2f}" for run in runs)
        print(f"  first frame drawn {med['first_frame_s']:.2f} s after launch (runs: {firsts}); "
              f"renderer ready at {med['ready_s']:.2f} s")
        print(f"  idle: {med['idle']:.1%} of a core, process tree (UI thread {med['idle_ui']:.1%}, "
              f"engine {med['idle_engine']:.1%})")
        print(f"  dragging at {med['drag_rate_hz']:.0f} Hz: {med['drag']:.1%} of a core, process tree "
              f"(UI thread {med['drag_ui']:.1%}, engine {med['drag_engine']:.1%})")

if __name__ == "__main__":
    main()
