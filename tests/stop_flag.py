"""For the tests' helper scripts (run as ``python tests/NAME.py``): SIGTERM as a flag their main loop polls."""

import json
import signal
import time


def stop_on_sigterm() -> list:
    """A list that gets an item when SIGTERM arrives; the caller's loop runs while it is empty. Not a
    threading.Event: setting one from a signal handler that interrupted this thread's own ``wait`` on it
    deadlocks on the event's lock (seen with py-spy in a recorder that never ended)."""
    stopped: list = []
    signal.signal(signal.SIGTERM, lambda *_: stopped.append(True))
    return stopped


def drive_until_sigterm(driver) -> None:
    """Say ``ready`` on standard output, let ``driver`` (a started plate driver) run until SIGTERM, stop it, then
    print its status as one JSON line: the protocol of the scripts that host a driver for a test."""
    stopped = stop_on_sigterm()
    print("ready", flush=True)
    while not stopped:
        time.sleep(0.01)
    driver.stop()
    print(json.dumps(driver.status()), flush=True)
