"""Run the demo under Xvfb as a user would (a real X server, real pointer events from xdotool),
wait on what the demo says it has drawn, and read its CPU time from /proc. Shared by the tests and
``bench/bench_demo_cpu.py``."""

from __future__ import annotations

import os
import queue
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

from xvfb import start_xvfb

ROOT = Path(__file__).resolve().parent.parent
TOOLS = ("Xvfb", "xdotool", "import")


def tools_missing() -> list[str]:
    return [tool for tool in TOOLS if not shutil.which(tool)]


def process_cpu_s(pid: int, thread: int | None = None) -> float:
    """User plus system CPU time of a process (or one of its threads), s."""
    path = f"/proc/{pid}/stat" if thread is None else f"/proc/{pid}/task/{thread}/stat"
    fields = Path(path).read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def descendants(pid: int) -> list[int]:
    """A process's children, their children and so on (Linux's /proc/PID/task/*/children)."""
    found, todo = [], [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = [int(c) for c in (task / "children").read_text().split()]
            except OSError:
                continue
            found += children
            todo += children
    return found


def tree_cpu_s(pid: int) -> float:
    """CPU time of a process and all its descendants still running, s (the demo, its engine, their helpers)."""
    total = 0.0
    for member in [pid, *descendants(pid)]:
        try:
            total += process_cpu_s(member)
        except (OSError, IndexError):
            continue  # ended between listing and reading
    return total


class XvfbDemo:
    """Xvfb on a free display and ``ultraglide demo --windowed --report-frames ARGS`` on it."""

    def __init__(self, *args: str, size=(1280, 800), cwd: Path = ROOT):
        self.xvfb, display = start_xvfb(*size)
        self.env = {**os.environ, "DISPLAY": display}
        self.env.pop("SDL_VIDEODRIVER", None)
        self.lines: queue.Queue[str] = queue.Queue()
        self.stdout: list[str] = []
        self.launched_s = time.perf_counter()
        self.demo = subprocess.Popen([sys.executable, "-m", "ultraglide", "demo", "--windowed", "--report-frames",
                                      *args], env=self.env, cwd=cwd, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.demo.stdout:
            self.stdout.append(line)
            self.lines.put(line.rstrip("\n"))

    def wait_for(self, pattern: str, timeout_s: float = 30.0) -> tuple[str, float]:
        """The next line of the demo's output matching ``pattern`` and when it came (perf_counter s)."""
        deadline = time.perf_counter() + timeout_s
        while True:
            left = deadline - time.perf_counter()
            if left <= 0 or self.demo.poll() is not None and self.lines.empty():
                raise AssertionError(f"the demo never printed {pattern!r}; it printed {''.join(self.stdout)!r}, "
                                     f"stderr: {self.demo.stderr.read() if self.demo.poll() is not None else ''}")
            try:
                line = self.lines.get(timeout=min(left, 0.5))
            except queue.Empty:
                continue
            if re.search(pattern, line):
                return line, time.perf_counter()

    def xdo(self, *args) -> None:
        subprocess.run(["xdotool", *map(str, args)], env=self.env, check=True, timeout=60)

    def drag(self, points, rate_hz: float = 120.0) -> None:
        """Press at the first point, move through the rest at ``rate_hz`` in one xdotool process, release."""
        command = ["mousemove", *points[0], "mousedown", "1"]
        for x, y in points[1:]:
            command += ["sleep", f"{1 / rate_hz:.5f}", "mousemove", x, y]
        command += ["mouseup", "1"]
        self.xdo(*command)

    def drag_recorded(self, points, recording: Path, timeout_s: float = 60.0) -> None:
        """Press at the first point and move through the rest, each move once the demo has recorded the one
        before it (a row in ``recording``, the ``--record`` file being written), then release. Paced by what
        the demo took in, not by a clock: a loaded machine slows the drag down, never bunches its moves."""
        def rows() -> int:
            if not recording.exists():
                return 0
            return sum(1 for line in recording.read_text().splitlines() if line[:1].isdigit())

        self.xdo("mousemove", *points[0], "mousedown", "1")
        for k, (x, y) in enumerate(points[1:], 2):
            self._await(lambda k=k: rows() >= k - 1, timeout_s)  # the previous point is in the recording
            self.xdo("mousemove", x, y)
        self._await(lambda: rows() >= len(points), timeout_s)
        self.xdo("mouseup", "1")

    def _await(self, condition, timeout_s: float) -> None:
        deadline = time.perf_counter() + timeout_s
        while not condition():
            if time.perf_counter() > deadline or self.demo.poll() is not None:
                raise AssertionError(f"the demo did not take the drag in; it printed {''.join(self.stdout)!r}")
            time.sleep(0.002)

    def shot(self, path: Path) -> Path:
        path.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run(["import", "-window", "root", str(path)], env=self.env, check=True, timeout=30)
        return path

    def cpu_s(self) -> float:
        return process_cpu_s(self.demo.pid)

    def tree_cpu_s(self) -> float:
        """The demo's process and its descendants (the engine process: renderer, device, simulated plate)."""
        return tree_cpu_s(self.demo.pid)

    def main_thread_cpu_s(self) -> float:
        return process_cpu_s(self.demo.pid, self.demo.pid)

    def quit(self, timeout_s: float = 30.0) -> int:
        self.xdo("key", "q")
        return self.demo.wait(timeout=timeout_s)

    def close(self) -> None:
        if self.demo.poll() is None:
            self.demo.kill()
            self.demo.wait(timeout=10)
        self.xvfb.terminate()
        self.xvfb.wait(timeout=10)

    def __enter__(self) -> XvfbDemo:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
