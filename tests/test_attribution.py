"""Every number the physics pages and docstrings attribute to a paper is a figure that paper states, with its place.

The registry is ``render/physics/sources.py``; the physics page lists it in a table. A sentence that names a cited
author and writes a quantity must find that quantity among the figures of the papers it names, or mark it as
ours ("ours", "our", "we"): model outputs are never attributed to a paper. Every page under docs/, the README and
the changelog are read, and the docstrings and comments of the physics, the planner, the simulated finger, plate
profiles and textures; a sentence is read whole across its line breaks, and a year after the name picks the paper.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from ultraglide.render.physics.sources import AUTHORS, FIGURES, PAPERS

ROOT = Path(__file__).resolve().parent.parent
# Every page a reader reads and the code whose words cite papers: the physics, the simulated finger, plate profiles
# and textures.
PAGES = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md", ROOT / "CHANGELOG.md"]
CODE = (sorted((ROOT / "render" / "physics").glob("*.py")) + [ROOT / "render" / "planning.py",
                                                               ROOT / "devices" / "sim" / "finger.py",
                                                               ROOT / "devices" / "profiles.py"]
        + sorted((ROOT / "textures").rglob("*.py")))
QUANTITY = re.compile(r"(?<![\w.:/(])(\d+(?:[ .]\d+)?)\s*(?:±\s*\d+(?:\.\d+)?\s*)?(?:[-–]\s*\d+(?:\.\d+)?\s*)?"
                      r"(µm⁻²|µm|µs|ms|mm/s|kHz|Hz|kPa|MPa|N\b|%)")
BARE_DECIMAL = re.compile(r"(?<![\w.:/(])(0\.\d+)(?![\d\w]|\s*(?:[-–±]|µm|µs|ms|mm/s|kHz|Hz|kPa|MPa|N\b|%))")
OURS = re.compile(r"\b(ours|our|we|ultraglide's)\b", re.IGNORECASE)
NUMBER = re.compile(r"\d+(?:[ .]\d+)?")
YEAR = re.compile(r"\b(?:19|20)\d\d\b")
# A line that starts a block of its own: a markdown list item or table row; in a docstring also a numpy field
# ("name : type"), a section's underline and a doctest line.
LIST_ITEM = re.compile(r" {0,3}(?:[-*+]|\d+\.) |\|")
FIELD = re.compile(r"[A-Za-z_*][\w*]*(?:\s*,\s*[A-Za-z_*][\w*]*)*\s*:(?:\s|$)|-{3,}\s*$|\s*(?:>>>|\.\.\.)")


def _numbers(text: str) -> set[float]:
    return {float(n.replace(" ", "")) for n in NUMBER.findall(text)}


def _blocks(text: str, code: bool) -> list[str]:
    """Paragraphs, joined across their line breaks: split at blank lines and list items or table rows, and in a
    docstring also at numpy fields, underlines and doctest lines (a doctest's output is a block of its own)."""
    blocks, current, after_doctest = [], [], False
    for line in text.splitlines():
        doctest = code and line.strip().startswith((">>>", "..."))
        starts = (not line.strip() or LIST_ITEM.match(line)
                  or (code and (FIELD.match(line) or after_doctest)))
        if starts and current:
            blocks.append(" ".join(current))
            current = []
        if line.strip():
            current.append(line.strip())
        after_doctest = doctest
    return blocks + ([" ".join(current)] if current else [])


def _sentences(text: str, code: bool = False) -> list[str]:
    """Sentences of a page's paragraph or of a docstring or comment block."""
    sentences = []
    for part in _blocks(text, code):
        part = re.sub(r"\s+", " ", part.replace("et al.", "et al"))
        sentences += [s for s in re.split(r"(?<=[.;])\s+(?=[A-Z(*`|])| \| ", part) if s.strip()]
    return sentences


def _docstrings_and_comments(path: Path) -> list[str]:
    """The docstrings of ``path`` and its comments: a run of comment lines is one text, an inline comment its own."""
    if not path.exists():
        return []
    source = path.read_text(encoding="utf-8")
    texts, run = [], []
    for line in source.splitlines():
        if line.lstrip().startswith("#"):
            run.append(line.lstrip()[1:])
            continue
        if run:
            texts.append("\n".join(run))
            run = []
        if "#" in line and not line.strip().startswith('"'):
            texts.append(line.split("#", 1)[1])
    if run:
        texts.append("\n".join(run))
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


def _named(sentence: str) -> set[str]:
    """The papers ``sentence`` cites: its author's surname, and the year if one follows the name (within 80
    characters: "Meyer, Wiertlewski, Peshkin and Colgate (2014)" cites Meyer2014, not Wiertlewski2016)."""
    named = set()
    for key, author in AUTHORS.items():
        for match in re.finditer(rf"\b{author}\b", sentence):
            year = YEAR.search(sentence, match.end(), match.end() + 80)
            if year is None or key.endswith(year.group(0)):
                named.add(key)
    return named


def unattributed(sentence: str) -> list[str]:
    """The quantities in ``sentence`` that name a cited author but are no figure of that author's papers."""
    named = _named(sentence)
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


def test_the_detector_reads_a_sentence_across_its_line_breaks(tmp_path):
    # a docstring's paragraph and a run of comments are read whole: the author on one line, the figure on the next
    source = tmp_path / "module.py"
    source.write_text('''"""Recovery, as Meyer et al. 2014 measured it at
22 mm/s, takes 45 ms.

Parameters
----------
recovery_s : float
    Meyer et al. 2014: 70 ms.
"""

# Huloux et al. (2018) saw friction
# settle in 12 ms.
ONSET_S = 0.005  # Meyer et al. 2014
''', encoding="utf-8")
    found = [q for text in _docstrings_and_comments(source) for sentence in _sentences(text, code=True)
             for q in unattributed(sentence)]
    assert sorted(found) == ["12 ms", "45 ms"]
    # list items are sentences of their own: a figure of ours in the next item is not the author's
    assert [unattributed(s) for s in _sentences("- Meyer et al. 2014: 5 ms\n- the plate's decay: 2.5 ms")] == [[], []]
    assert unattributed(_sentences("- Meyer et al. 2014: 5 ms, and\n  2.5 ms")[0]) == ["2.5 ms"]


def test_the_detector_tells_papers_by_their_year():
    # Monnoyer 2023's 20 ms is not a figure of Monnoyer 2018, nor Meyer 2014's 70 ms one of Wiertlewski 2016
    assert unattributed("Monnoyer et al. (2018) saw the skin release its strain over 20 ms") == ["20 ms"]
    assert unattributed("Monnoyer, Willemet and Wiertlewski (2023) saw a release over 20 ms") == []
    assert unattributed("Wiertlewski, Fenton Friesen and Colgate (2016) saw recovery over 70 ms") == ["70 ms"]
    assert unattributed("Meyer, Wiertlewski, Peshkin and Colgate (2014) saw recovery over 70 ms") == []
    assert unattributed("Monnoyer et al.'s 20 ms") == []  # no year: any of the author's papers


@pytest.mark.parametrize("where, text", _texts(), ids=lambda v: v if isinstance(v, str) and len(v) < 30 else "")
def test_every_attributed_number_is_a_published_figure(where, text):
    for sentence in _sentences(text, code=where.endswith(".py")):
        assert not unattributed(sentence), f"{where}: {sentence!r} attributes {unattributed(sentence)}"
