"""Shared test helpers."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# Property tests check behaviour, never speed: no per-example deadline, which a loaded machine would miss.
settings.register_profile("ultraglide", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ultraglide")

ROOT = Path(__file__).resolve().parent.parent


def run_cli(*args, check=False, env=None, timeout=300, **kwargs):
    """Run the installed ``ultraglide`` command as a user would, in a subprocess."""
    merged = {**os.environ, **(env or {})}
    result = subprocess.run([sys.executable, "-m", "ultraglide", *map(str, args)], capture_output=True,
                            text=True, env=merged, timeout=timeout, cwd=kwargs.get("cwd", ROOT))
    if check and result.returncode != 0:
        raise AssertionError(f"ultraglide {' '.join(map(str, args))} failed:\n{result.stderr}")
    return result


def assert_one_line_error(result):
    """A user error: non-zero exit, one line on stderr, no traceback."""
    assert result.returncode != 0, result.stdout
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    return lines[0]


@pytest.fixture
def cli():
    return run_cli
