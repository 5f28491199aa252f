"""The distribution installs one namespace, ``ultraglide``, and nothing of ours under a bare name."""

from __future__ import annotations

import subprocess
import sys

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
