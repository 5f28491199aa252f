"""The settled speed law's cost and gain: the live block with and without a law, and what a finger whose reduction
weakens with speed (s = 0.5, the simulated plate's own law) feels of a grating with the law rendered or ignored.

    .venv/bin/python bench/bench_speed_law.py
"""

from __future__ import annotations

import math
import time

import numpy as np
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.finger import FingerParams, FingerSpeedLaw, ForceScript, SimulatedFinger
from ultraglide.devices.sim.force_sensors import ForceSensorParams
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.renderer import Renderer
from ultraglide.textures.procedural import grating

RATE = 12000.0
LIVE_BLOCK = 8  # the engine's live block at 12 kHz
SPEEDS_MM_S = (25.0, 100.0, 200.0)
TEXTURE = grating(wavelength_mm=8.0, size_mm=(200.0, 50.0), ratio_range=(0.15, 1.0))
PROFILE = load_profile("sim-plate")


def live_block_cost(spec: str) -> float:
    """Median µs of one 8-sample live block, a finger pushed along a line at a speed swinging 50-150 mm/s (so a
    speed law's scale changes every block)."""
    renderer = Renderer(TEXTURE, load_model(spec), PROFILE)
    buffers = renderer.control_buffers(256, always=True)
    t, x, times = 1000.0, 10.0, []
    for k in range(4000):
        if k % 15 == 0:
            renderer.push(t, x, 25.0, 0.5)
        speed = 100.0 + 50.0 * math.sin(2 * math.pi * (t - 1000.0))
        x = 10.0 + (x - 10.0 + speed * LIVE_BLOCK / RATE) % 150.0
        start = time.perf_counter()
        renderer.control(LIVE_BLOCK, t, buffers)
        times.append(time.perf_counter() - start)
        t += LIVE_BLOCK / RATE
    return float(np.median(times[500:]) * 1e6)


def felt_error(spec: str, speed: float) -> tuple[float, int]:
    """RMS of the finger's true ratio against the target over a 1 s swipe at ``speed``, where the target is
    reachable at that speed (the first 50 ms left out), and how many samples that is."""
    model = load_model(spec)
    renderer = Renderer(TEXTURE, model, PROFILE, trajectory=SwipePath(duration_s=1.0, speed_mm_s=speed))
    blocks = [renderer.control(120) for _ in range(100)]
    plate = np.concatenate([b.plate_um_pp for b in blocks])
    target = np.concatenate([b.ratio for b in blocks]).astype(float)
    static = load_model("stretched")
    finger = SimulatedFinger(static.relative_friction, ForceScript.constant(0.5, speed),
                             FingerParams(drift=0.0, moisture=0.0), ForceSensorParams(noise_n=0.0),
                             speed_law=FingerSpeedLaw(0.5))
    truth = finger.truth(np.arange(4 * len(plate)) / 48000.0, np.repeat(plate, 4)).relative_friction[::4]
    floor = float(static.relative_friction(PROFILE.max_amplitude_um_pp * (22.0 / speed) ** 0.5, 0.5))
    pick = (np.arange(len(plate)) / RATE > 0.05) & (target > floor + 0.02)
    return float(np.sqrt(np.mean((truth[pick] - target[pick]) ** 2))), int(np.count_nonzero(pick))


def main() -> None:
    print("a finger with the speed law s = 0.5 (22 mm/s), an 8 mm grating 0.15-1: RMS error where reachable")
    print(f"{'speed':>9} {'law rendered':>13} {'law ignored':>12} {'samples':>8}")
    for speed in SPEEDS_MM_S:
        with_law, count = felt_error("speed:0.5:stretched", speed)
        without, _ = felt_error("stretched", speed)
        print(f"{speed:6g} mm/s {with_law:13.4f} {without:12.4f} {count:8d}")
    for spec in ("stretched", "speed:0.5:stretched", "dynamic", "speed:0.5:dynamic"):
        print(f"live block of {LIVE_BLOCK} samples, {spec}: {live_block_cost(spec):.1f} µs (median)")


if __name__ == "__main__":
    main()
