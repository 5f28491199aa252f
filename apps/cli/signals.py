"""SIGINT, SIGTERM and SIGHUP stop every command the way Ctrl-C does.

``ultraglide``'s ``main`` installs :class:`StopSignals` for the length of a command. A stop signal
raises :class:`Stopped` (a ``KeyboardInterrupt``) in the main thread, so every ``try``/``finally``
and ``with`` on the way out runs: devices ramp down and rest the plate, temporary files go.

A second signal must not cut that clean-up short. Clean-up that must finish (resting a device,
removing a temporary file) runs inside :func:`held`: a signal arriving there is raised when the
block ends. Signals that follow the first within ``grace_s`` (a burst: several kills, an impatient
double Ctrl-C) are ignored wherever they land, since the first is still on its way out and may
be between two held blocks. A signal after that raises again, so a command whose first stop was
swallowed (Python drops exceptions raised while it runs a finaliser) can still be stopped.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Iterator

STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class Stopped(KeyboardInterrupt):
    """A stop signal arrived; ``exit_status`` is the shell's 128 + signal number."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum
        self.name = signal.Signals(signum).name
        self.exit_status = 128 + signum


class StopSignals:
    """The handler for the stop signals while a command runs (see the module's docstring)."""

    def __init__(self, grace_s: float = 2.0):
        self.grace_s = grace_s
        self.received: int | None = None  # the first stop signal, once one has come
        self._first_s = 0.0
        self._held = 0
        self._pending = False  # a signal came during a held block
        self._previous: dict[int, object] = {}

    def __call__(self, signum: int, frame) -> None:
        now = time.monotonic()
        if self.received is None:
            self.received, self._first_s = signum, now
        elif now - self._first_s < self.grace_s:
            return  # part of a burst: the first is still being handled
        if self._held:
            self._pending = True
            return
        raise Stopped(self.received)

    @contextlib.contextmanager
    def holding(self) -> Iterator[None]:
        self._held += 1
        try:
            yield
        finally:
            self._held -= 1
        if not self._held and self._pending:
            self._pending = False
            raise Stopped(self.received)

    def install(self) -> bool:
        """Handle the stop signals from now on; False (and nothing done) off the main thread."""
        if threading.current_thread() is not threading.main_thread():
            return False
        for signum in STOP_SIGNALS:
            self._previous[signum] = signal.signal(signum, self)
        return True

    def restore(self) -> None:
        """Put back the handlers that were there before ``install``; once a stop signal has come, ignore
        the stop signals instead: the process is on its way out (and the interpreter, as it shuts down,
        would put back default handlers that kill it with another status)."""
        for signum, previous in self._previous.items():
            signal.signal(signum, previous if self.received is None else signal.SIG_IGN)
        self._previous.clear()


def held() -> contextlib.AbstractContextManager:
    """A block that a stop signal does not interrupt: one arriving inside is raised as the block ends.

    Outside ``ultraglide``'s ``main`` (a library caller, a test) this holds nothing."""
    with contextlib.suppress(ValueError):
        handler = signal.getsignal(signal.SIGTERM)
        if isinstance(handler, StopSignals) and threading.current_thread() is threading.main_thread():
            return handler.holding()
    return contextlib.nullcontext()
