"""The layers of the design card, enforced: every import of every module of ours (at the top, inside functions,
under TYPE_CHECKING) goes in the allowed direction.

    textures, devices, render.physics -> nothing of ours (but the root's leaf modules)
    render (the signal path)          -> physics, textures
    render.engine                     -> render, physics, textures, devices
    ultraglide.experiment             -> render.engine and below (designs, stimulus checks, sessions, analyses)
    ultraglide (the public API)       -> everything but apps
    apps                              -> anything;  nothing imports apps
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from conftest import ROOT

FOLDERS = {"textures": "ultraglide.textures", "devices": "ultraglide.devices", "render": "ultraglide.render",
           "apps": "ultraglide.apps", "ultraglide": "ultraglide"}
# the root's leaves: they import nothing of ours but each other
ROOT_LEAVES = {"ultraglide.errors", "ultraglide.atomic", "ultraglide.atomic.writer", "ultraglide.atomic.targets",
               "ultraglide.atomic.failures", "ultraglide.atomic.leftovers", "ultraglide.inputs",
               "ultraglide.lazy"}
ALLOWED = {
    "textures": {"textures"},
    "devices": {"devices"},
    "physics": {"physics"},
    "render": {"render", "physics", "textures"},
    "engine": {"engine", "render", "physics", "textures", "devices"},
    "experiment": {"experiment", "engine", "render", "physics", "textures", "devices"},
    "api": {"api", "experiment", "engine", "render", "physics", "textures", "devices"},
    "apps": {"apps", "api", "experiment", "engine", "render", "physics", "textures", "devices"},
}


def layer_of(module: str) -> str:
    for prefix, layer in (("ultraglide.render.physics", "physics"), ("ultraglide.render.engine", "engine"),
                          ("ultraglide.experiment", "experiment"),
                          ("ultraglide.render", "render"), ("ultraglide.textures", "textures"),
                          ("ultraglide.devices", "devices"), ("ultraglide.apps", "apps")):
        if module == prefix or module.startswith(prefix + "."):
            return layer
    return "api"


def modules() -> dict[str, Path]:
    found = {}
    for folder, package in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((package, *parts))] = path
    return found


def imports_of(name: str, path: Path) -> list[tuple[str, int]]:
    """Every module of ours that ``name`` imports, with the line."""
    found = []
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base
                                                                                                   else []))
            for alias in node.names:  # `from pkg import module` imports the module
                found.append((f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base, node.lineno))
    return [(module, line) for module, line in found if module == "ultraglide" or module.startswith("ultraglide.")]


MODULES = modules()


def test_the_walk_sees_every_layer():
    layers = {layer_of(name) for name in MODULES}
    assert layers == set(ALLOWED), layers
    assert len(MODULES) > 100


@pytest.mark.parametrize("name", sorted(MODULES))
def test_imports_follow_the_layers(name):
    layer = layer_of(name)
    wrong = []
    for module, line in imports_of(name, MODULES[name]):
        if module in ROOT_LEAVES or (name == "ultraglide.__main__" and module.startswith("ultraglide.apps.")):
            continue
        if module == "ultraglide" and layer != "apps":
            wrong.append(f"line {line}: the package root (it re-exports every layer)")
        elif layer_of(module) not in ALLOWED[layer]:
            wrong.append(f"line {line}: {module} ({layer_of(module)})")
    assert not wrong, f"{name} ({layer}) imports against the layers: " + "; ".join(wrong)


def test_the_root_leaves_import_nothing_of_ours_but_each_other():
    for leaf in ROOT_LEAVES:
        assert {module for module, _ in imports_of(leaf, MODULES[leaf])} <= ROOT_LEAVES - {leaf}
