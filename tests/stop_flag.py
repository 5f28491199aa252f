"""For the tests' helper scripts (run as ``python tests/NAME.py``): SIGTERM as a flag their main loop polls."""

import signal


def stop_on_sigterm() -> list:
    """A list that gets an item when SIGTERM arrives; the caller's loop runs while it is empty. Not a
    threading.Event: setting one from a signal handler that interrupted this thread's own ``wait`` on it
    deadlocks on the event's lock (seen with py-spy in a recorder that never ended)."""
    stopped: list = []
    signal.signal(signal.SIGTERM, lambda *_: stopped.append(True))
    return stopped
