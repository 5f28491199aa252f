"""Friction-model speed: inverse evaluations per second on one core, and build time.

Run: .venv/bin/python bench/bench_models.py
Aims (issues 2 and 12): >= 20 million inverse evaluations per second, with one force or a force per
sample (a pressure-sensing panel); building a model <= 50 ms; inverse exact to 1e-3 in ratio.
"""

from __future__ import annotations

import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from ultraglide.render.physics.friction_models import (  # noqa: E402
    ExponentialModel,
    PaperModel,
    StretchedExponentialModel,
    TableModel,
)
from ultraglide.render.physics.measurements import read_measurements  # noqa: E402

N = 1_000_000
REPEATS = 15
DATA = os.path.join(os.path.dirname(__file__), "..", "apps", "data", "monnoyer2018-fit.csv")


def best_rate(function) -> float:
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return N / min(times)


def median_ms(function, repeats: int = 9) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def main() -> None:
    rng = np.random.default_rng(1)
    random_ratio = rng.uniform(0.5, 1.0, N)
    swipe_ratio = 0.75 + 0.2 * np.sin(np.linspace(0, 2000 * np.pi, N))  # a texture under a finger
    amplitude = rng.uniform(0.0, 8.0, N)
    pressing = 0.5 + 0.3 * np.sin(np.linspace(0, 200 * np.pi, N))  # a finger pressing 0.2-0.8 N
    builders = {
        "paper": PaperModel,
        "exponential": ExponentialModel,
        "stretched": StretchedExponentialModel,
        "table": lambda: TableModel(read_measurements(DATA)),
    }
    print(f"{'model':12} {'build ms':>9} {'inverse M/s':>12} {'(swipe)':>9} {'(forces)':>9} {'forward M/s':>12}"
          f" {'max error':>10}")
    for name, build in builders.items():
        model = build()
        build_ms = median_ms(build)
        inverse = best_rate(lambda m=model: m.amplitude_um_pp(random_ratio, 0.5, 10.0)) / 1e6
        swipe = best_rate(lambda m=model: m.amplitude_um_pp(swipe_ratio, 0.5, 10.0)) / 1e6
        forces = best_rate(lambda m=model: m.amplitude_um_pp(swipe_ratio, pressing, 10.0)) / 1e6
        forward = best_rate(lambda m=model: m.relative_friction(amplitude, 0.5)) / 1e6
        result = model.amplitude_um_pp(swipe_ratio, pressing, 10.0)
        reached = result.amplitude_um_pp < min(10.0, model.max_amplitude_um_pp)
        error = np.max(np.abs(model.relative_friction(result.amplitude_um_pp, pressing) - swipe_ratio)[reached])
        print(f"{name:12} {build_ms:9.1f} {inverse:12.1f} {swipe:9.1f} {forces:9.1f} {forward:12.1f} {error:10.1e}")
    print(f"({N:,} samples a call, best of {REPEATS}; force 0.5 N, or 0.2-0.8 N per sample for (forces); "
          "limit 10 µm p-p; max error in ratio over the swipe with forces)")


if __name__ == "__main__":
    main()
