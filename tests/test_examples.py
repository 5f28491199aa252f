"""Every script in examples/ runs as a user would run it (a subprocess in an empty directory), and
what it writes is read back: WAVs by soundfile and checked for a carrier, CSVs and TOMLs parsed."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import numpy as np
import pytest
import soundfile
from conftest import ROOT
from ultraglide.textures.fileformat import load_texture

EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def run_example(name: str, cwd) -> subprocess.CompletedProcess:
    result = subprocess.run([sys.executable, str(ROOT / "examples" / name)], capture_output=True, text=True,
                            cwd=cwd, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    return result


def carrier_peak_hz(samples: np.ndarray, rate: int) -> float:
    spectrum = np.abs(np.fft.rfft(samples * np.hanning(len(samples))))
    return float(np.fft.rfftfreq(len(samples), 1 / rate)[np.argmax(spectrum)])


def test_every_example_is_short_and_tested():
    assert {path.name for path in EXAMPLES} == set(CHECKS)
    for path in EXAMPLES:
        code = [line for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
        assert len(code) <= 40, f"{path.name} has {len(code)} lines; an example stays short"


def check_export_texture(tmp_path, stdout):
    samples, rate = soundfile.read(tmp_path / "grating.wav")
    assert rate == 96000 and len(samples) / rate == pytest.approx(2.0, abs=0.05)
    assert carrier_peak_hz(samples, rate) == pytest.approx(25000, abs=2)  # the sim plate's resonance
    assert "wrote grating.wav" in stdout


def check_my_texture(tmp_path, stdout):
    texture = load_texture(tmp_path / "rings.png")
    assert (texture.width_mm, texture.height_mm) == (60.0, 40.0)
    assert texture.values.min() == pytest.approx(0.3, abs=1e-3) and texture.values.max() == pytest.approx(1.0, abs=1e-3)
    samples, rate = soundfile.read(tmp_path / "rings.wav")
    assert np.max(np.abs(samples)) > 0.1 and len(samples) / rate == pytest.approx(0.4, abs=0.05)


def check_calibrate_and_render(tmp_path, stdout):
    with open(tmp_path / "finger.toml", "rb") as stream:
        document = tomllib.load(stream)
    # the stand-in data follow exp(-a^2 / 2 tau^2) with tau = 1.2 µm zero-to-peak
    assert document["model"] == "exponential"
    assert document["parameters"]["tau_um_zp"] == pytest.approx(1.2, rel=0.05)
    half = float(stdout.split("half the friction needs ")[1].split()[0])
    assert half == pytest.approx(2 * 1.2 * np.sqrt(2 * np.log(2)), rel=0.05)  # µm p-p
    samples, rate = soundfile.read(tmp_path / "calibrated.wav")
    assert carrier_peak_hz(samples, rate) == pytest.approx(25000, abs=2)


def check_touch_source(tmp_path, stdout):
    samples, rate = soundfile.read(tmp_path / "touch.wav")
    assert len(samples) / rate >= 0.9  # a second of reports, recorded in real time
    assert np.max(np.abs(samples)) > 0.1
    assert carrier_peak_hz(samples, rate) == pytest.approx(25000, abs=5)


def check_custom_device(tmp_path, stdout):
    drive = np.loadtxt(tmp_path / "envelope.csv", skiprows=1)
    assert len(drive) / 12000 >= 0.5  # the whole swipe, then the ramp to rest
    assert drive.max() > 1.0 and drive[-1] < 1e-3
    assert "'samples'" in stdout


CHECKS = {"export_texture.py": check_export_texture, "my_texture.py": check_my_texture,
          "calibrate_and_render.py": check_calibrate_and_render, "touch_source.py": check_touch_source,
          "custom_device.py": check_custom_device}


@pytest.mark.slow
@pytest.mark.parametrize("example", [path.name for path in EXAMPLES])
def test_example_runs_and_writes_what_it_says(example, tmp_path):
    result = run_example(example, tmp_path)
    CHECKS[example](tmp_path, result.stdout)
