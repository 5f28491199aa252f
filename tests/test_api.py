"""The public API: every name in ``ultraglide.__all__`` resolves, lazily, to a documented object of
the package it claims; nothing private is exported; ``import ultraglide`` loads none of the heavy parts;
``export_wav`` writes what the command writes."""

from __future__ import annotations

import inspect
import subprocess
import sys

import numpy as np
import pytest
import soundfile
from conftest import run_cli

import ultraglide


def test_every_public_name_resolves_and_is_documented():
    assert len(ultraglide.__all__) == len(set(ultraglide.__all__))
    for name in ultraglide.__all__:
        value = getattr(ultraglide, name)
        assert not name.startswith("_") or name == "__version__"
        if name == "__version__":
            continue
        assert value.__module__.startswith("ultraglide."), (name, value.__module__)
        assert inspect.getdoc(value), f"ultraglide.{name} has no docstring"
        assert ".apps" not in value.__module__, f"ultraglide.{name} comes from the apps leaf"
    assert set(dir(ultraglide)) >= set(ultraglide.__all__)


def _public_callables():
    for name in ultraglide.__all__:
        value = getattr(ultraglide, name)
        if inspect.isfunction(value):
            yield name, value
        elif inspect.isclass(value) and value.__module__.startswith("ultraglide."):
            for member, function in vars(value).items():
                if inspect.isfunction(function) and not member.startswith("_"):
                    yield f"{name}.{member}", function


def test_public_functions_have_type_hints_and_docstrings():
    missing = []
    for name, function in _public_callables():
        signature = inspect.signature(function)
        unannotated = [p for p, parameter in signature.parameters.items()
                       if p not in ("self", "cls") and parameter.annotation is inspect.Parameter.empty]
        if unannotated or signature.return_annotation is inspect.Signature.empty:
            missing.append(f"{name}: {unannotated or 'return'}")
        if not inspect.getdoc(function):
            missing.append(f"{name}: docstring")
    assert not missing, missing


def test_unknown_names_raise_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'kernels'"):
        ultraglide.kernels  # noqa: B018 - internal modules are not re-exported
    assert not hasattr(ultraglide, "apps_cli")


def test_import_is_lazy():
    code = ("import sys, ultraglide; heavy = [m for m in ('numpy', 'scipy', 'numba', 'matplotlib', "
            "'ultraglide.render.renderer', 'ultraglide.apps.cli.main') if m in sys.modules]; print(heavy); "
            "ultraglide.grating; print('numpy' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:2] == ["[]", "True"]


@pytest.mark.slow
def test_export_wav_matches_the_export_command(tmp_path):
    library = ultraglide.export_wav("grating-2mm", tmp_path / "lib.wav", duration_s=0.5, speed_mm_s=80.0)
    run_cli("export", "grating-2mm", "-o", tmp_path / "cli.wav", "--duration-s", "0.5", "--speed-mm-s", "80",
            check=True)
    ours, rate = soundfile.read(tmp_path / "lib.wav", dtype="float32")
    theirs, _ = soundfile.read(tmp_path / "cli.wav", dtype="float32")
    assert rate == library.rate_hz == 96000
    assert library.duration_s == pytest.approx(len(ours) / rate)
    np.testing.assert_array_equal(ours, theirs)  # one path from renderer to samples
    assert np.max(np.abs(ours)) > 0.2


def test_export_wav_refuses_bad_input_and_leaves_nothing(tmp_path):
    with pytest.raises(ultraglide.RenderError, match="int16, or|float32, int24, int16"):
        ultraglide.export_wav("grating-2mm", tmp_path / "x.wav", format="int8", duration_s=0.1)
    with pytest.raises(ultraglide.RenderError, match=r"\.wav"):
        ultraglide.export_wav("grating-2mm", tmp_path / "x.mp3", duration_s=0.1)
    with pytest.raises(ultraglide.TextureError, match="no texture"):
        ultraglide.export_wav("no-such-texture", tmp_path / "x.wav", duration_s=0.1)
    assert list(tmp_path.iterdir()) == []
