"""docs/experiments.md as a tutorial: every TOML file, command and Python block on it run, in order, in one folder."""

import re
import shlex
import sys

import pytest
from conftest import ROOT, run_cli

PAGE = ROOT / "docs" / "experiments.md"
BLOCK = re.compile(r"^```(toml|sh|python)\n(.*?)^```", re.DOTALL | re.MULTILINE)


def blocks():
    return [(kind, text) for kind, text in BLOCK.findall(PAGE.read_text(encoding="utf-8"))]


def test_the_page_has_the_three_studies_and_their_analysis():
    kinds = [kind for kind, _ in blocks()]
    assert kinds.count("toml") == 3 and kinds.count("python") == 2 and kinds.count("sh") >= 4


@pytest.mark.slow
def test_every_block_of_the_tutorial_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    ran = 0
    for kind, text in blocks():
        if kind == "toml":
            name = re.match(r"# (\S+\.toml):", text).group(1)  # each design names its file on its first line
            (tmp_path / name).write_text(text, encoding="utf-8")
            continue
        if kind == "python":
            exec(compile(text, f"{PAGE.name}:python", "exec"), namespace)  # noqa: S102 - the page's own code
            ran += 1
            continue
        for line in text.splitlines():
            line = line.split("  #")[0].strip()
            if not line:
                continue
            words = shlex.split(line)
            redirect = None
            if ">" in words:
                words, redirect = words[:words.index(">")], words[words.index(">") + 1]
            assert words[0] == "ultraglide", line
            result = run_cli(*words[1:], cwd=tmp_path)
            assert result.returncode == 0, f"{line}: {result.stderr}"
            assert "Traceback" not in result.stderr
            if redirect:
                (tmp_path / redirect).write_text(result.stdout, encoding="utf-8")
            ran += 1
    assert ran >= 8
    printed = capsys.readouterr().out
    assert "trials planned" in printed
    assert sys.modules.get("pandas") is not None
