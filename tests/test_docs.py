"""The documentation site builds from the docstrings without a warning (``mkdocs build --strict``), and
covers the API: every public name has its reference entry, every guide page is in the navigation."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT

import ultraglide


@pytest.mark.slow
def test_site_builds_strictly(tmp_path):
    # as on a fresh clone: the namespace tree the build hook makes is not there yet (a build that only worked
    # when an earlier build had left it behind failed CI's first run)
    shutil.rmtree(ROOT / "build" / "api-namespace", ignore_errors=True)
    site = tmp_path / "site"
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
                            capture_output=True, text=True, cwd=ROOT, timeout=600,
                            env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert result.returncode == 0, result.stderr[-4000:]
    warnings = [line for line in result.stderr.splitlines() if line.startswith(("WARNING", "ERROR"))]
    assert not warnings, warnings
    api = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    # the reference is rendered from the docstrings: signatures and their units appear
    assert "export_wav" in api and "µm p-p" in api
    assert 'id="ultraglide.api.Renderer"' in api and 'id="ultraglide.api.render_swipe"' in api
    blocks = (site / "reference" / "building-blocks" / "index.html").read_text(encoding="utf-8")
    assert 'id="ultraglide.textures.compose.mix"' in blocks and 'id="ultraglide.api.write_wav"' in blocks
    for page in ("guide/textures", "guide/models", "guide/renderer", "guide/devices", "guide/safety",
                 "guide/engine", "guide/calibration", "guide/commands", "physics", "protocol"):
        assert (site / page / "index.html").is_file(), page


def test_api_reference_lists_every_public_name():
    import importlib

    reference = (ROOT / "docs" / "reference" / "api.md").read_text(encoding="utf-8")
    entries = re.findall(r"^::: ([\w.]+)\.(\w+)$", reference, flags=re.MULTILINE)
    assert {name for _, name in entries} == set(ultraglide.__all__) - {"__version__"}
    for module, name in entries:  # each entry documents the very object ``ultraglide.<name>`` is
        assert getattr(importlib.import_module(module), name) is getattr(ultraglide, name), f"{module}.{name}"


def test_every_page_is_in_the_navigation():
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    pages = {str(path.relative_to(ROOT / "docs")) for path in (ROOT / "docs").rglob("*.md")}
    missing = [page for page in sorted(pages) if page not in config]
    assert not missing, f"pages not in mkdocs.yml's nav: {missing}"


# ---- the docs against the code ---------------------------------------------------------------------------------

GUIDES = sorted((ROOT / "docs" / "guide").glob("*.md")) + [ROOT / "docs" / "index.md"]
NOT_RUN = re.compile(r"<!-- not run: [^>]+ -->\s*$")  # the line before a code block that is not to be run, and why


def _pages() -> list:
    return sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]


def _ids(page) -> set[str]:
    """The anchors a page has as the site renders it (Python-Markdown's toc, as mkdocs.yml configures it)."""
    import markdown

    html = markdown.Markdown(extensions=["toc", "tables", "admonition", "pymdownx.superfences"]).convert(
        page.read_text(encoding="utf-8"))
    return set(re.findall(r'\bid="([^"]+)"', html))


def test_every_internal_link_and_anchor_resolves():
    broken = []
    ids: dict = {}
    for page in _pages():
        text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.DOTALL)  # not links in code
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):  # https:, mailto: ...
                continue
            file, _, anchor = target.partition("#")
            resolved = (page.parent / file).resolve() if file else page
            if not resolved.exists():
                broken.append(f"{page.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and resolved.suffix == ".md":
                if resolved not in ids:
                    ids[resolved] = _ids(resolved)
                if anchor not in ids[resolved]:
                    broken.append(f"{page.relative_to(ROOT)}: {target} (no such anchor)")
    assert not broken, broken


# what a guide's instance names stand for: `renderer.control(` is Renderer's control
INSTANCES = {"renderer": "Renderer", "engine": "Engine", "status": "EngineStatus", "model": "FrictionModel",
             "device": "Device", "texture": "Texture", "stage": "OutputStage", "sampler": "Sampler"}
# the system's, numpy's, the library's
FOREIGN = {"prctl", "reshape", "limit_denominator", "time.perf_counter", "numpy.fromfile"}


def _defined_names() -> set[str]:
    """Every function, method and class name our sources define, the firmware's C functions too."""
    import ast

    names = {name for path in (ROOT / "devices" / "firmware").rglob("*.[ch]")
             for name in re.findall(r"\b(ug_\w+)\s*\(", path.read_text(encoding="utf-8", errors="replace"))}
    for folder in ("ultraglide", "render", "textures", "devices", "apps"):
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                    names.add(node.name)
    return names


def test_every_documented_call_exists():
    """Each `name(` a guide mentions: ``ultraglide.X.y(`` resolves from the package, ``Class.method(`` and
    ``instance.method(`` (renderer, engine ...) are members of the public class, a bare ``name(`` is defined in
    our sources."""
    defined = _defined_names()
    missing = []
    for page in GUIDES:
        for reference in re.findall(r"`([A-Za-z_][\w.]*)\(", page.read_text(encoding="utf-8")):
            parts = reference.split(".")
            if parts[0] == "ultraglide":
                value = ultraglide
                for part in parts[1:]:
                    value = getattr(value, part, None)
                ok = value is not None
            elif len(parts) == 2 and (parts[0] in ultraglide.__all__ or parts[0] in INSTANCES):
                ok = hasattr(getattr(ultraglide, INSTANCES.get(parts[0], parts[0])), parts[1])
            else:
                ok = parts[-1] in defined or reference in FOREIGN
            if not ok:
                missing.append(f"{page.relative_to(ROOT)}: {reference}(")
    assert not missing, missing


def _examples(language: str) -> list:
    found = []
    for page in [*GUIDES, ROOT / "README.md"]:
        lines = page.read_text(encoding="utf-8").splitlines()
        for number, line in enumerate(lines):
            if line.strip() == f"```{language}":
                end = lines.index("```", number + 1)
                if not (number and NOT_RUN.search(lines[number - 1])):
                    found.append(pytest.param("\n".join(lines[number + 1:end]),
                                              id=f"{page.relative_to(ROOT)}:{number + 1}"))
    return found


@pytest.mark.parametrize("code", _examples("python"))
def test_every_python_example_in_the_guides_runs(tmp_path, code):
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]


@pytest.mark.parametrize("code", _examples("sh"))
def test_every_command_in_the_guides_parses(code):
    """Each ``ultraglide ...`` line of a shell example is one the command's parser accepts (its options exist and
    take what they are given); the commands themselves run in their own tests."""
    import shlex

    from ultraglide.apps.cli.parser import build_parser

    for line in code.splitlines():
        words = shlex.split(re.sub(r"\[[^]]*\]", "", line), comments=True)  # [optional] parts left out
        words = words[:-1] if words and words[-1] == "&" else words  # a job started in the background
        if not words or words[0] != "ultraglide":
            continue
        words = words[1:]
        try:
            build_parser(words).parse_args(words)
        except SystemExit as exit_:
            pytest.fail(f"{line!r} is refused by the parser (exit {exit_.code})")
