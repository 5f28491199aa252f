"""SIGINT, SIGTERM and SIGHUP stop every command the way Ctrl-C does.

``ultraglide``'s ``main`` installs :class:`StopSignals` for the length of a command. A stop signal
raises :class:`Stopped` (a ``KeyboardInterrupt``) in the main thread, so every ``try``/``finally``
and ``with`` on the way out runs: devices ramp down and rest the plate, temporary files go.
Clean-up that must not be cut short (resting a device, removing a temporary file) runs inside
:func:`held`: a signal that arrives there, the first or a second one, is raised when the block ends.
A signal outside such a block raises again, so a second Ctrl-C still stops a command whose first
was swallowed (Python drops exceptions raised while it runs a finaliser).
"""

from __future__ import annotations

import contextlib
import signal
import threading
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

    def __init__(self):
        self.received: int | None = None  # the first stop signal, once one has come
        self._held = 0
        self._pending = False  # a signal came during a held block
        self._previous: dict[int, object] = {}

    def __call__(self, signum: int, frame) -> None:
        if self.received is None:
            self.received = signum
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
