"""``serve``'s loop: its thread's scheduling (nice -10 and a short time slice, as the kernel reports them) and its
short path (a message handled as websockets reads it) keeping every message's order and answer."""

import json
import os
import platform
import threading
import time

import pytest
from service_run import running_service, stop


def _sched(pid: int) -> dict:
    """The kernel's scheduling figures of thread ``pid`` (/proc/PID/task/PID/sched), by name."""
    fields = {}
    for line in open(f"/proc/{pid}/task/{pid}/sched").read().splitlines()[2:]:
        name, colon, value = line.partition(":")
        if colon:
            fields[name.strip()] = value.strip()
    return fields


def _may_raise_nice() -> bool:
    """Whether this machine lets a thread take nice -10 (a throwaway thread tries)."""
    allowed = []

    def attempt():
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), -10)
            allowed.append(True)
        except OSError:
            allowed.append(False)

    thread = threading.Thread(target=attempt)
    thread.start()
    thread.join()
    return allowed[0]


def _custom_slices() -> bool:
    """Linux 6.12 and later: an ordinary thread's own time slice (sched_setattr's runtime)."""
    release = platform.release().split("-")[0].split(".")
    return platform.system() == "Linux" and tuple(int(part) for part in release[:2]) >= (6, 12)


@pytest.mark.skipif(not _may_raise_nice(), reason="this machine does not let a thread take nice -10")
def test_the_loop_thread_runs_at_nice_minus_10_and_with_a_0_1_ms_slice_where_the_kernel_has_them():
    expected = {"prio": "110", **({"se.slice": "100000"} if _custom_slices() else {})}  # 120 + nice; ns

    def settled(sched):
        return all(sched.get(key) == value for key, value in expected.items())
    with running_service("--device", "null", "--port", "0") as (process, _):
        deadline = time.monotonic() + 60.0  # the loop takes its nice, then its slice: both waited for
        while not settled(_sched(process.pid)) and time.monotonic() < deadline:
            time.sleep(0.05)
        sched = _sched(process.pid)
    assert sched["prio"] == "110" and sched["policy"] == "0"  # nice -10, SCHED_OTHER (not real time)
    if _custom_slices():
        assert sched["se.slice"] == "100000"  # ns
    elif "se.slice" in sched:
        assert int(sched["se.slice"]) > 100000  # the kernel's own: it has no custom slices


def test_messages_sent_back_to_back_at_connection_are_each_answered_in_order_and_every_touch_reaches_the_engine():
    """Sent without waiting from the handshake on: the first are queued before the connection's handler runs (they
    take websockets' path), the rest are read with nothing queued (the short path); none overtakes another."""
    from websockets.sync.client import connect

    with running_service("--device", "null", "--port", "0") as (process, address):
        with connect(address["url"], compression=None, proxy=None) as ws:
            ws.send(json.dumps({"type": "hello", "id": 0, "protocol": 1, "role": "control"}))
            touches, requests = 0, []
            for k in range(1, 400):
                if k % 4 == 0:
                    requests.append(k)
                    kind = ("state", "touches.set", "subscribe")[k % 3]
                    fields = {"touches.set": {"drives": "first"}, "subscribe": {"status": False}}.get(kind, {})
                    ws.send(json.dumps({"type": kind, "id": k, **fields}))
                else:
                    ws.send(json.dumps({"type": "touch", "x": 10.0 + k * 0.1, "y": 20.0,
                                        "phase": "down" if touches == 0 else "move", "t": time.perf_counter()}))
                    touches += 1
            ws.send(json.dumps({"type": "touch", "x": 10.0, "y": 20.0, "phase": "up"}))
            touches += 1
            answered = []
            while len(answered) < len(requests) + 1:
                reply = json.loads(ws.recv(timeout=60))
                assert reply["type"] == "ok", reply
                answered.append(reply["id"])
        assert answered == [0, *requests]
        status = stop(process)
        summary = json.loads(process.stdout.read())
    assert status != 0  # stopped by SIGTERM
    assert summary["touches"] == touches and summary["touches_ignored"] == 0


def test_a_message_that_is_not_utf_8_closes_its_connection_and_the_service_goes_on(tmp_path):
    """A text frame that is not UTF-8 is refused by websockets as before the short path (close 1007); the next
    client is served."""
    from websockets.exceptions import ConnectionClosedError
    from websockets.sync.client import connect

    from ultraglide.client import Client

    with running_service("--device", "null", "--port", "0") as (process, address):
        with connect(address["url"], compression=None, proxy=None) as ws:
            ws.send(json.dumps({"type": "hello", "id": 1, "protocol": 1}))
            assert json.loads(ws.recv(timeout=60))["type"] == "ok"
            ws.send(b"\xff\xfe not text", text=True)
            with pytest.raises(ConnectionClosedError):
                ws.recv(timeout=60)
            assert ws.close_code == 1007
        with Client(address["url"]) as plate:
            assert plate.state()["scene_version"] == 0
        assert process.poll() is None

