"""Texture sampling speed: samples per second on one core.

Run: .venv/bin/python bench/bench_sampling.py
Aim (issue 3): >= 10 million bilinear samples per second.
"""

from __future__ import annotations

import time

import numpy as np
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.sampling import Sampler

N = 1_000_000
REPEATS = 10


def rate(function) -> float:
    best = np.inf
    for _ in range(REPEATS):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return N / best / 1e6


def main() -> None:
    rng = np.random.default_rng(0)
    x = rng.uniform(-5, 85, N)
    y = rng.uniform(-5, 55, N)
    t = np.linspace(0, 30, N)  # a finger circling at ~200 mm/s, as the renderer asks
    path_x, path_y = 40 + 20 * np.cos(t * 1.6), 25 + 20 * np.sin(t * 1.6)
    step = rng.uniform(0.0, 1.0, N)
    print(f"{'texture':14} {'query':28} {'M samples/s':>12}")
    for name in ("grating-1mm", "wood", "bumps"):
        texture = resolve_texture(name)
        sampler = Sampler(texture)
        direction = (np.gradient(path_x), np.gradient(path_y))
        cases = {
            "bilinear, random points": lambda s=sampler: s.ratio(x, y),
            "bilinear, finger path": lambda s=sampler, d=direction: s.ratio(path_x, path_y, direction=d),
            "band-limited, one step": lambda s=sampler: s.ratio(x, y, step_mm=0.3),
            "band-limited, step a sample": lambda s=sampler: s.ratio(x, y, step_mm=step),
        }
        for label, case in cases.items():
            print(f"{name:14} {label:28} {rate(case):12.1f}")
    print(f"({N:,} samples a call, best of {REPEATS})")


if __name__ == "__main__":
    main()
