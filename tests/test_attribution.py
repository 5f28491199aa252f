"""Every number the physics pages and docstrings attribute to a paper is a figure that paper states, with its place.

The registry is ``render/physics/sources.py``; the physics page lists it in a table. A sentence that names a cited
author and writes a quantity must find that quantity among the figures of the papers it names, or mark it as
ours ("ours", "our", "we"): model outputs are never attributed to a paper.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from ultraglide.render.physics.sources import AUTHORS, FIGURES, PAPERS

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "docs" / "physics.md", ROOT / "docs" / "guide" / "models.md"]
CODE = sorted((ROOT / "render" / "physics").glob("*.py")) + [ROOT / "render" / "planning.py",
                                                                ROOT / "devices" / "sim" / "finger.py"]
QUANTITY = re.compile(r"(?<![\w.:/(])(\d+(?:[ .]\d+)?)\s*(?:±\s*\d+(?:\.\d+)?\s*)?(?:[-–]\s*\d+(?:\.\d+)?\s*)?"
                      r"(µm⁻²|µm|ms|mm/s|kHz|Hz|kPa|N\b|%)")
BARE_DECIMAL = re.compile(r"(?<![\w.:/(])(0\.\d+)(?![\d\w]|\s*(?:[-–±]|µm|ms|mm/s|kHz|Hz|kPa|N\b|%))")
OURS = re.compile(r"\b(ours|our|we|ultraglide's)\b", re.IGNORECASE)
NUMBER = re.compile(r"\d+(?:[ .]\d+)?")


def _numbers(text: str) -> set[float]:
    return {float(n.replace(" ", "")) for n in NUMBER.findall(text)}


def _sentences(text: str, code: bool = False) -> list[str]:
    """Sentences (a docstring's also split at each line that starts unindented: numpy-style fields)."""
    parts = re.split(r"\n(?=\S)", text) if code else [text]
    sentences = []
    for part in parts:
        part = re.sub(r"\s+", " ", part.replace("et al.", "et al"))
        sentences += [s for s in re.split(r"(?<=[.;])\s+(?=[A-Z(*`|])| \| ", part) if s.strip()]
    return sentences


def _docstrings_and_comments(path: Path) -> list[str]:
    if not path.exists():
        return []
    source = path.read_text(encoding="utf-8")
    texts = [line.split("#", 1)[1] for line in source.splitlines() if "#" in line and not line.strip().startswith('"')]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node)
            if doc:
                texts.append(doc)
    return texts


def _texts() -> list[tuple[str, str]]:
    found = []
    for page in PAGES:
        found += [(page.name, paragraph) for paragraph in page.read_text(encoding="utf-8").split("\n\n")]
    for path in CODE:
        found += [(path.name, text) for text in _docstrings_and_comments(path)]
    return found


def unattributed(sentence: str) -> list[str]:
    """The quantities in ``sentence`` that name a cited author but are no figure of that author's papers."""
    named = {key for key, author in AUTHORS.items() if re.search(rf"\b{author}\b", sentence)}
    if not named or OURS.search(sentence):
        return []
    allowed = set().union(*(_numbers(f.value) | _numbers(f.what) for f in FIGURES if f.paper in named))
    quantities = [m.group(0) for m in QUANTITY.finditer(sentence)] + BARE_DECIMAL.findall(sentence)
    return [q for q in quantities if not _numbers(q) <= allowed]


def test_every_figure_names_its_paper_and_place():
    for figure in FIGURES:
        assert figure.paper in PAPERS, figure
        assert figure.where.strip(), figure
        assert re.search(r"§|Fig|Table|abstract|law|README|not located", figure.where), figure
        assert re.search(r"\d", figure.value), figure
    assert len({f.key for f in FIGURES}) == len(FIGURES)


def test_the_physics_page_lists_every_figure_with_its_source():
    page = (ROOT / "docs" / "physics.md").read_text(encoding="utf-8")
    block = page.split("<!-- published figures -->")[1].split("<!-- end of published figures -->")[0]
    rows = [[cell.strip() for cell in line.strip().strip("|").split("|")] for line in block.splitlines()
            if line.startswith("|") and not line.startswith("|---") and not line.startswith("| figure |")]
    expected = [[f.value, f.what, f.paper, f.where + ("" if f.checked else " (unchecked)")] for f in FIGURES]
    assert rows == expected


def test_the_detector_catches_a_misattribution():
    # the error this test exists for: our own squeeze-film output written as a paper's measurement
    assert unattributed("Friesen et al. 2018 measured: 0.76 at 6 µm and 0.5 N at 2 kPa") == [
        "6 µm", "0.5 N", "2 kPa", "0.76"]
    assert unattributed("our squeeze-film model gives 0.76 at 6 µm, where Friesen et al. measured nothing") == []
    assert unattributed("Meyer et al. 2014 saw recovery over 70 ms at 22 mm/s") == []
    assert unattributed("Meyer et al. 2014 saw recovery over 15 ms") == ["15 ms"]


@pytest.mark.parametrize("where, text", _texts(), ids=lambda v: v if isinstance(v, str) and len(v) < 30 else "")
def test_every_attributed_number_is_a_published_figure(where, text):
    for sentence in _sentences(text, code=where.endswith(".py")):
        assert not unattributed(sentence), f"{where}: {sentence!r} attributes {unattributed(sentence)}"
