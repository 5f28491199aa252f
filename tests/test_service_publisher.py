"""The service's publisher (``Service.publish``, its own thread in ``serve``): the engine's status is read only when
a subscriber is due, not at every look: each read holds the interpreter for about a millisecond of Python, which a
touch arriving then waited for."""

import asyncio
import contextlib
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


def test_output_rows_at_a_low_rate_are_read_at_that_rate_and_none_is_lost():
    with _service_on_null() as service:
        watcher = Session(None, 1, role="observe", output_hz=20.0)
        _publish_until(service, [watcher], lambda: sum(len(m["t"]) for m in _pushes(watcher, "output")) >= 20)
    times = [t for message in _pushes(watcher, "output") for t in message["t"]]
    gaps = np.diff(times)
    assert gaps.min() >= 1 / 20 * 0.999  # at most the rate asked for
    # and no hole: each read keeps 0.25 s of rows and comes within about 0.1 s of the last, so every 50 ms has its row
    # (a row is a block, 1-2 ms apart)
    assert gaps.max() < 0.1, gaps.max()
    seconds = times[-1] - times[0]
    assert service.status_reads <= seconds / 0.05 + 3, (service.status_reads, seconds)  # at 20 Hz, not 100


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
