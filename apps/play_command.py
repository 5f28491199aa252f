"""``ultraglide play``: render a swipe or a touch log to a device in real time."""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from ultraglide.apps.output_report import clipped_fraction, clipping_warning, limiter_fields
from ultraglide.apps.render_setup import load_inputs, make_renderer
from ultraglide.apps.sources import source_for
from ultraglide.apps.stop_signals import held
from ultraglide.devices.urls import open_device

REPORT_HZ = 120.0  # a synthetic swipe is reported like a 120 Hz touch panel


def report_times(trajectory) -> np.ndarray:
    """When the touch panel reports: the log's own times, or every 1/120 s along a swipe."""
    own = getattr(trajectory, "t_s", None)
    if own is not None:
        return np.asarray(own)
    return np.arange(trajectory.start_s, trajectory.end_s, 1.0 / REPORT_HZ)


def run(args) -> int:
    inputs = load_inputs(args)  # every mistake in the options surfaces before a device is touched
    trajectory = inputs.trajectory
    times = report_times(trajectory)
    states = trajectory.state(times)
    forces = np.broadcast_to(states.force_n, times.shape)
    device = open_device(args.device, inputs.profile, control_rate_hz=12000, carrier_hz=args.carrier_hz)
    try:
        rate = device.rate_hz if device.signal == "audio" else args.rate
        renderer = make_renderer(inputs, args, rate, live=True)
        stage = source_for(device, renderer)  # the limiter every output passes
        device.start(stage)
        started = time.perf_counter()
        for t, x, y, force in zip(times - times[0], states.x_mm, states.y_mm, forces, strict=True):
            delay = started + t - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            renderer.push(time.perf_counter(), float(x), float(y), None if np.isnan(force) else float(force))
        renderer.push(time.perf_counter(), float(states.x_mm[-1]), float(states.y_mm[-1]), down=False)
        time.sleep(renderer.tail_s)
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            device.stop()  # ramps down through the renderer, then rests the plate, on every way out
    status = {**device.status(), "clipped_samples": renderer.counters.clipped_samples,
              "clipped_fraction": round(clipped_fraction(renderer), 6), **limiter_fields(stage),
              "ramps": renderer.counters.ramps, "late_blocks": renderer.counters.late_blocks,
              "played_s": round(time.perf_counter() - started, 3)}
    status["faults"] = fault_counts(device)
    warning = clipping_warning(renderer, args.model, trajectory)
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        print(json.dumps(status))
    else:
        print(" ".join(f"{key}={value}" for key, value in status.items() if key != "faults"))
        print(stage.limiter.summary())
        print(describe_faults(status["faults"]))
    return 0


def fault_counts(device) -> dict[str, int]:
    """Each fault the device reported over the run, with its count; empty for devices that report none."""
    counts = getattr(device, "fault_counts", None)
    return counts() if counts else {}


def describe_faults(counts: dict[str, int]) -> str:
    """The run's device faults in words, e.g. ``device faults: 2 × watchdog trip (...)``."""
    from ultraglide.devices.protocol import FAULT_WORDS

    happened = [f"{count} × {FAULT_WORDS.get(name, name)}" for name, count in counts.items() if count]
    if not counts:
        return "device faults: this device reports none"
    return "device faults: " + ("; ".join(happened) if happened else "none")
