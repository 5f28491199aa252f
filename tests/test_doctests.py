"""The examples in the docstrings run and print what they say, module by module of the installed package."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

PACKAGES = ("textures", "devices", "render", "apps", "experiment")
MODULES = sorted(
    info.name
    for package in PACKAGES
    for info in pkgutil.walk_packages(importlib.import_module(f"ultraglide.{package}").__path__,
                                      f"ultraglide.{package}.")
) + ["ultraglide", "ultraglide.experiment"] + sorted(  # packages too: a room's __init__ may hold code
    # (ultraglide.devices.protocol); the root and the experiment package: their own docstrings; the modules beside
    # the root (api, errors ...)
    f"ultraglide.{info.name}" for info in pkgutil.iter_modules(importlib.import_module("ultraglide").__path__)
    if not info.ispkg and info.name not in ("__main__",)
)

# Modules whose examples are the user's first reading: each must hold at least one, so an example deleted (or a
# docstring doctest no longer finds) fails here instead of passing with nothing run
WITH_EXAMPLES = {"ultraglide.experiment", "ultraglide.experiment.design", "ultraglide.experiment.analysis",
                 "ultraglide.experiment.columns", "ultraglide.experiment.check", "ultraglide.experiment.runner"}


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
    if name in WITH_EXAMPLES:
        assert result.attempted > 0, f"{name} has no example"


def test_every_signal_module_is_checked() -> None:
    assert {"ultraglide.render.renderer", "ultraglide.textures.sampling", "ultraglide.devices.protocol",
            "ultraglide.render.physics.friction_models", "ultraglide.render.engine.engine",
            "ultraglide.apps.demo.app", "ultraglide", "ultraglide.api"} | WITH_EXAMPLES <= set(MODULES)
