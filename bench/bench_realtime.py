"""Real-time rendering: time to render one block for a live finger, through the output stage.

Run: .venv/bin/python bench/bench_realtime.py
Aim (issue 4): one block of 64 frames at 96 kHz, p99 under 10 % of its period (67 µs).
A feeder thread pushes touch reports at 120 Hz while the main thread pulls blocks from the output
stage (limiter and carrier), as an audio device would.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from ultraglide.apps.sources import EnvelopeSource
from ultraglide.devices.output_stage import OutputStage
from ultraglide.devices.profiles import load_profile
from ultraglide.render.friction_models import ExponentialModel, PaperModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.textures.library import resolve_texture

BLOCKS = 20000


def measure(texture_name: str, model, frames: int, rate: int) -> np.ndarray:
    settings = RenderSettings(audio_rate_hz=rate)
    profile = load_profile("sim-plate")
    renderer = Renderer(resolve_texture(texture_name), model, profile, settings)
    stage = OutputStage(EnvelopeSource(renderer), profile, "audio", rate, renderer.carrier_hz)
    stop = threading.Event()

    def feeder():
        start = time.perf_counter()
        while not stop.is_set():
            t = time.perf_counter()
            phase = (t - start) * 2.0
            renderer.push(t, 40 + 30 * np.cos(phase), 25 + 15 * np.sin(phase), 0.5)
            time.sleep(1 / 120)

    thread = threading.Thread(target=feeder, daemon=True)
    thread.start()
    time.sleep(0.05)
    times = np.empty(BLOCKS)
    for i in range(BLOCKS):
        started = time.perf_counter()
        stage.pull(frames, started)
        times[i] = time.perf_counter() - started
    stop.set()
    thread.join()
    return times[100:] * 1e6


def main() -> None:
    header = ("texture", "model", "block", "median µs", "p99 µs", "p99.9 µs", "budget µs")
    print("{:14} {:12} {:>12} {:>10} {:>8} {:>9} {:>10}".format(*header))
    for texture in ("grating-1mm", "bumps"):
        for name, model in (("exponential", ExponentialModel()), ("paper", PaperModel())):
            for frames, rate in ((64, 96000), (128, 192000)):
                t = measure(texture, model, frames, rate)
                budget = 0.1 * frames / rate * 1e6
                print(f"{texture:14} {name:12} {frames:4} @ {rate // 1000:3} kHz {np.median(t):10.1f} "
                      f"{np.percentile(t, 99):8.1f} {np.percentile(t, 99.9):9.1f} {budget:10.1f}")
    print(f"({BLOCKS} blocks each; a feeder thread pushes reports at 120 Hz)")


if __name__ == "__main__":
    main()
