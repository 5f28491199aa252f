"""What the service's tests share: a real ``ultraglide serve`` process, flat textures as PNG bytes, and the
engine's envelope record read back."""

import contextlib
import io
import json
import select
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
from conftest import start_cli


@contextlib.contextmanager
def running_service(*args, timeout_s: float = 120.0):
    """``ultraglide serve --json ARGS`` running: yields (process, first line as a dict: url, page, token). Stopped
    by SIGTERM on the way out; the test may have stopped it already."""
    process = start_cli("serve", "--json", *args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        line = read_line(process.stdout, timeout_s)
        assert line, f"serve printed no address: {process.stderr.read() if process.poll() is not None else ''}"
        yield process, json.loads(line)
    finally:
        stop(process)


def read_line(stream, timeout_s: float) -> str:
    """The next line of a process's output pipe, or '' at its end or after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        ready, _, _ = select.select([stream], [], [], min(0.5, max(0.0, deadline - time.monotonic())))
        if ready:
            return stream.readline()
    return ""


def stop(process, timeout_s: float = 60.0) -> int:
    """SIGTERM, as a service manager stops it; its exit status."""
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
    try:
        return process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        stacks = where_it_waits(process.pid)
        process.kill()
        raise AssertionError(f"the service did not stop within {timeout_s:g} s of SIGTERM; its threads:\n"
                             f"{stacks}") from None


def where_it_waits(pid: int) -> str:
    """Every thread's stack of process ``pid`` and of its children (an engine is one; py-spy, which the dev
    dependencies install), for a stop that hangs."""
    import shutil
    import sys

    spy = shutil.which("py-spy") or str(Path(sys.executable).with_name("py-spy"))
    try:
        return subprocess.run([spy, "dump", "--subprocesses", "--pid", str(pid)], capture_output=True, text=True,
                              timeout=60).stdout
    except (OSError, subprocess.SubprocessError) as error:
        return f"(py-spy could not look: {error})"


def flat_png(ratio: float, width_px: int = 40, height_px: int = 40) -> bytes:
    """A plain grayscale PNG whose brightness is ``ratio`` (a plain image's brightness is its friction ratio)."""
    from PIL import Image

    stream = io.BytesIO()
    Image.fromarray(np.full((height_px, width_px), round(ratio * 255), dtype=np.uint8), mode="L").save(stream, "PNG")
    return stream.getvalue()


def png_ratio(ratio: float) -> float:
    """The ratio a flat PNG of ``ratio`` holds (8 bits)."""
    return round(ratio * 255) / 255


def read_envelope(path) -> np.ndarray:
    """The envelope record (``--envelope-csv``) as a structured array: t_s, index, x_mm, y_mm, down, target_ratio,
    target_um_pp, commanded_um_pp."""
    return np.genfromtxt(path, delimiter=",", names=True)


def rows_at(envelope: np.ndarray, x_mm: float, y_mm: float, within_mm: float = 0.05) -> np.ndarray:
    """The rows rendered with the finger down at (x, y)."""
    near = (np.abs(envelope["x_mm"] - x_mm) < within_mm) & (np.abs(envelope["y_mm"] - y_mm) < within_mm)
    return envelope[near & (envelope["down"] > 0.5)]


def hold(client, x: float, y: float, seconds: float = 0.15, **touch) -> None:
    """A finger down at (x, y) in the view's units, held still (a move every 10 ms), then lifted."""
    client.touch(x, y, "down", **touch)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        time.sleep(0.01)
        client.touch(x, y, "move", **touch)
    client.touch(x, y, "up", **touch)
