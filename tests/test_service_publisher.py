"""The service's publisher (``Service.publish``, its own thread in ``serve``): the engine's status is read only when
a subscriber is due, not at every look: each read holds the interpreter for about a millisecond of Python, which a
touch arriving then waited for."""

import asyncio
import contextlib
import sys
import threading
import time

import numpy as np
from ultraglide.apps.service.server import Service, Session
from ultraglide.devices.profiles import load_profile
from ultraglide.render.engine import Engine, EngineConfig


def _publish_until(service: Service, sessions, enough, woke: list | None = None) -> None:
    """Run the publisher as serve does (a thread handing messages to this loop) until ``enough()`` holds, looked at
    whenever the first session is handed a message; ``woke``: (its thread's wake-ups as the kernel counts them,
    the seconds it ran) appended."""

    async def watch():
        loop = asyncio.get_running_loop()
        for session in sessions:
            session.wake = asyncio.Event()
            service.sessions.add(session)
        stop = threading.Event()
        publisher = threading.Thread(target=service.publish, args=(loop, stop), daemon=True)
        started = time.perf_counter()
        publisher.start()
        try:
            deadline = loop.time() + 60.0
            while not enough():
                assert loop.time() < deadline, "the subscribers got too little within 60 s"
                sessions[0].wake.clear()
                if not enough():
                    await asyncio.wait_for(sessions[0].wake.wait(), max(0.0, deadline - loop.time()))
            if woke is not None:
                woke.append((_voluntary_switches(publisher.native_id), time.perf_counter() - started))
        finally:
            stop.set()
            await asyncio.to_thread(publisher.join, 10.0)

    asyncio.run(watch())


def _voluntary_switches(thread_id: int) -> int:
    """How many times thread ``thread_id`` of this process gave up its CPU to wait (the kernel's count): each
    sleep it woke from, and each wait for the interpreter's lock."""
    for line in open(f"/proc/self/task/{thread_id}/status"):
        if line.startswith("voluntary_ctxt_switches:"):
            return int(line.split()[1])
    raise AssertionError("no voluntary_ctxt_switches in /proc")


@contextlib.contextmanager
def _service_on_null():
    """A service whose engine (its real process) renders to the null device, ready."""
    service = Service(None, load_profile("sim-plate"))
    with Engine.start(EngineConfig(texture=service.first_texture(), device="null", realtime_priority=False)) \
            as engine:
        engine.wait_ready(60.0)
        service.engine = engine
        yield service


def _pushes(session: Session, kind: str) -> list[dict]:
    return [message for push, message in session.queue if push and message["type"] == kind]


def test_a_status_subscriber_at_2_hz_costs_the_engine_one_status_read_per_status_sent():
    with _service_on_null() as service:
        page = Session(None, 1, role="control", status_hz=2.0)
        quiet = Session(None, 2, role="observe")  # subscribed to nothing: never a reason to read
        _publish_until(service, [page, quiet], lambda: len(_pushes(page, "status")) >= 3)
    statuses = _pushes(page, "status")
    assert statuses[0]["device"] == "null" and not quiet.queue
    # 3 statuses at 2 Hz took 1 s or more: at every 10 ms look the engine would have been read 100 times
    assert 3 <= service.status_reads <= len(statuses) + 1, (service.status_reads, len(statuses))


def _rows_sent(watcher: Session) -> list[float]:
    return [t for message in _pushes(watcher, "output") for t in message["t"]]


def _assert_every_due_row_sent(blocks: np.ndarray, times: list[float], subscribed: float, hz: float) -> None:
    """Rows at ``hz``: each the engine's first block at least 1/``hz`` after the one sent before it (the product's
    arithmetic: 0.1 % under), from the first block after the subscription on. Judged by the blocks' own times
    against the engine's history (``blocks``, its times), not by when the rows arrived."""
    assert blocks[0] < subscribed and len(times) >= 2, "the engine's ring no longer holds the whole run"
    # each row sent is one of the engine's blocks (its time rounded to the µs)
    at = np.searchsorted(blocks, np.asarray(times) - 1e-6)
    assert np.abs(blocks[at] - times).max() <= 1e-6
    sent = blocks[at]
    assert sent[0] == blocks[blocks > subscribed][0]  # the first block after the subscription
    assert np.diff(sent).min() >= 1 / hz * 0.999  # at most the rate asked for
    # and no hole: none of the engine's blocks was passed over that was due (1/hz after the last row sent)
    for before, row in zip(sent[:-1], sent[1:], strict=True):
        due = blocks[blocks - before >= 1 / hz * 0.999]
        assert row == due[0], (before, row, due[0])


def _hold_the_interpreter(seconds: float) -> float:
    """Run pure Python on this thread for ``seconds`` without letting another thread of this process have the
    interpreter (its switch interval made longer than that): the publisher's thread, woken meanwhile, runs late, as
    on a machine that does not schedule it. The seconds it was held."""
    interval = sys.getswitchinterval()
    sys.setswitchinterval(10 * seconds)
    began = time.perf_counter()
    try:
        while time.perf_counter() - began < seconds:
            pass
    finally:
        sys.setswitchinterval(interval)
    return time.perf_counter() - began


def test_output_rows_at_a_low_rate_are_read_at_that_rate_and_none_is_lost():
    """A gap longer than 50 ms between rows' times is the engine's (a loaded machine stalled it), never the
    publisher's: it read only 0.25 s of rows, and woken 0.15 s late lost some (holes of 132-596 ms beside two
    hogs)."""
    with _service_on_null() as service:
        subscribed = time.perf_counter()
        watcher = Session(None, 1, role="observe", output_hz=20.0, output_from_s=subscribed)
        _publish_until(service, [watcher], lambda: len(_rows_sent(watcher)) >= 20)
        blocks = service.engine.status(history_s=60.0).history.time_s  # every block rendered that its ring holds
    times = _rows_sent(watcher)
    _assert_every_due_row_sent(blocks, times, subscribed, 20.0)
    seconds = times[-1] - times[0]
    assert service.status_reads <= seconds / 0.05 + 3, (service.status_reads, seconds)  # at 20 Hz, not 100


def test_a_publisher_woken_a_second_late_loses_no_row():
    """The engine (its own process) renders on while the publisher's thread cannot run for 1 s: the rows of that
    second are all sent, at the rate asked, when it runs again."""
    with _service_on_null() as service:
        subscribed = time.perf_counter()
        watcher = Session(None, 1, role="observe", output_hz=20.0, output_from_s=subscribed)
        held = []

        def enough():
            if len(_rows_sent(watcher)) >= 3 and not held:  # the stimulus, once: after the first rows
                held.append((time.perf_counter(), _hold_the_interpreter(1.0)))
            return len(_rows_sent(watcher)) >= 30

        _publish_until(service, [watcher], enough)
        blocks = service.engine.status(history_s=60.0).history.time_s
    times = _rows_sent(watcher)
    began, held_s = held[0]
    assert held_s >= 1.0
    # the engine rendered in the hold's first 0.7 s, more than 0.25 s before the publisher could run again
    assert np.any((blocks > began) & (blocks < began + held_s - 0.3)), "the engine rendered nothing in the hold"
    _assert_every_due_row_sent(blocks, times, subscribed, 20.0)
    assert any(began < t < began + held_s - 0.3 for t in times), (began, held_s, times)  # a 0.25 s read lost them


def test_with_a_status_subscriber_at_2_hz_the_publisher_wakes_a_few_times_a_second_not_a_hundred():
    """Each wake-up of the publisher takes the interpreter from the loop; it slept 10 ms at a time whoever had
    subscribed (100 wake-ups a second, as often as a pointer's touches at 100 Hz)."""
    with _service_on_null() as service:
        page = Session(None, 1, role="control", status_hz=2.0)
        woke = []
        _publish_until(service, [page], lambda: len(_pushes(page, "status")) >= 4, woke)
    switches, seconds = woke[0]
    assert seconds >= 1.4  # 4 statuses at 2 Hz: the first at once, the fourth 1.5 s later
    # asleep until the next status is due (at most 0.25 s at a time), a few more for the interpreter's lock: the old
    # 10 ms sleeps alone made 100 a second
    assert switches <= 20 * seconds, (switches, seconds)
