"""``./run``: set-up installs only what is missing. Run on a copy of the script and what it installs from, with a
virtual environment whose python, ruff, basedpyright and ultraglide are scripts that write down how they were
called: the real script's logic, none of its installing."""

from __future__ import annotations

import shutil
import subprocess

import pytest
from conftest import ROOT

FAKE = """#!/bin/sh
echo "$(basename "$0") $*" >> "{log}"
"""


@pytest.fixture
def checkout(tmp_path):
    """A copy of ./run and pyproject.toml beside a .venv of recording stand-ins."""
    for name in ("run", "pyproject.toml", "setup.py"):
        shutil.copy(ROOT / name, tmp_path / name)
    for folder in ("include", "core", "ports/sim"):  # the firmware sources the install builds from
        shutil.copytree(ROOT / "devices" / "firmware" / folder, tmp_path / "devices" / "firmware" / folder)
    bin_dir = tmp_path / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    for name in ("python", "ruff", "basedpyright", "ultraglide"):
        (bin_dir / name).write_text(FAKE.format(log=tmp_path / "calls.log"))
        (bin_dir / name).chmod(0o755)
    return tmp_path


def run(checkout, *args) -> list[str]:
    """``./run ARGS`` in the copy; the stand-ins' calls it made."""
    log = checkout / "calls.log"
    log.write_text("")
    result = subprocess.run(["./run", *args], cwd=checkout, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    return log.read_text().splitlines()


def installs(calls: list[str]) -> list[str]:
    return [call for call in calls if call.startswith("python -m pip install -q -e")]


@pytest.mark.skipif(shutil.which("dpkg-query") is None, reason="./run checks system packages with dpkg")
def test_the_demo_after_the_tests_installs_nothing_again(checkout):
    calls = run(checkout, "tests", "--co")
    assert installs(calls) == ["python -m pip install -q -e .[test,demo,docs]"]
    after_install = calls.index("python -m pip install -q -e .[test,demo,docs]") + 1
    assert calls[after_install] == "python -m ultraglide.compile_kernels"  # compiled once, as installed
    assert "python -m pytest -n 3 --co" in calls
    calls = run(checkout, "demo", "--windowed")
    assert installs(calls) == [] and calls == ["ultraglide demo --windowed"]  # straight to the demo
    assert run(checkout, "tests", "-k", "x") == ["ruff check .", "basedpyright ", "python -m pytest -n 3 -k x"]
    # pyproject.toml changes: installed again, with everything that was there
    (checkout / "pyproject.toml").write_text((checkout / "pyproject.toml").read_text() + "\n# changed\n")
    assert installs(run(checkout, "demo")) == ["python -m pip install -q -e .[test,demo,docs]"]
    assert installs(run(checkout, "demo")) == []


@pytest.mark.skipif(shutil.which("dpkg-query") is None, reason="./run checks system packages with dpkg")
def test_the_tests_after_the_demo_install_what_the_tests_need(checkout):
    assert installs(run(checkout, "demo")) == ["python -m pip install -q -e .[demo]"]
    assert installs(run(checkout, "tests", "--co")) == ["python -m pip install -q -e .[demo,test,docs]"]
    assert installs(run(checkout, "demo")) == []


@pytest.mark.skipif(shutil.which("dpkg-query") is None, reason="./run checks system packages with dpkg")
def test_the_tests_keep_python_s_compiled_modules_even_where_the_shell_forbids_writing_them(checkout):
    """With PYTHONDONTWRITEBYTECODE set, each of the suite's interpreters would compile our modules afresh."""
    import os

    python = checkout / ".venv" / "bin" / "python"
    python.write_text(FAKE.format(log=checkout / "calls.log").replace(
        'echo "$(basename "$0") $*"', 'echo "$(basename "$0") $* [${PYTHONDONTWRITEBYTECODE-unset}]"'))
    run(checkout, "demo")  # installed once, so the calls below are the tests' own
    log = checkout / "calls.log"
    log.write_text("")
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    result = subprocess.run(["./run", "tests", "-k", "x"], cwd=checkout, env=env, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    assert log.read_text().splitlines()[-1] == "python -m pytest -n 3 -k x [unset]"


@pytest.mark.skipif(shutil.which("dpkg-query") is None, reason="./run checks system packages with dpkg")
def test_the_namespace_is_a_path_entry_tools_can_read(checkout):
    """A .pth path entry (which editors and analysers read; they do not run import hooks) to a folder holding only
    a link to ultraglide/, whose own links make the namespace a plain folder tree."""
    site = checkout / ".venv" / "lib" / "python3.11" / "site-packages"
    site.mkdir(parents=True)
    (checkout / "ultraglide").mkdir()
    run(checkout, "demo")
    entry = (site / "ultraglide-static.pth").read_text().strip()
    assert entry == str(checkout / ".venv" / "static")
    assert sorted(path.name for path in (checkout / ".venv" / "static").iterdir()) == ["ultraglide"]
    assert (checkout / ".venv" / "static" / "ultraglide").resolve() == (checkout / "ultraglide").resolve()


def test_the_repository_folder_is_the_whole_namespace():
    """ultraglide/ links the mapped folders in (pyproject.toml's package-dir), so that the namespace resolves
    from the folder tree alone: each link points at its folder."""
    import tomllib

    folders = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    for package, folder in folders.items():
        if package != "ultraglide":
            link = ROOT / package.replace(".", "/")
            assert link.is_symlink() and link.resolve() == (ROOT / folder).resolve(), package
