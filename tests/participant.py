"""A participant on a thread beside a session's window: real pygame events posted, paced by what the window shows.

A participant that fails (the window never showed what it waited for) ends the session: it posts a QUIT each
time the window waits for input until the session is over, so the test fails at once with the participant's
error, not after the suite's timeout with a window still waiting for an answer nobody will give.
"""

from __future__ import annotations

import threading
import time

DEADLINE_S = 120.0


def wait_for(window, what: str, number: int, deadline_s: float = DEADLINE_S) -> None:
    """Until ``window`` shows ``what`` ("trial" or "break") ``number`` and waits for input; AssertionError if it
    has not within ``deadline_s``."""
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        if window.ready.wait(0.05) and window.showing == (what, number):
            return
        time.sleep(0.005)  # shown, but not yet this one: the window clears ``ready`` when it moves on
    raise AssertionError(f"the window never showed {what} {number} within {deadline_s:g} s "
                         f"(it showed {window.showing})")


def post(pg, kind, **fields) -> None:
    pg.event.post(pg.event.Event(kind, **fields))


def key(pg, name: str) -> None:
    """A key press, by pygame's name of the key."""
    post(pg, pg.KEYDOWN, key=pg.key.key_code(name), mod=0, unicode=name if len(name) == 1 else "", scancode=0)


class Participant:
    """``body(*args)`` on a thread while the ``with`` block runs the session; its error is raised at the block's end.

    Examples
    --------
    ::

        with Participant(pg, window, answer_every_trial):
            try:
                outcome = run_session(config, design, window, tmp_path)
            finally:
                window.close()
    """

    def __init__(self, pg, window, body, *args):
        self.pg, self.window = pg, window
        self.error: BaseException | None = None
        self._over = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(body, args), daemon=True)

    def _run(self, body, args) -> None:
        try:
            body(*args)
        except BaseException as error:  # noqa: BLE001 - handed to the test at the block's end
            self.error = error
            while not self._over.is_set():  # a QUIT posted between trials would be cleared by the next one
                if self.window.ready.wait(0.05):
                    post(self.pg, self.pg.QUIT)
                    self._over.wait(0.05)

    def __enter__(self) -> Participant:
        self._thread.start()
        return self

    def __exit__(self, kind, value, traceback) -> None:
        self._over.set()
        if kind is not None:  # the session's own error says it all; the participant may wait on for nothing
            self._thread.join(1.0)
            return
        self._thread.join(DEADLINE_S)
        if self.error is not None:
            raise AssertionError(f"the participant failed: {self.error}") from self.error
        assert not self._thread.is_alive(), "the session ended while the participant still waited for the window"
