"""The service's rate limit, on a real ``ultraglide serve`` whose loop is made late for real (the process stopped by
SIGSTOP while its client sends, then continued: it reads seconds of messages in one burst, as a descheduled loop
does): a client sending a steady 1000 touches a second is not refused; one sending 20 000 a second is, past what
the limit lets through by the touches' own times."""

import json
import signal
import threading
import time

from service_run import running_service, stop
from ultraglide.apps.service.server import RATE_BURST, RATE_PER_S

from ultraglide.client import Client, ConnectionFailed, RateLimited


def send_steady(plate: Client, count: int, rate_hz: float, start: float) -> None:
    """``count`` touches of one finger (down, moves, up), the k-th happening at ``start + k / rate_hz`` (its ``t``,
    this program's perf_counter) and sent then, or as soon after as the socket takes it."""
    for k in range(count):
        due = start + k / rate_hz
        while time.perf_counter() < due:
            time.sleep(min(0.001, max(0.0, due - time.perf_counter())))
        phase = "down" if k == 0 else "up" if k == count - 1 else "move"
        plate.touch(10.0 + (k % 200) * 0.1, 20.0, phase, t=due)


def sent_while_stopped(process, plate: Client, count: int, rate_hz: float) -> tuple[float, float]:
    """The service stopped (SIGSTOP) while ``count`` touches at ``rate_hz`` happen and are sent (the socket's buffers
    hold them: 4 MB on this loopback), continued (SIGCONT) once the last is sent, then asked a request, answered once
    it has read every message before it. (The time it was continued, the time the answer came), perf_counter s."""
    start = time.perf_counter() + 0.05
    process.send_signal(signal.SIGSTOP)
    resumed, once = [], threading.Lock()

    def resume():
        with once:
            if not resumed:
                resumed.append(time.perf_counter())
                process.send_signal(signal.SIGCONT)

    # should the buffers fill, the sender waits in its write: the service is then continued from another thread,
    # 10 s after the last touch's time
    timer = threading.Timer(start + count / rate_hz + 10.0 - time.perf_counter(), resume)
    timer.start()
    try:
        send_steady(plate, count, rate_hz, start)
    finally:
        resume()
        timer.cancel()
    # a request refused over the rate is dropped unanswered: asked again every 0.5 s (the rate refills meanwhile)
    plate.timeout_s = 0.5
    deadline = time.monotonic() + 120.0
    while True:
        try:
            plate.state()
            return resumed[0], time.perf_counter()
        except ConnectionFailed as error:
            if "no answer" not in str(error) or time.monotonic() > deadline:
                raise


def final_summary(process) -> dict:
    """The service stopped by SIGTERM: its final status (``--json``'s last line)."""
    stop(process)
    return [json.loads(line) for line in process.stdout.read().splitlines() if line.startswith("{")][-1]


def test_a_steady_client_read_late_in_one_burst_is_not_refused():
    count, rate_hz = 5000, 1000.0  # 5 s of touches, all read in one burst once the service is continued: as read,
    # 5000 in well under a second; as sent, 1000 a second
    with running_service("--device", "null", "--port", "0") as (process, address):
        with Client(address["url"]) as plate:
            resumed, answered = sent_while_stopped(process, plate, count, rate_hz)
            refused = [error for error in plate.errors if isinstance(error, RateLimited)]
        summary = final_summary(process)
    assert not refused, f"{refused[-1]} (the backlog read in {answered - resumed:.3f} s)"
    assert summary["rate_refused"] == 0
    assert summary["touches"] == count and summary["touches_ignored"] == 0


def test_a_client_sending_above_the_limit_is_refused_past_it_however_late_it_is_read():
    # 1.2 s of touches 0.05 ms apart (ten times the limit), 2 MB on the wire, held by the socket's buffers: the limit
    # lets through at most 2000 + 2000 a second of the longer of their span and their reading, so this is a flood
    # to refuse unless the service takes 11 s to read them (a loaded machine's stalls count as reading time: it
    # cannot tell them from a client within its rate). 12 000 touches 0.25 ms apart were one only if read within
    # 5 s, and twice under load were not.
    count, rate_hz = 24000, 20000.0
    with running_service("--device", "null", "--port", "0") as (process, address):
        with Client(address["url"]) as plate:
            resumed, answered = sent_while_stopped(process, plate, count, rate_hz)
            refused = [error for error in plate.errors if isinstance(error, RateLimited)]
        summary = final_summary(process)
    # what the limit lets through at most: the burst, then its rate over the span of the touches' own times, or over
    # the time they were read in (at most from the service's continuing to the answer), whichever is longer
    let_through = RATE_BURST + RATE_PER_S * max((count - 1) / rate_hz, answered - resumed)
    said = (f"read and answered {answered - resumed:.3f} s after the service was continued; at most {let_through:.0f} "
            f"let through; the service's final status {summary}; {len(refused)} rate lines at the client")
    assert let_through < count, f"no flood to refuse: {said}"
    assert refused and "more than 2000 messages a second" in str(refused[0]) and "\n" not in str(refused[0]), said
    assert len(refused) <= 1 + summary["rate_refused"] // 1000, said  # one line for the first, one a thousand after
    assert summary["touches"] <= let_through, said
    # every touch not taken was refused over the rate (and maybe a request or two asked while still over it)
    assert count - summary["touches"] <= summary["rate_refused"] <= count - summary["touches"] + 240, said
