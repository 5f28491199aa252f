"""What temporal effects cost on the live block path: one 8-sample control block (64 frames at 96 kHz),
a live finger dragging over the widgets' slider, with and without the widgets' effects (click, detent
pulses, buzz, snap), back to back. Prints the renderer's block time (median and p99, µs) both ways and
the effect player's own share.

    .venv/bin/python bench/bench_effects.py
"""

from __future__ import annotations

import time

import numpy as np
from ultraglide.devices.profiles import load_profile
from ultraglide.render.physics.friction_models import ExponentialModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.textures import effects as fx
from ultraglide.textures import procedural

BLOCK = 8
BLOCKS = 20000
CONTROL_HZ = 12000.0


def bindings(slider_w: float, slider_h: float) -> tuple:
    track = (0.0, 0.3 * slider_h, slider_w, 0.4 * slider_h)
    stops = tuple(float(v) for v in np.linspace(0.08 * slider_w, 0.92 * slider_w, 6))
    return (fx.Binding(fx.Trigger("start", (0.0, 0.0, 10.0, 10.0)), fx.click()),
            fx.Binding(fx.Trigger("cross", track, lines_mm=stops), fx.pulse()),
            fx.Binding(fx.Trigger("while", track, min_speed_mm_s=20.0), fx.buzz(), release_s=0.04),
            fx.Binding(fx.Trigger("start", (slider_w - 10.0, 0.0, 10.0, 10.0)), fx.snap()))


def run(with_effects: bool) -> tuple[np.ndarray, np.ndarray]:
    slider = procedural.slider(size_mm=(140.0, 24.0), detents=6)
    texture = slider.with_(effects=bindings(140.0, 24.0) if with_effects else ())
    renderer = Renderer(texture, ExponentialModel(), load_profile("sim-plate"), RenderSettings())
    buffers = renderer.control_buffers(4096, always=True)
    player = renderer.effects
    block_s, mix_s = np.empty(BLOCKS), np.empty(BLOCKS)
    t = time.perf_counter()
    for k in range(BLOCKS):  # a finger sweeping the track back and forth at 100 mm/s, reported every 8 ms
        if k % 12 == 0:
            phase = (k * BLOCK / CONTROL_HZ * 100.0) % 260.0
            x = 10.0 + (phase if phase < 130.0 else 260.0 - phase) * (120.0 / 130.0)
            renderer.push(t, x, 12.0)
        started = time.perf_counter()
        if player is not None:
            before = player.started
        renderer.control(BLOCK, t, out=buffers)
        block_s[k] = time.perf_counter() - started
        mix_s[k] = player.started - before if player is not None else 0
        t += BLOCK / CONTROL_HZ
    return block_s[1000:], mix_s


def main() -> None:
    plain, _ = run(False)
    effects, started = run(True)
    for name, times in (("without effects", plain), ("with the widgets' effects", effects)):
        p50, p99 = np.percentile(times * 1e6, [50, 99])
        print(f"{name:28s} one {BLOCK}-sample block: median {p50:.1f} µs, p99 {p99:.1f} µs")
    print(f"effects started over the run: {int(started.sum())}; the difference is the effects' cost")


if __name__ == "__main__":
    main()
