"""The README's tour, run as written: each of its parts, top to bottom, in a fresh copy of the repository, with
the virtual environment's ``bin/`` on the PATH, as the README says. Where a command needs a screen it gets
Xvfb's, as the README says; where it needs a person, the test is that person: it drags on the demo and
quits it with Esc, rewrites a watched file, answers an experiment's trials with keys, stops a plate-sim
with Ctrl-C or ``kill %1``. Every wait is on what the command says or writes, never on the clock.

A command that runs to its end is ``python -m ultraglide`` forked from the test's command server
(tests/cli_server.py: the same interpreter and package as the ``ultraglide`` on that PATH, its libraries
imported once: 30 commands, ~1.2 s of CPU each otherwise); one that runs beside the test (a background job,
the demo, an experiment with its participant, a plate-sim stopped with Ctrl-C) is a real process in a session
of its own, its engine and other children with it. The installed ``ultraglide`` script itself is run by
tests/test_packaging.py, from a wheel in a clean environment."""

from __future__ import annotations

import io
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_cli, source_copy
from xvfb import start_xvfb
from xvfb_demo import tools_missing

DEADLINE_S = 600.0  # for any one command, on a loaded machine


def tour_parts() -> dict[str, list[str]]:
    """The tour's parts (their ``#`` headings) and each part's command lines, from the README."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    start = readme.index("```sh\n", readme.index("## A tour of the commands")) + len("```sh\n")
    block = readme[start:readme.index("```", start)]
    parts: dict[str, list[str]] = {}
    heading = None
    for line in block.splitlines():
        if line.startswith("# "):
            heading = line[2:].split(":")[0].split("(")[0].strip()
            parts[heading] = []
        elif line.strip():
            assert heading is not None, f"a command before the tour's first heading: {line}"
            parts[heading].append(line)
    return parts


class Command:
    """A command started in the background, its output lines gathered as they come."""

    def __init__(self, words: list[str], cwd: Path, env: dict):
        self.words = words
        self.process = subprocess.Popen(words, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True, start_new_session=True)
        self.out: list[str] = []
        self.err: list[str] = []
        self._readers = [threading.Thread(target=self._read, args=(stream, lines), daemon=True)
                         for stream, lines in ((self.process.stdout, self.out), (self.process.stderr, self.err))]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(stream, lines: list[str]) -> None:
        for line in stream:
            lines.append(line.rstrip("\n"))

    def wait_line(self, pattern: str, timeout_s: float = DEADLINE_S) -> str:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            found = next((line for line in self.out if re.search(pattern, line)), None)
            if found is not None:
                return found
            assert self.process.poll() is None, f"{self.words} ended ({self.process.returncode}): {self.said()}"
            time.sleep(0.05)
        raise AssertionError(f"{self.words} never printed {pattern!r}: {self.said()}")

    def said(self) -> str:
        return "\n".join(self.out[-20:] + self.err[-20:])

    def finish(self, timeout_s: float = DEADLINE_S) -> int:
        code = self.process.wait(timeout=timeout_s)
        for reader in self._readers:
            reader.join(timeout=10)
        return code

    def kill(self) -> None:
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait(timeout=30)


class Tour:
    """Runs a part's lines as a person at a terminal would (and as the README says)."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
        self.env.pop("SDL_VIDEODRIVER", None)
        self.jobs: list[Command] = []
        self.xvfb: subprocess.Popen | None = None

    def close(self) -> None:
        for job in self.jobs:
            job.kill()
        if self.xvfb is not None:
            self.xvfb.terminate()
            self.xvfb.wait(timeout=30)

    def screen(self) -> None:
        """``Xvfb :N -screen 0 1280x800x24 -noreset & export DISPLAY=:N``, on a free display."""
        if self.xvfb is not None:
            return
        self.xvfb, self.env["DISPLAY"] = start_xvfb(1280, 800)

    def xdo(self, *args) -> None:
        subprocess.run(["xdotool", *map(str, args)], env=self.env, check=True, timeout=120)

    def key_press(self, key: str) -> bool:
        """A participant's key press, which may not land: False when xdotool could not connect to the screen
        (seen beside two CPU hogs before the tests' Xvfb ran with -noreset: it was starting over as its last
        client left); the participant presses again, as for a key the window dropped. Any other failure of
        xdotool fails the test."""
        pressed = subprocess.run(["xdotool", "key", key], env=self.env, capture_output=True, text=True, timeout=120)
        if pressed.returncode != 0 and "Can't open display" not in pressed.stderr:
            raise AssertionError(f"xdotool key {key}: {pressed.stderr.strip()}")
        return pressed.returncode == 0

    def stuck(self, session: Command, rows: int, missed: int) -> str:
        """What a session that never ended was doing: its output, its trial log's length, the keys lost, the X focus
        and every thread's stack (once in CI a yes/no session ran 600 s with no word: none of these was known)."""
        from service_run import where_it_waits

        focus = subprocess.run(["xdotool", "getwindowfocus", "getwindowname"], env=self.env, capture_output=True,
                               text=True, timeout=60)
        windows = subprocess.run(["xwininfo", "-root", "-children"], env=self.env, capture_output=True, text=True,
                                 timeout=60)
        return (f"{session.said()}\n{rows} lines in trials.csv; {missed} key presses could not reach the screen; "
                f"focus: {(focus.stdout + focus.stderr).strip()}; {self.trial_words()}\nthe screen's windows: "
                f"{(windows.stdout + windows.stderr).strip()[-600:]}\n{where_it_waits(session.process.pid)}")

    def trial_words(self) -> str:
        """Whether a trial's zones are on the screen, as a person would see it."""
        from PIL import Image
        from ultraglide.apps.experiment.window import ZONE

        shot = subprocess.run(["import", "-window", "root", "png:-"], env=self.env, capture_output=True, timeout=60)
        if shot.returncode != 0:
            return f"no screenshot ({shot.stderr.decode(errors='replace').strip()[-200:]})"
        pixels = np.asarray(Image.open(io.BytesIO(shot.stdout)).convert("RGB"))
        zone = int(np.all(pixels == ZONE, axis=-1).sum())
        return f"the screen shows {zone} pixels of a trial's zones" if zone else "no trial's zones on the screen"

    def run(self, line: str) -> None:
        words = shlex.split(line, comments=True)
        if words == ["kill", "%1"]:
            job = self.jobs.pop()
            job.process.send_signal(signal.SIGTERM)
            assert job.finish() == 128 + signal.SIGTERM, job.said()
            return
        assert words[0] == "ultraglide", line
        if words[-1] == "&":
            job = Command(words[:-1], self.folder, self.env)
            self.jobs.append(job)
            job.wait_line(r"\S")  # it has started: its first line (plate-sim: where it serves)
            if "--link" in words:
                link = self.folder / words[words.index("--link") + 1]
                assert link.exists(), job.said()
            return
        if words[1] == "demo":
            self.demo(words)
        elif words[1] == "plate-sim":  # runs until Ctrl-C
            command = Command(words, self.folder, self.env)
            try:
                command.wait_line(r"\S")
                command.process.send_signal(signal.SIGINT)
                assert command.finish() == 128 + signal.SIGINT, command.said()
            finally:
                command.kill()
        elif words[1] == "experiment" and "--observer" not in words:
            self.participant(words)
        else:
            result = run_cli(*words[1:], env=self.env, inherit_env=False, cwd=self.folder, timeout=DEADLINE_S)
            assert result.returncode == 0, f"{line}\n{result.stdout[-2000:]}\n{result.stderr[-2000:]}"
            assert "Traceback" not in result.stderr, result.stderr

    def demo(self, words: list[str]) -> None:
        """The demo on the screen: wait for its first frame; drag until the recording has touches, or rewrite
        a watched texture until the demo says it reloaded it; then Esc."""
        self.screen()
        demo = Command(words, self.folder, self.env)
        try:
            demo.wait_line("first frame drawn")
            if "--record" in words:
                part = self.folder / (words[words.index("--record") + 1] + ".part")
                deadline = time.monotonic() + DEADLINE_S
                while not (part.exists() and part.read_text().count("\n") > 10):  # felt once the engine runs
                    assert time.monotonic() < deadline and demo.process.poll() is None, demo.said()
                    drag = ["mousemove", 100, 300, "mousedown", 1]
                    for x in range(110, 700, 10):
                        drag += ["sleep", "0.008", "mousemove", x, 300]
                    self.xdo(*drag, "mouseup", 1)
            if "--watch" in words:
                watched = words[2]
                subprocess.run(["ultraglide", "texture", "new", "edge", "--size-mm", "200x150", "--range", "0.2",
                                "1.0", "-o", watched], cwd=self.folder, env=self.env, check=True, timeout=DEADLINE_S)
                demo.wait_line(f"reloaded {re.escape(watched)}")
            self.xdo("key", "Escape")
            assert demo.finish() == 0, demo.said()
            assert "Traceback" not in "\n".join(demo.err), demo.said()
        finally:
            demo.kill()

    def participant(self, words: list[str]) -> None:
        """A participant at the plate: answers each trial with a key (1 in forced choice, Y in yes/no) once it is
        shown, until the session ends. A key sent before a trial is on screen is dropped by the window, so each
        is sent again until the trial log has one more row."""
        self.screen()
        key = "1" if "--afc" in words else "y"
        trials = self.folder / words[words.index("--out") + 1] / "trials.csv"
        session = Command(words, self.folder, self.env)
        missed = 0  # key presses xdotool could not make
        try:
            deadline = time.monotonic() + DEADLINE_S
            while session.process.poll() is None:
                rows = trials.read_text().count("\n") if trials.exists() else 0
                assert time.monotonic() < deadline, self.stuck(session, rows, missed)
                missed += not self.key_press(key)
                step = time.monotonic() + 0.06  # then again: the window may not have shown the trial yet (a key
                # too many is dropped when the next trial clears the window's events, or answers it: all the same)
                while time.monotonic() < step and session.process.poll() is None:
                    if trials.exists() and trials.read_text().count("\n") > rows:
                        break
                    time.sleep(0.02)
            assert session.finish() == 0, f"{session.said()}\n({missed} key presses could not reach the screen)"
            assert (trials.parent / "result.json").exists(), session.said()
        finally:
            session.kill()


PARTS = tour_parts()


def test_the_tour_has_its_parts():
    assert list(PARTS) == ["the physics, a model, a calibration", "textures", "rendering", "a plate driver",
                           "the demo", "threshold experiments"]
    assert sum(len(lines) for lines in PARTS.values()) >= 35


@pytest.mark.slow
@pytest.mark.skipif(bool(tools_missing()), reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
@pytest.mark.parametrize("part", list(PARTS))
def test_the_readme_tour_runs_as_written(part, tmp_path):
    if part == "a plate driver" and not all(map(shutil.which, ("arm-none-eabi-gcc", "qemu-system-arm"))):
        pytest.skip("the firmware's part needs gcc-arm-none-eabi and qemu-system-arm (./run tests installs them)")
    tour = Tour(source_copy(tmp_path / "ultraglide"))
    try:
        for line in PARTS[part]:
            tour.run(line)
    finally:
        tour.close()
