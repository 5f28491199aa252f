"""What the client's ``touch()`` costs, part by part, cold (as a program that sleeps between pointer events runs it)
and warm, and the whole call on its short path and its general one against a real ``ultraglide serve``.

Run: .venv/bin/python bench/bench_client_touch.py [--calls 300]

* **parts**: each part of a touch's way out, timed alone after a 10 ms sleep (cold: ``--calls`` times, p50 and p90)
  and in a tight loop (warm): the general path's (the fields cleaned, ``json.dumps``, websockets' frame, its mask's
  random bytes) and the short path's (``ultraglide.client.touch_text``, the frame written by hand).
* **the call**: ``Client.touch`` against ``ultraglide serve --device null``, 10 ms apart, alternately by its short
  path and its general one (``pointer_type`` given sends it the general way): wall time and this thread's CPU.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np


def timed(function, calls: int) -> tuple[np.ndarray, float]:
    """``function()`` timed alone after a 10 ms sleep, ``calls`` times (s each); and its mean in a tight loop (s)."""
    function()
    cold = []
    for _ in range(calls):
        time.sleep(0.01)
        start = time.perf_counter()
        function()
        cold.append(time.perf_counter() - start)
    start = time.perf_counter()
    for _ in range(3000):
        function()
    return np.asarray(cold), (time.perf_counter() - start) / 3000


def parts(calls: int) -> None:
    import secrets

    from websockets.client import ClientProtocol
    from websockets.protocol import OPEN
    from websockets.speedups import apply_mask
    from websockets.uri import parse_uri

    from ultraglide import client

    protocol = ClientProtocol(parse_uri("ws://127.0.0.1:1/ws"))
    protocol.state = OPEN
    fields = {"x": 20.5, "y": 50.0, "phase": "move", "pointer": 0, "view": None, "pressure": None, "force_n": None,
              "t": 1234.5678, "pointer_type": None}
    message = {"type": "touch", **client._clean(**fields)}
    text = client._encoded(message)
    payload, mask = text.encode(), os.urandom(4)

    def frame():
        protocol.send_text(text.encode())
        protocol.data_to_send()

    pieces = {
        "general: the fields cleaned": lambda: client._clean(**fields),
        "general: json.dumps": lambda: client._encoded(message),
        "general: websockets' frame": frame,
        "general: the mask's 4 random bytes": lambda: secrets.token_bytes(4),
        "short: touch_text": lambda: client.touch_text(20.5, 50.0, "move", 0, 1234.5678),
        "short: the frame by hand": lambda: bytes((0x81, 0x80 | len(payload))) + mask + apply_mask(payload, mask),
        "a call that does nothing": lambda: None,
    }
    for name, function in pieces.items():
        cold, warm = timed(function, calls)
        print(f"{name:38s} cold p50 {np.percentile(cold, 50) * 1e6:6.1f} µs, p90 {np.percentile(cold, 90) * 1e6:6.1f} "
              f"µs; warm {warm * 1e6:5.1f} µs")


def calls(count: int) -> None:
    from ultraglide.client import Client

    serve = subprocess.Popen([sys.executable, "-m", "ultraglide", "serve", "--device", "null", "--port", "0",
                              "--json"], stdout=subprocess.PIPE, text=True)
    try:
        url = json.loads(serve.stdout.readline())["url"]
        with Client(url) as plate:
            plate.touch(20.0, 50.0, "down")
            wall = {"short": [], "general": []}
            cpu = {"short": [], "general": []}
            for k in range(2 * count):
                time.sleep(0.01)
                way = "short" if k % 2 else "general"
                start, start_cpu = time.perf_counter(), time.thread_time()
                plate.touch(20.0 + (k % 100) * 0.5, 50.0, "move", t=start,
                            pointer_type=None if way == "short" else "touch")
                cpu[way].append(time.thread_time() - start_cpu)
                wall[way].append(time.perf_counter() - start)
            plate.touch(20.0, 50.0, "up")
            plate.state()
            assert not plate.errors, list(plate.errors)
        for way in ("general", "short"):
            print(f"touch() by its {way} path against serve on null: wall p50 {np.percentile(wall[way], 50) * 1e6:.0f} "
                  f"µs, p99 {np.percentile(wall[way], 99) * 1e6:.0f} µs; its CPU p50 "
                  f"{np.percentile(cpu[way], 50) * 1e6:.0f} µs, p99 {np.percentile(cpu[way], 99) * 1e6:.0f} µs "
                  f"(n={count})")
    finally:
        serve.terminate()
        serve.wait(60)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=300, help="cold calls of each part, and calls each way")
    args = parser.parse_args()
    parts(args.calls)
    calls(args.calls)
    print(f"load average {', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
