"""Compile every compiled kernel of ours into numba's cache at once: ``python -m ultraglide.compile_kernels``.

A kernel is compiled the first time a process calls it and finds no cache entry for it (about 10 s of CPU for all
of them on a 2-core machine), then loaded from the cache by every later process. On a fresh install several
processes start at once (the demo and its engine, a test run's workers and their command servers) and each would
compile the same kernels; ``./run`` calls this once after installing, so none does.
"""

from __future__ import annotations

import importlib
import sys
import time

# every module of ours that defines a compiled kernel (tests/test_compile_kernels.py checks the sources for others)
KERNEL_MODULES = ("ultraglide.render.kernels", "ultraglide.render.physics.kernels", "ultraglide.render.effects",
                  "ultraglide.render.physics.dynamics_fit",
                  "ultraglide.devices.output.kernels", "ultraglide.devices.sim.force_sensors",
                  "ultraglide.devices.sim.kernels", "ultraglide.textures.kernels",
                  "ultraglide.textures.formats.kernels")


def compile_all() -> int:
    """Compile (or load from the cache) each kernel with the types our code calls it with; the number of kernels."""
    import numpy as np

    from ultraglide.devices.output import kernels as device_kernels
    from ultraglide.devices.sim import force_sensors
    from ultraglide.devices.sim import kernels as sim_kernels
    from ultraglide.render import effects
    from ultraglide.render import kernels as render_kernels
    from ultraglide.render.physics import dynamics_fit
    from ultraglide.render.physics import kernels as physics_kernels
    from ultraglide.textures import kernels as texture_kernels
    from ultraglide.textures.formats import kernels as format_kernels

    for warm_up in (render_kernels.warm_up, physics_kernels.warm_up, effects.warm_up, device_kernels.warm_up,
                    texture_kernels.warm_up, format_kernels.warm_up):
        warm_up()
    force_sensors.low_pass(np.zeros((2, 4)), 0.5, np.zeros(2))
    sim_kernels.friction_lag(np.ones(2), np.ones(2), np.ones(2), 0.05, 48000.0, 0.005, 0.07, 22.0, 0.5, 2.0, 1.0,
                             np.empty(2))  # the simulated finger's lag, typed as devices/sim/finger.py calls it
    dynamics_fit._lag_courses(np.ones(8), np.full(2, 0.5), 8, np.empty((2, 1)))  # calibrate's edge fit
    return len(kernels())


def kernels() -> dict[str, object]:
    """Each compiled kernel of ours (``module.name``: its numba dispatcher)."""
    from numba.core.dispatcher import Dispatcher

    found = {}
    for name in KERNEL_MODULES:
        module = importlib.import_module(name)
        for attribute, value in vars(module).items():
            if isinstance(value, Dispatcher) and value.py_func.__module__ == name:
                found[f"{name}.{attribute}"] = value
    return found


def uncompiled() -> list[str]:
    """The kernels called from Python that this process has no compiled version of (after :func:`compile_all`:
    none). A kernel only other kernels call is compiled into them, and has none of its own."""
    found = kernels()
    inner = {name for dispatcher in found.values() for name in dispatcher.py_func.__code__.co_names}
    return sorted(name for name, dispatcher in found.items()
                  if not dispatcher.signatures and name.rpartition(".")[2] not in inner)


def main() -> int:
    started = time.perf_counter()
    count = compile_all()
    print(f"{count} compiled kernels in numba's cache ({time.perf_counter() - started:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
