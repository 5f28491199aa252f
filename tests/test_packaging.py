"""The distribution installs one namespace, ``ultraglide``, and nothing of ours under a bare name."""

from __future__ import annotations

import subprocess
import sys

import pytest

import ultraglide


def _run(code: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd, timeout=120)


def test_subpackages_import_under_the_namespace(tmp_path) -> None:
    result = _run("import ultraglide.render.renderer, ultraglide.textures.texture, ultraglide.devices.protocol, "
                  "ultraglide.apps.cli.main; print('ok')", tmp_path)
    assert result.stdout.strip() == "ok", result.stderr


def test_no_bare_top_level_packages(tmp_path) -> None:
    for bare in ("render", "textures", "devices", "apps"):
        result = _run(f"import importlib.util, sys; sys.exit(importlib.util.find_spec({bare!r}) is not None)", tmp_path)
        assert result.returncode == 0, f"a bare '{bare}' is importable from outside the repository"


def test_python_dash_m_matches_the_command(tmp_path) -> None:
    result = subprocess.run([sys.executable, "-m", "ultraglide", "--version"], capture_output=True, text=True,
                            cwd=tmp_path, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"ultraglide {ultraglide.__version__}"


def test_a_reader_that_leaves_stops_the_command_quietly(tmp_path):
    """``ultraglide textures | head -1``: the pipe closes before the listing is written; no error, 128 + SIGPIPE."""
    import signal

    command = subprocess.Popen([sys.executable, "-m", "ultraglide", "textures"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, cwd=tmp_path)
    command.stdout.close()  # the only reader leaves before the command has even started writing
    _, stderr = command.communicate(timeout=120)
    assert command.returncode == 128 + signal.SIGPIPE
    assert stderr == b""


@pytest.mark.slow
def test_a_wheel_builds_without_warnings_and_runs_from_a_clean_venv(tmp_path):
    """What `pipx install .` does: build a wheel (in an isolated build environment), install it with its
    dependencies into a fresh virtual environment, and run the command from there, away from the sources."""
    import os

    import soundfile
    from conftest import source_copy

    source = source_copy(tmp_path / "source")
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", tmp_path / "wheels", source],
                           capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stderr
    noise = [line for line in (build.stdout + build.stderr).splitlines()
             if "would be ignored" in line or "SetuptoolsDeprecationWarning" in line]
    assert not noise, noise  # every data folder is listed in pyproject.toml
    wheel = next((tmp_path / "wheels").glob("ultraglide-*.whl"))
    # every module of ours is in it: the packages are listed by hand in pyproject.toml, and one left out
    # (apps.calibration once) is missing from an install while the editable one, which maps folders, has it
    import tomllib
    import zipfile

    folders = tomllib.loads((source / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    ours = {f"{package.replace('.', '/')}/{path.relative_to(source / folder).as_posix()}"
            for package, folder in folders.items() for path in (source / folder).rglob("*.py")}
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    shipped = {name for name in names if name.endswith(".py")}
    assert sorted(ours - shipped) == []
    # and every file a board's firmware build reads (`ultraglide firmware build` runs make on the installed
    # sources: a Makefile's include, a linker script or a header left out breaks it only there)
    firmware = source / "devices" / "firmware"
    sources = {f"ultraglide/devices/firmware/{path.relative_to(firmware).as_posix()}"
               for folder in ("core", "include", "ports") for path in (firmware / folder).rglob("*")
               if path.is_file() and path.suffix != ".py"}
    assert sources and sorted(sources - names) == []
    # a venv without pip of its own, filled by this pip (`pip --python`), as pipx does with its shared pip:
    # seeding pip into the venv and running it there from uncompiled sources was ~7 s CPU of ~27; the venv
    # still holds nothing but the wheel and what it depends on
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", tmp_path / "clean"], check=True, timeout=300)
    # --no-compile: byte-compiling numpy, scipy and matplotlib at install is most of an install's time, and
    # Python compiles what the command imports when it runs; what is tested (the wheel, its dependencies,
    # the command from a clean environment) is the same
    installed = subprocess.run([sys.executable, "-m", "pip", "--python", tmp_path / "clean" / "bin" / "python",
                                "install", "-q", "--no-compile", "--disable-pip-version-check", wheel],
                               capture_output=True, text=True, timeout=900)
    assert installed.returncode == 0, installed.stderr
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "VIRTUAL_ENV")}
    command = tmp_path / "clean" / "bin" / "ultraglide"
    assert not (tmp_path / "clean" / "bin" / "pip").exists()  # the venv has no installer of its own
    version = subprocess.run([command, "--version"], capture_output=True, text=True, cwd=tmp_path, env=env,
                             timeout=120)
    assert version.stdout.strip() == f"ultraglide {ultraglide.__version__}", version.stderr
    exported = subprocess.run([command, "export", "grating-1mm", "-o", "swipe.wav", "--duration-s", "0.3"],
                              capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
    assert exported.returncode == 0, exported.stderr
    samples, rate = soundfile.read(tmp_path / "swipe.wav")
    assert rate == 96000 and 0.3 <= len(samples) / rate < 0.5 and 0.2 < abs(samples).max() <= 1.0
    # the core installs without the demo's and the figures' dependencies, and renders to an array there
    python = tmp_path / "clean" / "bin" / "python"
    core = subprocess.run([python, "-c", "import importlib.util, ultraglide; "
                           "print([m for m in ('pygame', 'matplotlib') if importlib.util.find_spec(m)]); "
                           "swipe = ultraglide.render_swipe('grating-1mm', duration_s=0.2); "
                           "print(swipe.rate_hz, len(swipe.audio), round(float(abs(swipe.audio).max()), 1))"],
                          capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
    assert core.returncode == 0, core.stderr
    absent, rendered = core.stdout.splitlines()
    assert absent == "[]"
    rate, frames, peak = rendered.split()
    assert rate == "96000" and abs(int(frames) - (len(samples) - 9600)) <= 1 and 0.2 < float(peak) <= 1.0
    # a command whose extra is missing names it, in one line, exit 2, and writes nothing
    for words, extra in ((["texture", "show", "grating-1mm", "-o", "show.pdf"], "figures"),
                         (["export", "grating-1mm", "-o", "plotted.wav", "--duration-s", "0.1", "--plot", "p.png"],
                          "figures"),
                         (["demo", "--windowed"], "demo")):
        refused = subprocess.run([command, *words], capture_output=True, text=True, cwd=tmp_path, env=env,
                                 timeout=600)
        assert refused.returncode == 2, (words, refused.stderr)
        assert refused.stderr.count("\n") == 1, refused.stderr
        assert f"pip install 'ultraglide[{extra}]'" in refused.stderr, refused.stderr
    assert sorted(path.name for path in tmp_path.iterdir() if path.suffix in (".pdf", ".png", ".wav")) == ["swipe.wav"]


def test_the_wheel_declares_the_extras(tmp_path):
    """The wheel's metadata, read back with the standard library's email parser: the core requires neither
    pygame nor matplotlib; the demo, figures and all extras add them; test holds all."""
    import email
    import zipfile

    from conftest import source_copy

    source = source_copy(tmp_path / "source")
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-w",
                            tmp_path / "wheels", source], capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stderr
    wheel = next((tmp_path / "wheels").glob("ultraglide-*.whl"))
    with zipfile.ZipFile(wheel) as archive:
        name = next(name for name in archive.namelist() if name.endswith(".dist-info/METADATA"))
        metadata = email.message_from_bytes(archive.read(name))
    assert set(metadata.get_all("Provides-Extra")) >= {"demo", "figures", "all", "test", "docs"}
    requires = metadata.get_all("Requires-Dist")
    core = {requirement.split(";")[0].split(">")[0].split("=")[0].strip() for requirement in requires
            if "extra ==" not in requirement}
    assert {"numpy", "scipy", "numba", "soundfile"} <= core
    assert not core & {"pygame-ce", "matplotlib"}, core

    def extra(name: str) -> set[str]:
        return {requirement.split(";")[0].split(">")[0].strip() for requirement in requires
                if f'extra == "{name}"' in requirement}

    assert "pygame-ce" in extra("demo") and "matplotlib" in extra("figures")
    assert {"ultraglide[demo,figures]"} == extra("all") and "ultraglide[all]" in extra("test")


def test_every_import_of_ours_resolves_in_the_folder_tree():
    """What an editor or an analyser does, without running code: each ``ultraglide...`` module that any of our
    modules imports is a file (or a package folder) under ultraglide/, whose links bring the mapped folders in; the
    import hook of the editable install plays no part."""
    import ast

    from conftest import ROOT

    def resolves(module: str) -> bool:
        path = ROOT.joinpath(*module.split("."))
        return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()

    unresolved = []
    files = [path for folder in ("ultraglide", "render", "textures", "devices", "apps")
             for path in (ROOT / folder).rglob("*.py")]
    assert len(files) > 150
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([alias.name for alias in node.names] if isinstance(node, ast.Import)
                     else [node.module] if isinstance(node, ast.ImportFrom) and node.module and not node.level else [])
            for name in names:
                if name.startswith("ultraglide.") and not resolves(name):
                    unresolved.append(f"{path.relative_to(ROOT)}:{node.lineno}: {name}")
    assert not unresolved, unresolved
