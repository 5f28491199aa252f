"""docs/guide/hardware.md: every ``ultraglide`` command on the page is one the parser takes (the rig it names
loads, its options exist), and the dry run's shell blocks run as written, in a scratch folder, to the end."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys

import numpy as np
import pytest
import soundfile
from conftest import ROOT

GUIDE = ROOT / "docs" / "guide" / "hardware.md"
BLOCK = re.compile(r"```(sh|text)\n(.*?)```", re.DOTALL)


def blocks(kind: str) -> list[str]:
    return [body for found, body in BLOCK.findall(GUIDE.read_text(encoding="utf-8")) if found == kind]


def commands() -> list[list[str]]:
    """Every ``ultraglide ...`` line of the page's code blocks and inline code, as its words."""
    text = GUIDE.read_text(encoding="utf-8")
    lines = [line for _, body in BLOCK.findall(text) for line in body.splitlines()]
    lines += re.findall(r"`(ultraglide [^`]+)`", text)
    found = []
    for line in lines:
        line = re.sub(r"^HOME=\S+ ", "", line.strip()).rstrip("&").strip()
        if line.startswith("ultraglide "):
            found.append(shlex.split(line)[1:])
    return found


def test_the_guide_is_in_the_navigation_and_has_its_commands():
    assert "guide/hardware.md" in (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    words = {" ".join(command[:2]) for command in commands()}
    for wanted in ("rig check", "plate sweep", "plate check", "play grating-1mm", "demo --rig", "plate-sim --profile"):
        assert wanted in words, wanted


@pytest.mark.parametrize("command", commands(), ids=lambda command: " ".join(command)[:60])
def test_every_command_of_the_guide_parses(command, tmp_path):
    """The real parser takes each command as written (its options exist, with their values' types) and the plate
    it names resolves (the rig's files beside it: the example, and a measured profile standing in for one)."""
    from ultraglide.apps.cli.parser import build_parser
    from ultraglide.apps.commands.plate_choice import choose_plate

    (tmp_path / "examples").mkdir()
    shutil.copy(ROOT / "examples" / "rig.toml", tmp_path / "examples" / "rig.toml")
    shutil.copy(ROOT / "examples" / "rig.toml", tmp_path / "rig.toml")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        args = build_parser(command).parse_args(command)
        choose_plate(args)
    finally:
        os.chdir(cwd)
    assert callable(args.run)


@pytest.mark.slow
def test_the_dry_run_runs_as_written(tmp_path):
    """The page's shell blocks, in order, in a scratch folder holding examples/rig.toml: each ends well, and what
    they leave is what the page says (a WAV and PortAudio's capture at the rig's carrier, never above the limit
    over full scale, 5 / 10; the capture as long as the run; a measured profile)."""
    (tmp_path / "examples").mkdir()
    shutil.copy(ROOT / "examples" / "rig.toml", tmp_path / "examples" / "rig.toml")
    env = {**os.environ, "PATH": f"{os.path.dirname(sys.executable)}:{os.environ['PATH']}"}
    for body in blocks("sh"):
        result = subprocess.run(["bash", "-euc", body], cwd=tmp_path, env=env, capture_output=True, text=True,
                                timeout=600)
        assert result.returncode == 0, body + result.stdout[-2000:] + result.stderr[-2000:]
    assert "limit: 5 µm p-p" in subprocess.run(
        ["bash", "-c", blocks("sh")[0].splitlines()[0]], cwd=tmp_path, env=env, capture_output=True, text=True,
        timeout=120).stdout
    samples, rate = soundfile.read(tmp_path / "dry-run.wav")
    played = np.fromfile(tmp_path / "played.raw", "<f4")  # the file PCM writes where the command ran
    # the two seconds played, ramps included (2.016-2.020 s in three runs at load 5), in a capture held to real
    # time: the silence before and after is the stream's opening and closing, which a loaded machine stretches
    # (2.15 s in all at load 5; 2.50 s beside two CPU hogs)
    sounding = np.flatnonzero(np.abs(played) > 0.01)
    assert 1.98 <= (sounding[-1] - sounding[0]) / 192000 <= 2.06
    assert 2.0 <= len(played) / 192000 <= 3.5
    for signal, rate_hz in ((samples, rate), (played, 192000)):
        assert 0.2 < np.max(np.abs(signal)) <= 0.5 + 1e-6
        start = int(np.flatnonzero(np.abs(signal) > 0.1)[0])
        window = signal[start:start + rate_hz // 4]
        peak_hz = np.argmax(np.abs(np.fft.rfft(window * np.hanning(len(window))))) * rate_hz / len(window)
        assert peak_hz == pytest.approx(26400, abs=8)
    assert "resonance_hz = 264" in (tmp_path / "measured.toml").read_text()
