"""Latency from a touch entering the engine to the first output sample that reflects it.

Run: .venv/bin/python bench/bench_latency.py [--steps 100] [--devices sim null ...] [--rest-ms 0 100]
Each device is measured after a short rest and after 100 ms more, when a serial link has stopped
streaming and disabled the output (docs/protocol.md, "Rest").
Aim (issue 11): under 2 ms inside the engine; the device's buffering is reported as it is
(audio: PortAudio's output latency; sim: the writer batch, link and jitter buffer, end to end on the
simulated plate's amplitude). Any device URL works, e.g. ``audio:system`` with jackd running.
"""

from __future__ import annotations

import argparse

from ultraglide.apps.commands.latency import measure


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--devices", nargs="+", default=["sim", "null"])
    parser.add_argument("--rest-ms", type=float, nargs="+", default=[0.0, 100.0],
                        help="rest before each step beyond the plate's settling (100: a serial link has gone idle)")
    args = parser.parse_args()
    print(f"{'device':28} {'engine p50':>10} {'p99':>7} {'device p50':>10} {'p99':>7} {'total p50':>9} {'p99':>7}"
          f" {'pull every':>10}  (ms)")
    for device, rest_ms in [(d, r) for d in args.devices for r in args.rest_ms]:
        f = measure(device, args.steps, rest_s=rest_ms / 1000)
        device = f"{device} (rest {rest_ms:g} ms)"
        e, d, t = f["engine_ms"], f["device_ms"], f["total_ms"]
        print(f"{device:28} {e['p50']:10.2f} {e['p99']:7.2f} {d['p50']:10.2f} {d['p99']:7.2f} {t['p50']:9.2f} "
              f"{t['p99']:7.2f} {f['block_ms']:10.2f}", flush=True)
    print(f"({args.steps} steps each, sticky to slippery; engine = waiting for the device's next pull + rendering)")


if __name__ == "__main__":
    main()
