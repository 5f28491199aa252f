"""A command stopped (SIGTERM, Ctrl-C) while its engine is still loading (issue 26's hostile trial, by class: a
stop signal mid-run of every command that writes): one line, the shell's status, no traceback, nothing left behind.

The engine process loads the texture, the model and the device before it answers; the simulated plate takes a
second or more there (its compiled filter). A signal in that second used to leave the engine's "up" with nobody to
read it (a BrokenPipeError traceback from the engine process), its shared-memory segment for the resource tracker
to call leaked, and a growing log's ``.part``. The signal is sent as soon as the engine process exists; whether it
lands while the engine loads or once it runs, the same must hold.
"""

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import start_cli, wait_for
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture


def engine_of(pid: int) -> int | None:
    """The engine process a command started, or None yet: forked (its command line is the command's own) or
    spawned (multiprocessing's spawn_main)."""
    try:
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
        own = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return None
    for child in children:
        try:
            line = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if line == own or b"spawn_main" in line:
            return int(child)
    return None


def segments(pid: int) -> list[str]:
    """The engine's shared-memory segments that process ``pid`` made (named after it) and left."""
    return [name for name in os.listdir("/dev/shm") if name.startswith(f"ultraglide_{pid}_")]


COMMANDS = {
    "play on sim with logs": ["play", "wood", "--duration-s", "60", "--device", "sim", "--closed-loop",
                              "--finger-log", "{d}/f.csv", "--sensors-csv", "{d}/s.csv"],
    "play to a WAV": ["play", "wood", "--duration-s", "60", "--device", "wav:{d}/p.wav"],
    "latency on sim": ["latency", "--steps", "2000"],
}


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_command_stopped_while_its_engine_loads_says_so_in_one_line_and_leaves_nothing(tmp_path, command, signum):
    argv = [arg.format(d=tmp_path) for arg in COMMANDS[command]]
    process = start_cli(*argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert wait_for(lambda: engine_of(process.pid) is not None or process.poll() is not None, 120)
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 128 + signum, err
    assert err.strip() == f"ultraglide: stopped ({signal.Signals(signum).name})", err  # no traceback, no warning
    assert not [path.name for path in tmp_path.iterdir() if path.name.endswith(".part") or ".ultraglide-" in path.name]
    assert segments(process.pid) == []


SIGNAL_WHILE_THE_SEGMENT_IS_MADE = r'''
import os, signal, sys
from multiprocessing import shared_memory
from ultraglide.render.engine import Engine, EngineConfig

def interrupt_inside_the_making(frame, event, arg):
    # a real Ctrl-C, sent at the one moment it used to cost a leak: the segment named to the resource tracker,
    # not yet made
    if event == "call" and frame.f_code is shared_memory.SharedMemory.__init__.__code__:
        sys.setprofile(None)
        os.kill(os.getpid(), signal.SIGINT)

signal.signal(signal.SIGINT, signal.default_int_handler)  # as at a terminal (a test worker's children ignore it)
sys.setprofile(interrupt_inside_the_making)
try:
    Engine.start(EngineConfig(texture=sys.argv[1], device="null"))
except KeyboardInterrupt:
    print("stopped", os.getpid())
'''


def test_ctrl_c_while_the_engines_shared_memory_is_made_leaves_no_segment_and_no_warning(tmp_path):
    """Ctrl-C in the instant the engine's segment is named to the resource tracker but not yet made: the start
    still ends as a stop, and neither the segment nor the tracker's record of it outlives the process (else the
    tracker warns of a leak on its way out, on the command's terminal)."""
    texture = save_texture(Texture(np.ones((2, 2), np.float32), 10.0, 10.0), tmp_path / "t.png")
    result = subprocess.run([sys.executable, "-c", SIGNAL_WHILE_THE_SEGMENT_IS_MADE, str(texture)],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0 and result.stdout.startswith("stopped "), result.stdout + result.stderr
    assert result.stderr == ""  # the resource tracker's "leaked shared_memory objects", had it kept a record
    assert segments(int(result.stdout.split()[1])) == []
