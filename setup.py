"""The firmware core's shared library for the simulated plate (software in the loop); everything else about
the package is in pyproject.toml.

The core (devices/firmware/core) and the simulator's port (ports/sim) are built into one shared library,
``ultraglide.devices.firmware._sil``: importable as an (empty) extension module, so Python finds it, and
loaded by devices/firmware/sil.py with ctypes, which calls the port's C functions. Warnings are errors, as
in the board build; the simulator's build alone can break protocol rules on purpose (UG_CONFORMANCE_BREAKS).
"""

import hashlib
from pathlib import Path

from setuptools import Extension, setup

FIRMWARE = "devices/firmware"
SOURCES = ("core/*.c", "core/*.h", "core/*.inc", "include/*.h", "ports/sim/*.c", "ports/sim/*.h")


def sources_digest() -> str:
    """SHA-256 of the sources the library is built from (devices/firmware/sil.py computes the same and refuses
    a library built from other sources)."""
    digest = hashlib.sha256()
    for pattern in SOURCES:
        for path in sorted(Path(FIRMWARE).glob(pattern)):
            digest.update(path.relative_to(FIRMWARE).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


setup(ext_modules=[Extension(
    "ultraglide.devices.firmware._sil",
    sources=[path.as_posix() for path in sorted(Path(FIRMWARE).glob("core/*.c"))]  # every file of the core
    + [f"{FIRMWARE}/ports/sim/ug_sim.c", f"{FIRMWARE}/ports/sim/module.c"],
    include_dirs=[f"{FIRMWARE}/include", f"{FIRMWARE}/core", f"{FIRMWARE}/ports/sim"],
    define_macros=[("UG_CONFORMANCE_BREAKS", "1"), ("UG_SOURCES_DIGEST", f'"{sources_digest()}"')],
    extra_compile_args=["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-Wshadow", "-Wdouble-promotion"],
    libraries=["m"],
)])
