"""SIGINT, SIGTERM and SIGHUP stop every command the way Ctrl-C does.

``ultraglide``'s ``main`` installs :class:`StopSignals` for the length of a command. A stop signal
raises :class:`Stopped` (a ``KeyboardInterrupt``) in the main thread, so every ``try``/``finally``
and ``with`` on the way out runs: devices ramp down and rest the plate, temporary files go.

A stop signal that finds the main thread taking a condition's lock back after a wait (the end of every wait on
an event or a queue, blocked while another thread holds that lock) is raised a moment later: raised there, the
wait would end without the lock, and the ``with`` around it release the lock under the thread that held it
("release unlocked lock" there) or leave it held by nobody (plate-sim once never exited: its main thread and
its frames thread both blocked on its event queue's lock). It is retried every ``RETRY_S`` (SIGALRM, only while
a stop waits; the wait itself, blocked on its own, is a safe place) and raised anyway after ``RETRY_FOR_S``
(a lock held that long is held for good: better a stop than a hang).

A second signal must not cut that clean-up short. Clean-up that must finish (resting a device,
removing a temporary file) runs inside :func:`held`: a signal arriving there is raised when the
block ends. Signals that follow the first within ``grace_s`` (a burst: several kills, an impatient
double Ctrl-C) are ignored wherever they land, since the first is still on its way out and may
be between two held blocks. A signal after that raises again, so a command whose first stop was
swallowed (Python drops exceptions raised while it runs a finaliser) can still be stopped.
"""

from __future__ import annotations

import contextlib
import inspect
import signal
import threading
import time
from collections.abc import Iterator

STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
RETRY_S = 0.01
RETRY_FOR_S = 1.0


def _retaking_lines() -> frozenset[int]:
    """The lines of ``threading.Condition.wait`` that take its lock back after the wait."""
    try:
        lines, first = inspect.getsourcelines(threading.Condition.wait)
    except (OSError, TypeError):
        return frozenset()
    return frozenset(first + index for index, line in enumerate(lines) if "_acquire_restore(" in line)


_RETAKING_LINES = _retaking_lines()


def retaking_a_lock(frame) -> bool:
    """Whether ``frame`` (where a signal found the main thread) is a condition taking its lock back after a wait
    (every wait on an event, a queue or a semaphore ends there): an exception raised in that acquire leaves the
    wait without the lock, and the ``with`` around it then releases the lock of whichever thread holds it."""
    code = frame.f_code if frame is not None else None
    return code is threading.Condition._acquire_restore.__code__ or (
        code is threading.Condition.wait.__code__ and frame.f_lineno in _RETAKING_LINES)


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
        self._pending = False  # a signal came during a held block, or while a condition took its lock back
        self._previous: dict[int, object] = {}
        self._retrying_since: float | None = None  # a stop put off from a lock's re-acquire: SIGALRM retries it
        self._alarm_previous = None
        self._alarm_ours = False

    def __call__(self, signum: int, frame) -> None:
        now = time.monotonic()
        if self.received is None:
            self.received, self._first_s = signum, now
        elif now - self._first_s < self.grace_s:
            return  # part of a burst: the first is still being handled
        self._raise_when_safe(frame)

    def _raise_when_safe(self, frame) -> None:
        if self._held:
            self._pending = True
            return
        if retaking_a_lock(frame):
            if self._retrying_since is None:
                self._retrying_since = time.monotonic()
            if time.monotonic() - self._retrying_since < RETRY_FOR_S:
                self._pending = True
                self._retry_later()
                return
        self._stop_retrying()
        self._pending = False
        raise Stopped(self.received)

    def _retry_later(self) -> None:
        if not self._alarm_ours:
            self._alarm_previous, self._alarm_ours = signal.signal(signal.SIGALRM, self._retry), True
        signal.setitimer(signal.ITIMER_REAL, RETRY_S)

    def _retry(self, signum: int, frame) -> None:
        if self._pending and not self._held:
            self._raise_when_safe(frame)
        elif not self._pending:
            self._stop_retrying()
        # (held: the block raises it as it ends)

    def _stop_retrying(self) -> None:
        self._retrying_since = None
        if self._alarm_ours:
            signal.setitimer(signal.ITIMER_REAL, 0)
            # (None: a handler set outside Python, which signal.signal cannot put back; the default is)
            signal.signal(signal.SIGALRM, signal.SIG_DFL if self._alarm_previous is None else self._alarm_previous)
            self._alarm_previous, self._alarm_ours = None, False

    @contextlib.contextmanager
    def holding(self) -> Iterator[None]:
        self._held += 1
        try:
            yield
        finally:
            self._held -= 1
        if not self._held and self._pending:
            self._pending = False
            self._stop_retrying()
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
        self._stop_retrying()
        for signum, previous in self._previous.items():
            signal.signal(signum, previous if self.received is None else signal.SIG_IGN)
        self._previous.clear()


def stop_requested() -> bool:
    """Whether a stop signal has come to this command (held back, for instance, by a :func:`held` block around an
    event loop, which polls this and ends its service on its own: a ``KeyboardInterrupt`` raised wherever the signal
    found the loop's thread can land inside a library's coroutine and leave it broken). False outside ``main``."""
    with contextlib.suppress(ValueError):
        handler = signal.getsignal(signal.SIGTERM)
        return isinstance(handler, StopSignals) and handler.received is not None
    return False


def held() -> contextlib.AbstractContextManager:
    """A block that a stop signal does not interrupt: one arriving inside is raised as the block ends.

    Outside ``ultraglide``'s ``main`` (a library caller, a test) this holds nothing."""
    with contextlib.suppress(ValueError):
        handler = signal.getsignal(signal.SIGTERM)
        if isinstance(handler, StopSignals) and threading.current_thread() is threading.main_thread():
            return handler.holding()
    return contextlib.nullcontext()
