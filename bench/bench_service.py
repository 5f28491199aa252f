"""What ``ultraglide serve`` adds to the engine's touch-to-output latency, and what 1000 pointer events a second do.

Run: .venv/bin/python bench/bench_service.py [--touches 300] [--rounds 2] [--soak-s 60] [--browser]

One engine (on the simulated plate, as ``serve`` starts it) and the service in this process, its loop set up as
``serve``'s (:func:`apps.commands.serve._loop_in_real_time`: the loop thread's priority; the interpreter's switch
interval printed) and its publisher thread running; a client in another process (``ultraglide.client``) on a real
socket, subscribed to the status at 2 Hz as the page is (``--no-subscribe``: not). Both clocks are
``perf_counter`` (CLOCK_MONOTONIC, one clock for every process on Linux).

* **latency**: rounds of touches at 100 Hz, alternately put into the engine directly (as ``play`` and the demo do:
  the engine's own touch-to-output latency) and sent by the client (its event time: its clock when it sent it). For
  each, the engine's own record (``Engine.latencies``): when the block that first rendered it was presented.
  Aim (issue 41): the service adds at most 1 ms at p99.
* **soak**: 1000 pointer events a second for ``--soak-s`` seconds, first put into the engine directly, then sent by
  the client: the engine's late blocks in each (none beyond the engine's own), and this process's memory.
* ``--browser``: the page in headless Chromium (``serve --page``), 200 synthesized touch moves: the milliseconds from
  each pointer event's time stamp to its message sent (the browser's own part, reported apart).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np

CLIENT = r"""
import json, sys, time
from ultraglide.client import Client
url, count, rate, status_hz = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
sent = []
with Client(url) as plate:
    if status_hz:
        plate.subscribe(status=status_hz)  # as the page does
    start = time.perf_counter()
    for k in range(count):
        due = start + k / rate
        while time.perf_counter() < due:
            if due - time.perf_counter() > 0.0005:
                time.sleep(0.0002)
        t = time.perf_counter()
        plate.touch(20.0 + (k % 100) * 0.5, 50.0, "down" if k == 0 else "move", t=t)
        sent.append((t, time.perf_counter()))  # its time, and when the client's call returned (its frame written)
    plate.touch(20.0, 50.0, "up")
    plate.state()  # everything sent has arrived
print(json.dumps(sent))
"""


def rss_mb() -> tuple[float, float]:
    """This process's resident memory now and at its peak, MB."""
    fields = dict(line.split(":", 1) for line in open("/proc/self/status").read().splitlines() if ":" in line)
    return int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024


def matched(latencies, sent) -> np.ndarray:
    """Each event's latency (s): from its time at the client to its block's presentation, matched by time (each
    event's row is the first whose touch time is at or after it: the service shifts a client's time by the least
    delivery seen, a few tens of µs, and events are 10 ms apart)."""
    touch_t, _, presented = latencies
    order = np.argsort(touch_t)
    touch_t, presented = touch_t[order], presented[order]
    index = np.searchsorted(touch_t, np.asarray(sent) - 1e-9)
    index = index[index < len(touch_t)]
    return presented[index] - np.asarray(sent)[: len(index)]


async def direct(engine, count: int, rate: float) -> list[float]:
    """Touches into the engine from this loop, as play and the demo put them: their times."""
    sent = []
    start = time.perf_counter()
    for k in range(count):
        due = start + k / rate
        await asyncio.sleep(max(0.0, due - time.perf_counter() - 0.0005))
        while time.perf_counter() < due:
            pass
        t = time.perf_counter()
        engine.touch(t, 20.0 + (k % 100) * 0.5, 50.0, down=True)
        sent.append(t)
    engine.touch(time.perf_counter(), 20.0, 50.0, down=False)
    return sent


async def by_client(url: str, count: int, rate: float, status_hz: float = 2.0) -> np.ndarray:
    """The client's touches: each one's time and when its call to the client returned, perf_counter s."""
    process = await asyncio.create_subprocess_exec(sys.executable, "-c", CLIENT, url, str(count), str(rate),
                                                   str(status_hz), stdout=subprocess.PIPE)
    out, _ = await process.communicate()
    return np.asarray(json.loads(out)).reshape(-1, 2)


def figures(values_s) -> str:
    values = np.asarray(values_s) * 1e3
    return f"p50 {np.percentile(values, 50):.3f} ms, p99 {np.percentile(values, 99):.3f} ms (n={len(values)})"


async def measure(args) -> None:
    from ultraglide.apps.commands.serve import _loop_in_real_time
    from websockets.asyncio.server import serve

    engine, service = args.engine, args.service
    service.priority = _loop_in_real_time(service)  # as serve's loop: its thread's priority
    print(f"the service's loop: {service.priority}, switch interval {sys.getswitchinterval() * 1e3:g} ms; status "
          f"subscribed at {args.status_hz:g} Hz")
    stop = threading.Event()
    publisher = threading.Thread(target=service.publish, args=(asyncio.get_running_loop(), stop),
                                 name="ultraglide-publisher", daemon=True)
    publisher.start()  # as serve's
    server = await serve(service.handle, "127.0.0.1", 0, origins=[None], compression=None)
    async with server:
        url = f"ws://127.0.0.1:{server.sockets[0].getsockname()[1]}/ws"
        await asyncio.sleep(0.5)
        own, through = [], []
        for _ in range(args.rounds):
            sent = await direct(engine, args.touches, 100.0)
            await asyncio.sleep(0.05)
            own.append(matched(engine.latencies(), sent))
            sent = await by_client(url, args.touches, 100.0, args.status_hz)
            await asyncio.sleep(0.05)
            through.append(matched(engine.latencies(), sent[:, 0]))
        own, through = np.concatenate(own), np.concatenate(through)
        service.arrivals = []
        sent = await by_client(url, args.touches, 100.0, args.status_hz)
        arrivals = np.asarray([row for row in service.arrivals if row[0] is not None])
        service.arrivals = None
        returned = sent[np.clip(np.searchsorted(sent[:, 0], arrivals[:, 0] - 1e-9), 0, len(sent) - 1), 1]
        print(f"through the service, from the client's send to the message read by the service's loop "
              f"{figures(arrivals[:, 1] - arrivals[:, 0])} (of it, the client's call, its encoding and its socket "
              f"write: {figures(returned - arrivals[:, 0])}); from read to the engine's ring "
              f"{figures(arrivals[:, 2] - arrivals[:, 1])}")
        print(f"latency, touch to its block presented (sim): engine alone {figures(own)}; "
              f"through the service {figures(through)}")
        added = np.percentile(through, 99) - np.percentile(own, 99)
        print(f"the service adds {added * 1e3:.3f} ms at p99 ({(np.median(through) - np.median(own)) * 1e3:.3f} ms "
              f"at p50); aim: at most 1 ms at p99")
        if args.soak_s > 0:
            count = int(args.soak_s * 1000)
            before = engine.status(0.0)
            await direct(engine, count, 1000.0)
            middle = engine.status(0.0)
            rss_before, _ = rss_mb()
            sent = await by_client(url, count, 1000.0, args.status_hz)
            after = engine.status(0.0)
            rss_after, peak = rss_mb()
            print(f"soak, 1000 events/s for {args.soak_s:g} s: late blocks {middle.late_blocks - before.late_blocks} "
                  f"(engine alone), {after.late_blocks - middle.late_blocks} (through the service; {len(sent)} events "
                  f"sent, {after.touches - middle.touches} reached the engine, {after.touches_dropped} dropped "
                  f"by its ring); device underruns {after.underruns - before.underruns}; this process's memory "
                  f"{rss_before:.0f} MB before the service's soak, {rss_after:.0f} MB after (peak {peak:.0f} MB)")
    stop.set()
    publisher.join(10)


def browser_send_times(count: int = 200) -> None:
    import shutil
    import tempfile

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service as Driver

    serve = subprocess.Popen([sys.executable, "-m", "ultraglide", "serve", "grating-1mm", "--port", "0", "--page",
                              "--json"], stdout=subprocess.PIPE, text=True)
    try:
        address = json.loads(serve.stdout.readline())
        with tempfile.TemporaryDirectory() as profile:
            options = webdriver.ChromeOptions()
            options.binary_location = shutil.which("chromium")
            for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                         "--disable-background-networking", "--disable-component-update", "--disable-sync",
                         "--window-size=800,600", f"--user-data-dir={profile}"):
                options.add_argument(flag)
            driver = webdriver.Chrome(service=Driver(shutil.which("chromedriver")), options=options)
            try:
                driver.get(address["page"])
                deadline = time.monotonic() + 60
                while not driver.execute_script("return window.ultraglide && window.ultraglide.ready"):
                    if time.monotonic() > deadline:
                        raise SystemExit("the page did not get ready")
                    time.sleep(0.05)
                for k in range(count):
                    kind = "touchStart" if k == 0 else "touchMove"
                    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": kind, "touchPoints": [
                        {"x": 100 + k, "y": 300, "radiusX": 5, "radiusY": 5, "force": 0.5, "id": 1}]})
                driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
                times = driver.execute_script("return window.ultraglide.sendTimes()")
            finally:
                driver.quit()
    finally:
        serve.terminate()
        serve.wait(60)
    values = np.asarray(times)
    print(f"browser (headless Chromium), pointer event's time stamp to its message sent: p50 "
          f"{np.percentile(values, 50):.3f} ms, p99 {np.percentile(values, 99):.3f} ms (n={len(values)}; "
          f"synthesized by the DevTools protocol, so it includes their dispatch)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--touches", type=int, default=300, help="touches per round and way (default: 300)")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--soak-s", type=float, default=60.0, help="the soak's length (0: none; default: 60)")
    parser.add_argument("--browser", action="store_true", help="also time the page in headless Chromium")
    parser.add_argument("--no-subscribe", dest="status_hz", action="store_const", const=0.0, default=2.0,
                        help="the client subscribes to nothing (default: the status at 2 Hz, as the page)")
    args = parser.parse_args()
    from ultraglide.apps.service.server import Service
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.engine import Engine, EngineConfig

    profile = load_profile("sim-plate")
    service = Service(None, profile)
    args.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="sim"))  # forked, as serve's
    service.engine = args.engine
    try:
        args.engine.wait_ready()
        args.service = service
        asyncio.run(measure(args))
    finally:
        service.worker.shutdown()
        args.engine.stop()
    print(f"load average {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    if args.browser:
        browser_send_times()


if __name__ == "__main__":
    main()
