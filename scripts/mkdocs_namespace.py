"""MkDocs hook: lay the ``ultraglide`` namespace out as one folder tree for mkdocstrings.

The distribution maps top-level folders into the namespace (``render/`` is ``ultraglide.render``,
pyproject.toml's package-dir), which static analysis (griffe) cannot follow. Before each build this
makes ``build/api-namespace/ultraglide/``: copies of ``ultraglide/*.py`` (copies, since griffe follows a
linked ``__init__.py`` back to the real folder) and a symbolic link per mapped folder, so the API
reference is read from the sources as they are.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from mkdocs.plugins import event_priority

ROOT = Path(__file__).resolve().parent.parent
TREE = ROOT / "build" / "api-namespace" / "ultraglide"
FOLDERS = ("render", "textures", "devices", "apps")


@event_priority(100)  # before mkdocstrings reads its paths: a path that does not exist yet is dropped
def on_config(config):
    shutil.rmtree(TREE, ignore_errors=True)
    TREE.mkdir(parents=True)
    for module in (ROOT / "ultraglide").glob("*.py"):
        shutil.copy2(module, TREE / module.name)
    for folder in FOLDERS:
        (TREE / folder).symlink_to(ROOT / folder, target_is_directory=True)
    return config
