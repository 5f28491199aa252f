"""What ``ultraglide serve`` adds to the engine's touch-to-output latency, and what 1000 pointer events a second do.

Run: .venv/bin/python bench/bench_service.py [--touches 300] [--rounds 2] [--soak-s 60] [--browser] [--unix]
[--loop-slice-ms 0.1] [--no-short-path] [--client-general] [--client sync|async] [--pace spin|sleep]

One engine (on the simulated plate, as ``serve`` starts it) and the service in this process, its loop set up as
``serve``'s (:func:`apps.commands.serve._loop_in_real_time`: the loop thread's priority; the interpreter's switch
interval printed) and its publisher thread running; a client in another process (``ultraglide.client``) on a real
socket, subscribed to the status at 2 Hz as the page is (``--no-subscribe``: not). Both clocks are
``perf_counter`` (CLOCK_MONOTONIC, one clock for every process on Linux).

* **latency**: rounds of touches at 100 Hz, alternately put into the engine directly (as ``play`` and the demo do:
  the engine's own touch-to-output latency) and sent by the client (its event time: its clock when it sent it). For
  each, the engine's own record (``Engine.latencies``): when the block that first rendered it was presented.
  Aim (issue 41): the service adds at most 1 ms at p99.
* **the floor**, in each round too: the same touches, the same pacing, from a bare socket in another process to a
  bare asyncio protocol on the service's own loop (no WebSocket, no service): the client's send to the loop's read,
  what two Python processes do on this machine for one small message; and the service's same hop beside it.
* **soak**: 1000 pointer events a second for ``--soak-s`` seconds, first put into the engine directly, then sent by
  the client: the engine's late blocks in each (none beyond the engine's own), this process's memory, and where
  every touch the client sent went: sent late (its own lateness), lost on the socket, refused over the rate, taken
  and not rendered, reached the engine, dropped by its ring, unaccounted for; and how late the service read them.
* ``--unix``: the client and the floor through a Unix socket (``serve --unix``) instead of TCP on loopback.
* ``--loop-slice-ms``: the loop thread's time slice (serve's, :data:`apps.commands.serve.LOOP_SLICE_S`; 0: the
  kernel's default), for a before/after.
* ``--no-short-path``: the service's connections without serve's short path
  (:func:`apps.service.server.short_path_connection`: a message handled as websockets reads it), for a before/after.
* ``--client-general``: the client's touches through its general path (``json.dumps``, websockets' ``send``), not
  its short one (:func:`ultraglide.client.touch_text` and its own frame), for a before/after.
* ``--client async``: the client is :class:`ultraglide.client.AsyncClient` (its touch not awaited), in the rounds
  and the soak; with ``--client-general``, its touches through websockets' ``send`` in a task each.
* ``--pace``: how each client waits for its next touch: ``spin`` (the default: short sleeps, then a busy wait) or
  ``sleep`` (one sleep, as a program woken by its input).
* The client's refusals by the service (the rate, ...), when there are any, are printed as they came.
* ``--browser``: the page in headless Chromium (``serve --page``), 200 synthesized touch moves: the milliseconds from
  each pointer event's time stamp to its message sent (the browser's own part, reported apart).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np

PACE = r"""
def wait_until(due, pace):
    if pace == "sleep":
        time.sleep(max(0.0, due - time.perf_counter()))
        return
    while time.perf_counter() < due:
        if due - time.perf_counter() > 0.0005:
            time.sleep(0.0002)
"""

REPORT = r"""
refused = {}
for error in errors:  # the service's refusals of unanswered messages (rate, ...): how many lines, the last said of each
    count_of, _ = refused.get(error.code, (0, ""))
    refused[error.code] = (count_of + 1, str(error))
late = [t - (start + k / rate) for k, (t, _) in enumerate(sent)]  # how late each touch was sent, s
print(json.dumps({"sent": sent, "waited_ns": ran[1], "runs": ran[2], "refused": refused, "messages": messages + count
                  + 1, "late_max_s": max(late), "late_over_10ms": sum(v > 0.01 for v in late)}))
# its thread's wait for a CPU and its runs (the kernel's), what the service refused, the messages it sent (touches, the
# lift, its hello, subscription and last request), how late it sent its touches
"""

CLIENT = r"""
import json, sys, time
from ultraglide.client import Client
url, count, rate, status_hz, pace = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5]
general = sys.argv[6] == "general"
""" + PACE + r"""
sent = []
with Client(url) as plate:
    messages = 2  # its hello, and its last request
    if general:
        plate._frame_parts = None  # (--client-general) every touch through json.dumps and websockets' send
    if status_hz:
        plate.subscribe(status=status_hz)  # as the page does
        messages += 1
    schedstat = open("/proc/thread-self/schedstat").read().split()
    start = time.perf_counter()
    for k in range(count):
        wait_until(start + k / rate, pace)
        t = time.perf_counter()
        plate.touch(20.0 + (k % 100) * 0.5, 50.0, "down" if k == 0 else "move", t=t)
        sent.append((t, time.perf_counter()))  # its time, and when the client's call returned (its frame written)
    ran = [b - a for a, b in zip(map(int, schedstat), map(int, open("/proc/thread-self/schedstat").read().split()))]
    plate.touch(20.0, 50.0, "up")
    plate.state()  # everything sent has arrived
    errors = list(plate.errors)
""" + REPORT

ASYNC_CLIENT = r"""
import asyncio, json, sys, time
from ultraglide.client import AsyncClient
url, count, rate, status_hz, pace = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5]
general = sys.argv[6] == "general"

async def wait_until(due, pace):  # asyncio's timers wake within a millisecond: the last one yields to the loop only
    if pace == "sleep":
        await asyncio.sleep(max(0.0, due - time.perf_counter()))
        return
    while time.perf_counter() < due:
        await asyncio.sleep(0.0002 if due - time.perf_counter() > 0.0015 else 0)

async def main():
    sent = []
    async with await AsyncClient.connect(url) as plate:
        messages = 2  # its hello, and its last request
        if general:
            plate._frame_parts = None  # (--client-general) every touch through json.dumps and websockets' send
        if status_hz:
            await plate.subscribe(status=status_hz)  # as the page does
            messages += 1
        schedstat = open("/proc/thread-self/schedstat").read().split()
        start = time.perf_counter()
        for k in range(count):
            await wait_until(start + k / rate, pace)
            t = time.perf_counter()
            plate.touch(20.0 + (k % 100) * 0.5, 50.0, "down" if k == 0 else "move", t=t)
            sent.append((t, time.perf_counter()))  # its time, and when the call returned (on its way or in a task)
        ran = [b - a for a, b in zip(map(int, schedstat), map(int, open("/proc/thread-self/schedstat").read().split()))]
        plate.touch(20.0, 50.0, "up")
        await plate.state()  # everything sent has arrived
        return sent, ran, start, messages, list(plate.errors)

sent, ran, start, messages, errors = asyncio.run(main())
""" + REPORT

FLOOR_CLIENT = r"""
import json, socket, sys, time
address, count, rate, pace = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
""" + PACE + r"""
if address.startswith("unix:"):
    sock = socket.socket(socket.AF_UNIX)
    sock.connect(address[len("unix:"):])
else:
    sock = socket.create_connection(("127.0.0.1", int(address)))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # as websockets' and asyncio's sockets
sent = []
start = time.perf_counter()
for k in range(count):
    wait_until(start + k / rate, pace)
    t = time.perf_counter()
    message = {"type": "touch", "x": 20.0 + (k % 100) * 0.5, "y": 50.0, "phase": "down" if k == 0 else "move",
               "pointer": 0, "t": t}  # the client's touch, as JSON, a line each
    sock.sendall(json.dumps(message, separators=(",", ":")).encode() + b"\n")
    sent.append((t, time.perf_counter()))
sock.sendall(b'{"type":"end"}\n')
sock.recv(1)  # the server has read everything
print(json.dumps(sent))
"""


class Floor:
    """A bare asyncio protocol on the bench's loop: each line's time (the client's) and when it was read."""

    def __init__(self):
        self.reads: list[tuple[float, float]] = []
        self.ended = None
        self.buffer = b""

    def __call__(self):
        import asyncio

        floor = self

        class Lines(asyncio.Protocol):
            def connection_made(self, transport):
                self.transport = transport

            def data_received(self, data):
                read = time.perf_counter()
                floor.buffer += data
                while b"\n" in floor.buffer:
                    line, floor.buffer = floor.buffer.split(b"\n", 1)
                    message = json.loads(line)
                    if message["type"] == "end":
                        self.transport.write(b"!")
                        floor.ended.set()
                    else:
                        floor.reads.append((message["t"], read))

        return Lines()


async def by_floor(floor: Floor, address: str, count: int, rate: float, pace: str) -> np.ndarray:
    """The floor's touches: each one's time and when it was read by the loop, perf_counter s."""
    floor.reads, floor.buffer, floor.ended = [], b"", asyncio.Event()
    process = await asyncio.create_subprocess_exec(sys.executable, "-c", FLOOR_CLIENT, address, str(count), str(rate),
                                                   pace, stdout=subprocess.PIPE)
    await process.communicate()
    await asyncio.wait_for(floor.ended.wait(), 30)
    return np.asarray(floor.reads).reshape(-1, 2)


def rss_mb() -> tuple[float, float]:
    """This process's resident memory now and at its peak, MB."""
    fields = dict(line.split(":", 1) for line in open("/proc/self/status").read().splitlines() if ":" in line)
    return int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024


def matched(latencies, sent) -> np.ndarray:
    """Each event's latency (s): from its time at the client to its block's presentation, matched by time (each
    event's row is the first whose touch time is at or after it: the service shifts a client's time by the least
    delivery seen, a few tens of µs, and events are 10 ms apart)."""
    touch_t, _, presented = latencies
    order = np.argsort(touch_t)
    touch_t, presented = touch_t[order], presented[order]
    index = np.searchsorted(touch_t, np.asarray(sent) - 1e-9)
    index = index[index < len(touch_t)]
    return presented[index] - np.asarray(sent)[: len(index)]


async def direct(engine, count: int, rate: float) -> list[float]:
    """Touches into the engine from this loop, as play and the demo put them: their times."""
    sent = []
    start = time.perf_counter()
    for k in range(count):
        due = start + k / rate
        await asyncio.sleep(max(0.0, due - time.perf_counter() - 0.0005))
        while time.perf_counter() < due:
            pass
        t = time.perf_counter()
        engine.touch(t, 20.0 + (k % 100) * 0.5, 50.0, down=True)
        sent.append(t)
    engine.touch(time.perf_counter(), 20.0, 50.0, down=False)
    return sent


async def by_client(url: str, count: int, rate: float, status_hz: float = 2.0, pace: str = "spin",
                    path: str = "short", waits: list | None = None, flavour: str = "sync",
                    said: dict | None = None) -> np.ndarray:
    """The client's touches: each one's time and when its call to the client returned, perf_counter s; and how
    long its thread and the loop's waited for a CPU (``waits``: [client's, loop's] ns and runs, appended).
    ``flavour``: ``sync`` (:class:`ultraglide.client.Client`) or ``async`` (:class:`~ultraglide.client.AsyncClient`);
    ``said``: a dict to update with the rest of what the client said (its refusals, messages, lateness)."""
    loop_before = loop_schedstat()
    process = await asyncio.create_subprocess_exec(sys.executable, "-c", CLIENT if flavour == "sync" else ASYNC_CLIENT,
                                                   url, str(count), str(rate), str(status_hz), pace, path,
                                                   stdout=subprocess.PIPE)
    out, _ = await process.communicate()
    loop_after = loop_schedstat()
    result = json.loads(out)
    if result["refused"]:
        print(f"the service refused some of the client's messages (lines received, the last of each kind): "
              f"{result['refused']}")
    if waits is not None:
        waits.append((result["waited_ns"], result["runs"], loop_after[1] - loop_before[1],
                      loop_after[2] - loop_before[2]))
    if said is not None:
        said.update({key: value for key, value in result.items() if key != "sent"})
    return np.asarray(result["sent"]).reshape(-1, 2)


class Rows:
    """``Service.arrivals`` for the soak: its rows in an array made beforehand (its memory is not the service's)."""

    def __init__(self, count: int):
        self.array = np.full((count, 3), np.nan)
        self.count = 0

    def append(self, row) -> None:
        if self.count < len(self.array):
            self.array[self.count] = [np.nan if v is None else v for v in row]
            self.count += 1


async def engine_touches(engine, expected: int, before: int, timeout_s: float = 5.0):
    """The engine's status once it has taken ``expected`` touches since ``before`` (its count), or after
    ``timeout_s``: it drains its ring once a block."""
    deadline = time.monotonic() + timeout_s
    while True:
        status = engine.status(0.0)
        if status.touches - before >= expected or time.monotonic() > deadline:
            return status
        await asyncio.sleep(0.01)


def loop_schedstat() -> list[int]:
    """This thread's (the loop's) time run, time waited for a CPU (ns) and runs, from the kernel's schedstat."""
    return [int(v) for v in open(f"/proc/self/task/{threading.get_native_id()}/schedstat").read().split()]


def waited(waits) -> str:
    """Each side's mean wait for a CPU per run (the kernel's schedstat), µs."""
    client_ns, client_runs, loop_ns, loop_runs = np.sum(np.asarray(waits, dtype=float), axis=0)
    return (f"the client's thread waited {client_ns / max(client_runs, 1) / 1e3:.0f} µs for a CPU per run "
            f"({client_runs:.0f} runs), the service loop's {loop_ns / max(loop_runs, 1) / 1e3:.0f} µs "
            f"({loop_runs:.0f})")


def figures(values_s) -> str:
    values = np.asarray(values_s) * 1e3
    return f"p50 {np.percentile(values, 50):.3f} ms, p99 {np.percentile(values, 99):.3f} ms (n={len(values)})"


async def measure(args) -> None:
    import tempfile

    from ultraglide.apps.commands.serve import _loop_in_real_time
    from ultraglide.apps.service.server import short_path_connection
    from websockets.asyncio.server import serve, unix_serve

    engine, service = args.engine, args.service
    service.priority = _loop_in_real_time(service) if args.loop_slice_ms is None else \
        _loop_in_real_time(service, args.loop_slice_ms / 1e3)  # as serve's loop: its thread's scheduling
    print(f"the service's loop: {service.priority}, switch interval {sys.getswitchinterval() * 1e3:g} ms; status "
          f"subscribed at {args.status_hz:g} Hz; {'a Unix socket' if args.unix else 'TCP on loopback'}; clients "
          f"pace by {args.pace}; the service's {'short path' if args.short_path else 'websockets queue'}; the "
          f"client's {args.client_path} path")
    loop = asyncio.get_running_loop()
    stop = threading.Event()
    publisher = threading.Thread(target=service.publish, args=(loop, stop), name="ultraglide-publisher", daemon=True)
    publisher.start()  # as serve's
    folder = tempfile.TemporaryDirectory()
    floor = Floor()
    options = {"compression": None}  # as serve's connections (its short path; --no-short-path: websockets' own)
    if args.short_path:
        options["create_connection"] = short_path_connection()
    if args.unix:
        server = await unix_serve(service.handle, f"{folder.name}/service.sock", **options)
        url = f"ws+unix:{folder.name}/service.sock"
        floor_server = await loop.create_unix_server(floor, f"{folder.name}/floor.sock")
        floor_address = f"unix:{folder.name}/floor.sock"
    else:
        server = await serve(service.handle, "127.0.0.1", 0, origins=[None], **options)
        url = f"ws://127.0.0.1:{server.sockets[0].getsockname()[1]}/ws"
        floor_server = await loop.create_server(floor, "127.0.0.1", 0)
        floor_address = str(floor_server.sockets[0].getsockname()[1])
    async with server, floor_server:
        await asyncio.sleep(0.5)
        own, through, arrivals, returned, floors, waits = [], [], [], [], [], []
        for _ in range(args.rounds):
            sent = await direct(engine, args.touches, 100.0)
            await asyncio.sleep(0.05)
            own.append(matched(engine.latencies(), sent))
            service.arrivals = []
            sent = await by_client(url, args.touches, 100.0, args.status_hz, args.pace, args.client_path, waits,
                                   args.client)
            await asyncio.sleep(0.05)
            through.append(matched(engine.latencies(), sent[:, 0]))
            rows = np.asarray([row for row in service.arrivals if row[0] is not None])
            service.arrivals = None
            arrivals.append(rows)
            returned.append(sent[np.clip(np.searchsorted(sent[:, 0], rows[:, 0] - 1e-9), 0, len(sent) - 1), 1])
            floors.append(await by_floor(floor, floor_address, args.touches, 100.0, args.pace))
        own, through, floors = np.concatenate(own), np.concatenate(through), np.concatenate(floors)
        arrivals, returned = np.concatenate(arrivals), np.concatenate(returned)
        print(f"the floor (a bare socket in another process to a bare asyncio protocol on this loop), from the "
              f"client's send to the loop's read {figures(floors[:, 1] - floors[:, 0])}")
        print(f"through the service, from the client's send to the message read by the service's loop "
              f"{figures(arrivals[:, 1] - arrivals[:, 0])} (of it, the client's call, its encoding and its socket "
              f"write: {figures(returned - arrivals[:, 0])}); from read to the engine's ring "
              f"{figures(arrivals[:, 2] - arrivals[:, 1])}; {waited(waits)}")
        print(f"latency, touch to its block presented (sim): engine alone {figures(own)}; "
              f"through the service {figures(through)}")
        added = np.percentile(through, 99) - np.percentile(own, 99)
        print(f"the service adds {added * 1e3:.3f} ms at p99 ({(np.median(through) - np.median(own)) * 1e3:.3f} ms "
              f"at p50); aim: at most 1 ms at p99")
        if args.soak_s > 0:
            count = int(args.soak_s * 1000)
            before = engine.status(0.0)
            await direct(engine, count, 1000.0)
            middle = await engine_touches(engine, count + 1, before.touches)
            rows = Rows(count + 10)
            service.arrivals = rows
            read_before, refused_before = counters(service)
            counted_before, ignored_before = service.touches, service.touches_ignored
            rss_before, _ = rss_mb()
            said = {}
            loop_before = loop_schedstat()
            sent = await by_client(url, count, 1000.0, args.status_hz, args.pace, args.client_path,
                                   flavour=args.client, said=said)
            loop_after = loop_schedstat()
            counted = service.touches - counted_before
            after = await engine_touches(engine, counted, middle.touches)
            rss_after, peak = rss_mb()
            service.arrivals = None
            print(f"soak, 1000 events/s for {args.soak_s:g} s: late blocks {middle.late_blocks - before.late_blocks} "
                  f"(engine alone), {after.late_blocks - middle.late_blocks} (through the service); device underruns "
                  f"{after.underruns - before.underruns}; this process's memory {rss_before:.0f} MB before the "
                  f"service's soak, {rss_after:.0f} MB after (peak {peak:.0f} MB); the service loop's thread ran "
                  f"{(loop_after[0] - loop_before[0]) / 1e9:.2f} s and waited "
                  f"{(loop_after[1] - loop_before[1]) / 1e9:.2f} s for a CPU")
            read_after, refused_after = counters(service)
            print(soak_account(len(sent) + 1, said, read_after - read_before, refused_after - refused_before, counted,
                               service.touches_ignored - ignored_before, after.touches - middle.touches,
                               after.touches_dropped - middle.touches_dropped, rows))
    stop.set()
    publisher.join(10)
    folder.cleanup()


def counters(service) -> tuple[float, float]:
    """The service's messages read and refused over the rate so far; NaN for a service without the counts (the
    code before them, for a before/after)."""
    return getattr(service, "messages_read", np.nan), getattr(service, "rate_refusals", np.nan)


def soak_account(touches: int, said: dict, read: int, rate_refused: int, counted: int, ignored: int, reached: int,
                 dropped: int, rows: Rows) -> str:
    """Where every touch of the soak went, in words: sent by the client (and how late it sent them), read by the
    service (the rest lost on the socket), refused over the rate (and the lines the client received saying so), taken
    but not rendered (a pointer that does not drive), put into the engine's ring: taken by the engine or dropped by
    its ring; and what is left unaccounted for (nothing on this path merges events: none should be); how late the
    service read the touches it took, after the client's time."""
    lost = said["messages"] - read  # of every message it sent: its touches, and its hello, subscription, last request
    lines, _ = said["refused"].get("rate", (0, ""))
    unaccounted = touches - lost - rate_refused - ignored - reached - dropped
    if np.isnan(read):  # a service without the counts: what is not otherwise accounted for was lost or refused
        lost = rate_refused = "?"
        unaccounted = f"{touches - ignored - reached - dropped} lost or refused (this service does not count them), 0"
    arrivals = rows.array[:rows.count]
    delay = (arrivals[:, 1] - arrivals[:, 0]) * 1e3
    delay = delay[np.isfinite(delay)]
    return (f"where the soak's {touches} touches went: the client sent {said['late_over_10ms']} of them more than "
            f"10 ms after their time (the latest by {said['late_max_s'] * 1e3:.1f} ms); {lost} messages lost on the "
            f"socket (of {said['messages']} sent); {rate_refused} refused over the rate ({lines} error lines at the "
            f"client); {ignored} taken and not rendered; {counted} into the engine's ring: {reached} reached the "
            f"engine, {dropped} dropped by its ring; {unaccounted} unaccounted for. The service read those it took "
            f"{np.percentile(delay, 50):.2f} ms after the client's time at p50, {np.percentile(delay, 99):.2f} ms at "
            f"p99, {delay.max():.0f} ms at most")


def browser_send_times(count: int = 200) -> None:
    import shutil
    import tempfile

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service as Driver

    serve = subprocess.Popen([sys.executable, "-m", "ultraglide", "serve", "grating-1mm", "--port", "0", "--page",
                              "--json"], stdout=subprocess.PIPE, text=True)
    try:
        address = json.loads(serve.stdout.readline())
        with tempfile.TemporaryDirectory() as profile:
            options = webdriver.ChromeOptions()
            options.binary_location = shutil.which("chromium")
            for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                         "--disable-background-networking", "--disable-component-update", "--disable-sync",
                         "--window-size=800,600", f"--user-data-dir={profile}"):
                options.add_argument(flag)
            driver = webdriver.Chrome(service=Driver(shutil.which("chromedriver")), options=options)
            try:
                driver.get(address["page"])
                deadline = time.monotonic() + 60
                while not driver.execute_script("return window.ultraglide && window.ultraglide.ready"):
                    if time.monotonic() > deadline:
                        raise SystemExit("the page did not get ready")
                    time.sleep(0.05)
                for k in range(count):
                    kind = "touchStart" if k == 0 else "touchMove"
                    driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": kind, "touchPoints": [
                        {"x": 100 + k, "y": 300, "radiusX": 5, "radiusY": 5, "force": 0.5, "id": 1}]})
                driver.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
                times = driver.execute_script("return window.ultraglide.sendTimes()")
            finally:
                driver.quit()
    finally:
        serve.terminate()
        serve.wait(60)
    values = np.asarray(times)
    print(f"browser (headless Chromium), pointer event's time stamp to its message sent: p50 "
          f"{np.percentile(values, 50):.3f} ms, p99 {np.percentile(values, 99):.3f} ms (n={len(values)}; "
          f"synthesized by the DevTools protocol, so it includes their dispatch)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--touches", type=int, default=300, help="touches per round and way (default: 300)")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--soak-s", type=float, default=60.0, help="the soak's length (0: none; default: 60)")
    parser.add_argument("--browser", action="store_true", help="also time the page in headless Chromium")
    parser.add_argument("--no-subscribe", dest="status_hz", action="store_const", const=0.0, default=2.0,
                        help="the client subscribes to nothing (default: the status at 2 Hz, as the page)")
    parser.add_argument("--unix", action="store_true", help="through a Unix socket (serve --unix), not TCP")
    parser.add_argument("--loop-slice-ms", type=float, default=None, metavar="MS",
                        help="the service loop thread's time slice, ms (default: serve's; 0: the kernel's)")
    parser.add_argument("--no-short-path", dest="short_path", action="store_false",
                        help="messages through websockets' queue and the handler's task, not serve's short path")
    parser.add_argument("--client-general", dest="client_path", action="store_const", const="general",
                        default="short", help="the client's touches through its general path (json.dumps and "
                                              "websockets' send), not its short one")
    parser.add_argument("--client", choices=("sync", "async"), default="sync",
                        help="the client: ultraglide.client.Client (the default) or AsyncClient")
    parser.add_argument("--pace", choices=("spin", "sleep"), default="spin",
                        help="how the clients wait for each touch's time (default: spin, short sleeps then a busy "
                             "wait; sleep: one sleep, as a program its input wakes)")
    args = parser.parse_args()
    from ultraglide.apps.service.server import Service
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.engine import Engine, EngineConfig

    profile = load_profile("sim-plate")
    service = Service(None, profile)
    args.engine = Engine.start(EngineConfig(texture=service.first_texture(), device="sim"))  # forked, as serve's
    service.engine = args.engine
    try:
        args.engine.wait_ready()
        args.service = service
        asyncio.run(measure(args))
    finally:
        service.worker.shutdown()
        args.engine.stop()
    print(f"load average {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    if args.browser:
        browser_send_times()


if __name__ == "__main__":
    main()
