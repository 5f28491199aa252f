"""The command's quick exit: what a normal exit does that matters, then the process ends at once."""

import subprocess
import sys

SCRIPT = """
import atexit, concurrent.futures, threading, time
from ultraglide.apps.cli.main import quick_exit
pool = concurrent.futures.ThreadPoolExecutor(2)  # left open, as a library may leave one
pool.submit(lambda: None).result()
worker = threading.Thread(target=lambda: (time.sleep(0.2), print("worker finished", flush=True)))
worker.start()  # not a daemon: waited for
atexit.register(lambda: print("atexit ran"))  # printed, then flushed by the quick exit
quick_exit(3)
print("never")
"""


def test_an_open_executor_does_not_hold_the_exit_and_threads_and_atexit_are_waited_for():
    result = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60)
    assert result.returncode == 3, result.stderr
    assert result.stdout.splitlines() == ["worker finished", "atexit ran"]
