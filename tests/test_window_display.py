"""A window opens on the display the environment names, or the command says that display did not answer: SDL left
to itself falls back to its invisible offscreen driver, where a window waits for a person who cannot see it."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from xvfb import start_xvfb
from xvfb_demo import tools_missing


def silent_display() -> str:
    """An X display number nothing serves (no socket, no lock)."""
    for number in range(4000, 4100):
        if not (Path(f"/tmp/.X11-unix/X{number}").exists() or Path(f"/tmp/.X{number}-lock").exists()):
            return f":{number}"
    raise RuntimeError("no free X display number in 4000-4099")


COMMANDS = {
    "demo": ["demo", "--windowed"],
    "texture show": ["texture", "show", "grating-1mm", "--window"],
    "experiment": ["experiment", "threshold", "grating-1mm", "--trials", "2", "--out", "{tmp}/session"],
    "on-plate calibration": ["calibrate", "--device", "sim", "--participant", "P1", "-o", "{tmp}/p1.toml",
                             "--windowed"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_display_that_does_not_answer_is_one_line_and_nothing_written(command, tmp_path):
    display = silent_display()
    args = [arg.format(tmp=tmp_path) for arg in COMMANDS[command]]
    result = run_cli(*args, env={"DISPLAY": display, "WAYLAND_DISPLAY": "", "SDL_VIDEODRIVER": ""}, timeout=120)
    line = assert_one_line_error(result)
    assert f"cannot open a window (the display {display} did not answer" in line, line
    assert "check DISPLAY" in line
    assert not list(tmp_path.iterdir())  # no session folder, no calibration


@pytest.mark.skipif(bool(tools_missing()), reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
def test_on_a_live_x_server_the_window_is_x11s_and_the_driver_choice_is_not_inherited(tmp_path):
    """The driver is chosen for the display's start only: a process started after (the engine's) inherits no
    SDL_VIDEODRIVER."""
    xvfb, display = start_xvfb(640, 480)
    try:
        script = ("import os, pygame; from ultraglide.apps.window.screen import init_display; init_display(pygame); "
                  "pygame.display.set_mode((64, 64)); print(pygame.display.get_driver(), "
                  "os.environ.get('SDL_VIDEODRIVER', '-'))")
        env = {key: value for key, value in os.environ.items() if key not in ("SDL_VIDEODRIVER", "WAYLAND_DISPLAY")}
        result = subprocess.run([sys.executable, "-c", script], env={**env, "DISPLAY": display}, cwd=ROOT,
                                capture_output=True, text=True, timeout=120)
        assert result.returncode == 0, result.stderr
        assert result.stdout.splitlines()[-1].split() == ["x11", "-"]  # after pygame's greeting
    finally:
        xvfb.terminate()
        xvfb.wait(timeout=30)
