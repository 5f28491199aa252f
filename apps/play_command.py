"""``ultraglide play``: render a swipe or a touch log to a device in real time, through the engine.

The swipe or log is replayed as touch reports, at their own times, into the real-time engine
(:mod:`render.engine`, its own process), exactly as the demo's touch panel feeds it.
"""

from __future__ import annotations

import json
import sys
import time
from types import SimpleNamespace

import numpy as np
from ultraglide.apps.output_report import force_words  # (takes anything with default_force_n)
from ultraglide.apps.render_setup import load_inputs
from ultraglide.apps.stop_signals import held
from ultraglide.render.engine import Engine, EngineConfig

REPORT_HZ = 120.0  # a synthetic swipe is reported like a 120 Hz touch panel


def report_times(trajectory) -> np.ndarray:
    """When the touch panel reports: the log's own times, or every 1/120 s along a swipe."""
    own = getattr(trajectory, "t_s", None)
    if own is not None:
        return np.asarray(own)
    return np.arange(trajectory.start_s, trajectory.end_s, 1.0 / REPORT_HZ)


def engine_config(args) -> EngineConfig:
    return EngineConfig(texture=args.texture, model=args.model, profile=args.profile, device=args.device,
                        carrier_hz=args.carrier_hz, rate_hz=args.rate, lookahead_s=args.lookahead_ms / 1000.0,
                        precompensate=not args.no_precompensation,
                        track_resonance=getattr(args, "track_resonance", False))


def run(args) -> int:
    inputs = load_inputs(args)  # every mistake in the options surfaces before a device is touched
    trajectory = inputs.trajectory
    times = report_times(trajectory)
    states = trajectory.state(times)
    forces = np.broadcast_to(states.force_n, times.shape)
    engine = Engine.start(engine_config(args))
    try:
        engine.wait_ready()
        started = time.perf_counter()
        for t, x, y, force in zip(times - times[0], states.x_mm, states.y_mm, forces, strict=True):
            delay = started + t - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            engine.touch(time.perf_counter(), float(x), float(y), None if np.isnan(force) else float(force))
        engine.touch(time.perf_counter(), float(states.x_mm[-1]), float(states.y_mm[-1]), down=False)
        time.sleep(engine.ready_info["tail_s"])
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            final = engine.stop()  # ramps down, rests the plate and ends the engine, on every way out
    played_s = round(time.perf_counter() - started, 3)
    figures = final.summary()
    figures["fault_words"] = figures.pop("faults")
    device_status = figures.pop("device_status")
    counts = device_status.pop("fault_counts", None)
    limiter = device_status.pop("limiter", "")
    clipped = final.clipped_samples / final.control_samples if final.control_samples else 0.0
    status = {**device_status, **figures, "clipped_fraction": round(clipped, 6), "faults": counts or {},
              "played_s": played_s}
    if final.clipped_samples:
        force = force_words(trajectory, SimpleNamespace(default_force_n=engine.config.default_force_n))
        print(f"warning: {100 * clipped:.1f} % of the time the texture asked for less friction than model "
              f"{args.model} reaches at {force} within "
              f"{inputs.profile.max_amplitude_um_pp:g} µm p-p; held at the limit", file=sys.stderr)
    if args.json:
        print(json.dumps(status))
    else:
        print(f"played {played_s:.2f} s on {final.device}: {final.blocks} blocks rendered, {final.late_blocks} late, "
              f"{final.underruns} device underruns; block time {final.block_p50_us:.0f} µs median, "
              f"{final.block_p99_us:.0f} µs p99; {final.clipped_samples} samples held at the plate's limit; "
              f"engine priority {final.priority}")
        print(limiter)
        print(describe_faults(counts or {}))
    return 0


def describe_faults(counts: dict[str, int]) -> str:
    """The run's device faults in words, e.g. ``device faults: 2 × watchdog trip (...)``."""
    from ultraglide.devices.protocol import FAULT_WORDS

    happened = [f"{count} × {FAULT_WORDS.get(name, name)}" for name, count in counts.items() if count]
    if not counts:
        return "device faults: this device reports none"
    return "device faults: " + ("; ".join(happened) if happened else "none")
