"""CPU 0 taken from ordinary threads, as a busy machine takes it: a process spinning there at real-time priority
(SCHED_FIFO 1). The kernel still leaves ordinary threads a share (its real-time throttling, or the fair class's
deadline server: 50 ms a second), so threads kept on CPU 0 run in bursts and wait, runnable, in between. Or CPU 0
shared with ordinary busy processes (:func:`cpu0_shared`): a thread kept there runs a share of the time."""

import contextlib
import os
import subprocess
import sys

import pytest

SPIN = """
import os, sys
os.sched_setaffinity(0, {0})
try:
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
except OSError as error:
    print(f"no real-time priority here ({error})", flush=True)
    sys.exit(0)
print("spinning", flush=True)
while True:
    pass
"""


@contextlib.contextmanager
def cpu0_taken():
    """While the block runs, CPU 0 spins for a real-time process (skips the test where none may take it)."""
    hog = subprocess.Popen([sys.executable, "-c", SPIN], stdout=subprocess.PIPE, text=True)
    try:
        said = hog.stdout.readline().strip()
        if said != "spinning":
            pytest.skip(said or "the CPU hog did not start")
        yield hog
    finally:
        hog.kill()
        hog.wait()


@contextlib.contextmanager
def cpu0_shared(hogs: int = 2):
    """While the block runs, ``hogs`` ordinary processes (SCHED_OTHER, nice 0) spin on CPU 0."""
    spin = "import os, sys\nos.sched_setaffinity(0, {0})\nprint('spinning', flush=True)\nwhile True:\n    pass\n"
    started = []
    try:
        for _ in range(hogs):
            started.append(subprocess.Popen([sys.executable, "-c", spin], stdout=subprocess.PIPE, text=True))
            assert started[-1].stdout.readline().strip() == "spinning", "a CPU hog did not start"
        yield started
    finally:
        for hog in started:
            hog.kill()
            hog.wait()


def keep_on_cpu0(pid: int) -> list[int]:
    """Put every thread of process ``pid`` on CPU 0 at ordinary priority (SCHED_OTHER, nice 0); returns them."""
    threads = list(map(int, os.listdir(f"/proc/{pid}/task")))
    for tid in threads:
        with contextlib.suppress(OSError):  # (a thread that ended meanwhile)
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
            os.sched_setaffinity(tid, {0})
    return threads


def free_of_cpu0(threads: list[int]) -> None:
    """Let ``threads`` run on any CPU again."""
    for tid in threads:
        with contextlib.suppress(OSError):
            os.sched_setaffinity(tid, range(os.cpu_count()))
