"""SIGINT, SIGTERM and SIGHUP stop every command the way Ctrl-C does.

``ultraglide``'s ``main`` installs :class:`StopSignals` for the length of a command. A stop signal
raises :class:`Stopped` (a ``KeyboardInterrupt``) in the main thread, so every ``try``/``finally``
and ``with`` on the way out runs: devices ramp down and rest the plate, temporary files go.

A stop signal that finds the main thread where an exception would break something is raised a moment later:

- inside ``threading``'s own lock handling (a condition taking its lock or giving it back, every wait on an
  event or a queue going in or out), except where it blocks waiting: raised there, the lock stays held by the
  main thread for good, or the wait ends without it and the ``with`` around it releases it under the thread that
  held it ("release unlocked lock" there). plate-sim once never exited: its main thread blocked on its event
  queue's lock, which it had itself taken just before the signal. Raised anyway after ``RETRY_FOR_S`` (a lock
  held that long is held for good: better a stop than a hang).
- inside a finaliser (a ``__del__`` the collector runs wherever it runs): Python prints the exception as
  "Exception ignored in" and drops it, and the command goes on as if nothing had come. Never raised there.

It is retried every ``RETRY_S`` (SIGALRM, only while a stop waits).

A second signal must not cut that clean-up short. Clean-up that must finish (resting a device,
removing a temporary file) runs inside :func:`held`: a signal arriving there is raised when the
block ends. Signals that follow the first within ``grace_s`` (a burst: several kills, an impatient
double Ctrl-C) are ignored wherever they land, since the first is still on its way out and may
be between two held blocks. A signal after that raises again, so a command whose first stop was
lost (caught by a library on its way out, say) can still be stopped.
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


def _blocking_lines() -> dict[object, frozenset[int]]:
    """The lines of ``threading`` where a thread blocks in an acquire holding no lock of a condition's: the wait
    of ``Condition.wait`` and the join of ``Thread._wait_for_tstate_lock``, by their code objects."""
    lines = {}
    for function, call in ((threading.Condition.wait, "waiter.acquire("),
                           (threading.Thread._wait_for_tstate_lock, "lock.acquire(")):
        try:
            source, first = inspect.getsourcelines(function)
        except (OSError, TypeError):
            continue
        lines[function.__code__] = frozenset(first + index for index, line in enumerate(source) if call in line)
    return lines


_BLOCKING_LINES = _blocking_lines()
_THREADING_FILE = threading.Condition.wait.__code__.co_filename


def passing_a_lock(frame) -> bool:
    """Whether ``frame`` (where a signal found the main thread) is ``threading``'s own code outside a blocking wait:
    taking a condition's lock, giving it back, or between the two halves of a wait. An exception raised there can
    leave the lock held for good, or released under another thread (see the module's docstring).

    Examples
    --------
    >>> import sys
    >>> passing_a_lock(sys._getframe())  # this example's own frame
    False
    """
    if frame is None or frame.f_code.co_filename != _THREADING_FILE:
        return False
    return frame.f_lineno not in _BLOCKING_LINES.get(frame.f_code, ())


def in_a_finaliser(frame) -> bool:
    """Whether ``frame`` or one of its callers is a ``__del__``: Python drops an exception raised there.

    Examples
    --------
    >>> import sys
    >>> class Noted:
    ...     def __del__(self):
    ...         print("in a finaliser:", in_a_finaliser(sys._getframe()))
    >>> dropped = Noted()
    >>> del dropped
    in a finaliser: True
    >>> in_a_finaliser(sys._getframe())
    False
    """
    while frame is not None:
        if frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


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
        finaliser = in_a_finaliser(frame)
        if finaliser or passing_a_lock(frame):
            if self._retrying_since is None:
                self._retrying_since = time.monotonic()
            if finaliser or time.monotonic() - self._retrying_since < RETRY_FOR_S:
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
