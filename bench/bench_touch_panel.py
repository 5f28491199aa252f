"""What reading the touch panel in the service (``serve --touch-panel``) adds to the engine's touch-to-output latency.

Run: .venv/bin/python bench/bench_touch_panel.py [--touches 300] [--rounds 2]

One engine (on the simulated plate, as ``serve`` starts it) and the service in this process, its panel feed on a
FIFO; a writer in another process stands in for the kernel: input_event records (multi-touch protocol B, a finger
moving 0.5 mm every 10 ms) stamped with the wall clock as the kernel stamps them, each frame's ``perf_counter``
time noted as it is written. Rounds alternate with touches put into the engine directly (as ``play`` and the demo
do: the engine's own latency). For each, the engine's record (``Engine.latencies``): when the block that first
rendered it was presented. What is not measured: the panel's own scan and its driver up to the evdev buffer.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_service import direct, figures  # noqa: E402

WRITER = r"""
import json, os, struct, sys, time
path, count, rate = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
fd = os.open(path, os.O_WRONLY)
def record(now, kind, code, value):
    return struct.pack("=qqHHi", int(now), int((now % 1) * 1e6), kind, code, value)
sent = []
start = time.perf_counter()
for k in range(count):
    due = start + k / rate
    while time.perf_counter() < due:
        if due - time.perf_counter() > 0.0005:
            time.sleep(0.0002)
    now = time.time()
    events = [(3, 0x39, 1)] if k == 0 else []
    events += [(3, 0x35, 200 + (k % 100) * 5), (3, 0x36, 500), (0, 0, 0)]
    t = time.perf_counter()
    os.write(fd, b"".join(record(now, *e) for e in events))
    sent.append(t)
os.write(fd, record(time.time(), 3, 0x39, -1) + record(time.time(), 0, 0, 0))
time.sleep(0.05)
os.close(fd)
print(json.dumps(sent))
"""


def nearest(latencies, sent, within_s: float = 0.004) -> np.ndarray:
    """Each frame's latency (s): from its write to the presentation of the block that first rendered it; its engine
    row is the touch whose time is nearest its write (the feed puts the kernel's time on our clock by the least
    offset: a few tens of µs after the write; frames are 10 ms apart)."""
    touch_t, _, presented = latencies
    order = np.argsort(touch_t)
    touch_t, presented = touch_t[order], presented[order]
    sent = np.asarray(sent)
    index = np.clip(np.searchsorted(touch_t, sent), 1, len(touch_t) - 1)
    index = np.where(np.abs(touch_t[index - 1] - sent) < np.abs(touch_t[index] - sent), index - 1, index)
    near = np.abs(touch_t[index] - sent) < within_s
    return presented[index[near]] - sent[near]


async def by_panel(service, fifo: str, count: int, rate: float) -> list[float]:
    from ultraglide.apps.service.panel import PanelFeed
    from ultraglide.devices.touch.evdev import AxisRange, PanelRanges, PanelReader

    reader = PanelReader(fifo, PanelRanges(AxisRange(0, 1600), AxisRange(0, 1000)))  # 0.1 mm a unit
    feed = PanelFeed(service, reader)
    feed.start(asyncio.get_running_loop())
    process = await asyncio.create_subprocess_exec(sys.executable, "-c", WRITER, fifo, str(count), str(rate),
                                                   stdout=subprocess.PIPE)
    out, _ = await process.communicate()
    while not feed.gone:
        await asyncio.sleep(0.01)
    return json.loads(out)


async def measure(args) -> None:
    engine, service = args.engine, args.service
    with tempfile.TemporaryDirectory(prefix="ultraglide-bench-") as folder:
        fifo = os.path.join(folder, "panel")
        os.mkfifo(fifo)
        await asyncio.sleep(0.5)
        own, through = [], []
        for _ in range(args.rounds):
            sent = await direct(engine, args.touches, 100.0)
            await asyncio.sleep(0.05)
            own.append(nearest(engine.latencies(), sent))
            sent = await by_panel(service, fifo, args.touches, 100.0)
            await asyncio.sleep(0.05)
            through.append(nearest(engine.latencies(), sent))
    own, through = np.concatenate(own), np.concatenate(through)
    print(f"latency, touch to its block presented (sim): engine alone {figures(own)}; from the panel's FIFO "
          f"through the service {figures(through)}")
    print(f"reading the panel adds {(np.percentile(through, 99) - np.percentile(own, 99)) * 1e3:.3f} ms at p99 "
          f"({(np.median(through) - np.median(own)) * 1e3:.3f} ms at p50)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--touches", type=int, default=300, help="touches per round and way (default: 300)")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    from ultraglide.apps.service.server import Service
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.engine import Engine, EngineConfig

    service = Service(None, load_profile("sim-plate"))
    args.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="sim"))  # forked, as serve's
    args.service, service.engine = service, args.engine
    try:
        args.engine.wait_ready()
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), -10)  # as serve's loop
        asyncio.run(measure(args))
    finally:
        service.worker.shutdown()
        args.engine.stop()
    print(f"load average {', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
