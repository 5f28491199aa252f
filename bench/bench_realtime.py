"""Real-time rendering: the engine's block path, in its own process, for a live finger.

Run: .venv/bin/python bench/bench_realtime.py [--blocks 20000] [--paced]
Aim (issues 4, 11): one block of 64 frames at 96 kHz, p99 under 10 % of its period (67 µs); the block path
allocates nothing once running (tests/test_block_path.py). ``dynamic`` (the default model) plans the friction
felt: one block in three at 64 frames (every 2 ms) carries the planner's decision.

For each case a spawned process builds the engine's block path (render.engine.process.EngineSource:
drain the touch ring, render, limit and put on the carrier (the output stage), publish the status)
exactly as the engine does (gc frozen and off, priority raised where allowed, huge pages off, the CPU
wake-up request held as the engine holds it while rendering) and pulls blocks back to back, or with
``--paced`` one period apart; this process writes touch reports into the shared ring at 120 Hz
meanwhile, as the UI would. The times are the pull's own. ``--no-wake-request`` leaves the CPUs to
their governor (on this VM an idle vCPU halts, and a block after a halt runs on cold caches).
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import time
import types

import numpy as np


def worker(shared_name: str, texture_name: str, model_name: str, frames: int, rate: int, blocks: int, paced: bool,
           wake_request: bool, conn) -> None:
    import gc

    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.engine.process import EngineSource
    from ultraglide.render.engine.realtime import CpuWakeLatency, keep_huge_pages_out
    from ultraglide.render.engine.shm import SharedBlock
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.renderer import Renderer, RenderSettings
    from ultraglide.textures.library import resolve_texture

    shared = SharedBlock.attach(shared_name)
    renderer = Renderer(resolve_texture(texture_name), load_model(model_name), load_profile("sim-plate"),
                        RenderSettings(audio_rate_hz=rate))
    device = types.SimpleNamespace(signal="audio", rate_hz=rate, carrier_hz=None)  # what a sound card says of itself
    source = EngineSource(renderer, shared, device)
    pages = keep_huge_pages_out()
    wake = CpuWakeLatency(0 if wake_request else None)
    wake.hold(True)
    times = np.empty(blocks)
    gc.collect()
    gc.freeze()
    gc.disable()
    conn.send("ready")
    conn.recv()  # the feeder is running
    period = frames / rate
    for i in range(blocks):
        if paced:
            time.sleep(period)
        started = time.perf_counter()
        source.pull(frames, None)
        times[i] = time.perf_counter() - started
    conn.send((times, f"{source.priority}; {pages}; {wake.words()}"))
    wake.close()
    shared.close()


def measure(texture: str, model: str, frames: int, rate: int, blocks: int, paced: bool = False,
            wake_request: bool = True) -> tuple[np.ndarray, str]:
    from ultraglide.render.engine.shm import SharedBlock

    context = multiprocessing.get_context("spawn")
    shared = SharedBlock.create()
    parent, child = context.Pipe()
    process = context.Process(target=worker, args=(shared.name, texture, model, frames, rate, blocks, paced,
                                                          wake_request, child))
    process.start()
    try:
        assert parent.recv() == "ready"
        parent.send("go")
        start = time.perf_counter()
        while not parent.poll(1 / 120):
            t = time.perf_counter()
            phase = (t - start) * 2.0
            shared.push_touch(t, 40 + 30 * math.cos(phase), 25 + 15 * math.sin(phase), 0.5, 1.0)
        times, priority = parent.recv()
    finally:
        process.join(30)
        shared.close()
    return times[100:] * 1e6, priority


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=20000)
    parser.add_argument("--paced", action="store_true",
                        help="sleep one block period before each block, as a device's thread does: caches and the "
                             "CPU's clock go cold in between, which back-to-back blocks hide")
    parser.add_argument("--no-wake-request", dest="wake_request", action="store_false",
                        help="do not ask idle CPUs to wake within 0 µs (the engine asks while it renders)")
    args = parser.parse_args()
    header = ("texture", "model", "block", "median µs", "p99 µs", "p99.9 µs", "budget µs")
    print("{:14} {:12} {:>12} {:>10} {:>8} {:>9} {:>10}".format(*header))
    priority = ""
    for texture in ("grating-1mm", "bumps"):
        for model in ("exponential", "paper", "dynamic"):  # dynamic, the default: it plans every 2 ms
            for frames, rate in ((64, 96000), (128, 192000)):
                t, priority = measure(texture, model, frames, rate, args.blocks, args.paced, args.wake_request)
                budget = 0.1 * frames / rate * 1e6
                print(f"{texture:14} {model:12} {frames:4} @ {rate // 1000:3} kHz {np.median(t):10.1f} "
                      f"{np.percentile(t, 99):8.1f} {np.percentile(t, 99.9):9.1f} {budget:10.1f}", flush=True)
    print(f"({args.blocks} blocks each, {'one period apart' if args.paced else 'back to back'}, in the engine's own "
          f"process at {priority}; "
          "touch reports at 120 Hz through the shared ring)")


if __name__ == "__main__":
    main()
