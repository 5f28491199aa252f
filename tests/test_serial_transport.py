"""The serial transport's writes, on real pseudo-terminals: a frame the kernel takes whole returns without polling
the port (pyserial's ``write`` polls after every write, and on a tty that poll waits for the flip-buffer's kworker);
a port with no room is waited on for room, up to the write timeout, and then fails as pyserial's write fails, with
what the kernel took intact; a URL transport keeps pyserial's write; a far end that went away fails as before."""

import os
import pty
import select
import threading
import time

import numpy as np
import pytest
import serial
from conftest import wait_for
from ultraglide.devices import protocol as p
from ultraglide.devices.serial.link import FrameWriter, SerialCounters, open_port, port_failure
from ultraglide.devices.serial.locks import DriverLocks
from ultraglide.devices.serial.transport import Transport

FRAME = p.encode_frame(p.HEARTBEAT, 7)
FULL = np.full(p.MAX_SETPOINTS_PER_FRAME, 0.5)  # a SETPOINTS frame of the most values: about 500 bytes
BIG = p.encode_frame(p.SETPOINTS, 7, p.setpoints_payload(0, 1000, FULL))


@pytest.fixture
def pty_pair():
    """A pseudo-terminal: (the far end's fd, the port's path); the far end closed after (if still open)."""
    far, near = pty.openpty()
    path = os.ttyname(near)
    ends = {"far": far}
    yield ends, path
    for fd in (ends["far"], near):
        if fd is not None:
            os.close(fd)


def drain(far: int, until, timeout_s: float = 60.0) -> bytes:
    """What arrives on the far end, read until ``until(data)`` holds (or the deadline: a loaded machine)."""
    data = bytearray()
    deadline = time.monotonic() + timeout_s
    while not until(data) and time.monotonic() < deadline:
        if select.select([far], [], [], 0.05)[0]:
            data += os.read(far, 65536)
    return bytes(data)


def heard(far: int, count: int) -> list:
    """The frames the far end decodes until ``count`` of them have come."""
    data = drain(far, lambda data: data.count(b"\x00") >= count)
    return p.FrameDecoder().feed(data)


def until_timed_out(write) -> tuple[int, BaseException, float]:
    """``write(BIG)`` again and again, the far end reading nothing, until one fails: how many went whole, the
    failure, and how long the failing write took (s). The flip-buffer's kworker frees room a while after the first
    EAGAIN, so no single write is known to be the one that finds the port full."""
    whole = 0
    while True:
        started = time.monotonic()
        try:
            write(BIG)
        except serial.SerialException as error:
            return whole, error, time.monotonic() - started
        whole += 1


def waiting_in_poll(thread_id: int) -> bool:
    """The thread sleeps in the kernel's poll, as its wait channel says."""
    with open(f"/proc/self/task/{thread_id}/wchan") as wchan:
        return "poll" in wchan.read()


class Counted:
    """The select module's ``select`` and ``poll`` as they are, each call counted by the thread that made it."""

    def __init__(self, monkeypatch):
        self.by_thread: dict[int, int] = {}
        real_select, real_poll = select.select, select.poll
        count = self._count

        def counting_select(*args):
            count()
            return real_select(*args)

        class CountingPoll:
            def __init__(self):
                self._poll = real_poll()

            def register(self, *args):
                self._poll.register(*args)

            def poll(self, *args):
                count()
                return self._poll.poll(*args)

        monkeypatch.setattr(select, "select", counting_select)
        monkeypatch.setattr(select, "poll", CountingPoll)

    def _count(self) -> None:
        me = threading.get_ident()
        self.by_thread[me] = self.by_thread.get(me, 0) + 1

    def here(self) -> int:
        """Calls this thread made."""
        return self.by_thread.get(threading.get_ident(), 0)


def transport_on(path: str, write_timeout_s: float, received: list | None = None) -> Transport:
    """A transport opened on ``path`` (its reader thread started), frames it receives appended to ``received``."""
    transport = Transport(path, 921600, write_timeout_s, 1000, DriverLocks(), SerialCounters(),
                          on_frame=(received if received is not None else []).append,
                          on_bad_frames=lambda *counts: None, on_lost=lambda cause: None)
    transport.open()
    return transport


def test_a_frame_the_kernel_takes_whole_returns_without_polling_the_port(pty_pair, monkeypatch):
    ends, path = pty_pair
    counted = Counted(monkeypatch)
    port = open_port(path, 921600, write_timeout_s=0.5)
    try:
        writer = FrameWriter(port, 0.5)
        assert writer.direct
        for _ in range(50):  # 50 frames of 11 bytes: room for all of them, unread
            writer.write(FRAME)
        ours = counted.here()
        for _ in range(50):  # the control: pyserial's own write on the same port waits on it after each write
            port.write(FRAME)
        pyserials = counted.here() - ours
    finally:
        port.close()
    assert ours == 0
    assert pyserials == 50
    assert drain(ends["far"], lambda data: len(data) >= 100 * len(FRAME)) == 100 * FRAME


def test_the_transport_sends_frames_whole_in_order_and_its_writer_never_polls(pty_pair, monkeypatch):
    ends, path = pty_pair
    counted = Counted(monkeypatch)
    transport = transport_on(path, 0.5)
    try:
        seqs = [transport.send(p.HEARTBEAT) for _ in range(20)]
        setpoints_seq = transport.send(p.SETPOINTS, setpoints=np.array([0.0, 0.25, 0.5, 1.0]))
        writer_waits = counted.here()  # this thread was the writer; the reader thread's own selects are its own
        assert transport.index == 4
    finally:
        transport.close()
    assert writer_waits == 0
    assert transport.waited_s == 0.0  # no write waited for room: none of the writer's time was the link's
    frames = heard(ends["far"], 21)
    assert [(frame.kind, frame.seq) for frame in frames[:20]] == [(p.HEARTBEAT, seq) for seq in seqs]
    assert (frames[20].kind, frames[20].seq) == (p.SETPOINTS, setpoints_seq)
    first, rate, values = p.parse_setpoints(frames[20].payload)
    assert (first, rate) == (0, 1000)
    np.testing.assert_allclose(values, [0.0, 0.25, 0.5, 1.0], atol=0.5 / p.SETPOINT_SCALE)


def test_a_port_without_room_is_waited_on_and_the_frame_goes_whole_once_the_far_end_reads(pty_pair):
    ends, path = pty_pair
    transport = transport_on(path, 60.0)
    seqs, stop, outcome = [], threading.Event(), {}

    def send():  # frames until the port has no room and the writer waits in the kernel's poll
        outcome["thread"] = threading.get_native_id()
        try:
            while not stop.is_set():
                seqs.append(transport.send(p.HEARTBEAT))
        except BaseException as error:  # noqa: BLE001 - the test says what it was
            outcome["error"] = error

    writer = threading.Thread(target=send)
    try:
        writer.start()
        assert wait_for(lambda: "thread" in outcome and waiting_in_poll(outcome["thread"]), 60)  # it waits for room
        stop.set()
        waited_with = len(seqs)  # the frame it waits with is not yet sent ...
        assert waiting_in_poll(outcome["thread"])  # ... as it still waits, stopped or not
        data = drain(ends["far"], lambda data: not writer.is_alive() and data.count(b"\x00") >= len(seqs))
        writer.join(60)
    finally:
        transport.close()
    assert not writer.is_alive()
    assert "error" not in outcome, outcome.get("error")
    assert len(seqs) == waited_with + 1  # the frame that waited went, then the writer stopped
    assert len(data) > 4096  # the far end read nothing while the writer filled the kernel's buffers
    frames = p.FrameDecoder().feed(data)  # every frame whole and in order, the one that waited among them
    assert [(frame.kind, frame.seq) for frame in frames] == [(p.HEARTBEAT, seq) for seq in seqs]


def test_a_port_that_never_has_room_times_out_as_pyserials_write_does(pty_pair):
    ends, path = pty_pair
    port = open_port(path, 921600, write_timeout_s=0.3)
    try:
        _, pyserials, _ = until_timed_out(port.write)  # the control: pyserial's own write on the full port
        writer = FrameWriter(port, 0.3)
        began = time.monotonic()
        _, ours, waited_s = until_timed_out(writer.write)
        writing_s = time.monotonic() - began
    finally:
        port.close()
    assert type(ours) is type(pyserials) is serial.SerialTimeoutException
    assert str(ours) == str(pyserials) == "Write timeout"
    assert port_failure(ours) == "the port stopped taking data (a write timed out)"
    assert 0.3 <= waited_s < 10.0  # it waited its timeout for room, and no longer than a loaded machine needs
    # and it counts that wait as the link's (the plate driver's writer does not take it for a host's stall): at
    # least the failing write's, at most all its writes took
    assert 0.3 <= writer.waited_s <= writing_s, (writer.waited_s, waited_s, writing_s)


def test_the_transports_write_timeout_fails_its_send_and_what_went_before_arrives_whole(pty_pair):
    ends, path = pty_pair
    transport = transport_on(path, 0.3)
    seqs = []
    try:
        whole, error, waited_s = until_timed_out(lambda frame: seqs.append(transport.send(p.SETPOINTS, setpoints=FULL)))
        assert transport.counters.frames_sent == whole == len(seqs)  # the frame that timed out is not counted
    finally:
        transport.close()
    assert isinstance(error, serial.SerialTimeoutException) and 0.3 <= waited_s < 10.0
    # the streamer and the session name a write's failure by port_failure: the words the run's report gives
    assert port_failure(error) == "the port stopped taking data (a write timed out)"
    frames = heard(ends["far"], len(seqs))  # what the kernel took: the frames that went, whole, in order
    assert [frame.seq for frame in frames] == seqs


def test_a_far_end_that_went_away_fails_the_write_as_pyserials_write_does(pty_pair):
    ends, path = pty_pair
    port = open_port(path, 921600, write_timeout_s=0.5)
    try:
        os.close(ends["far"])  # the device closed its side (a plate-sim that exited)
        ends["far"] = None
        with pytest.raises(serial.SerialException) as pyserials:
            port.write(FRAME)
        with pytest.raises(serial.SerialException) as ours:
            FrameWriter(port, 0.5).write(FRAME)
    finally:
        port.close()
    assert type(ours.value) is type(pyserials.value)
    assert str(ours.value) == str(pyserials.value)
    assert port_failure(ours.value) == "the port went away (the device closed it or was unplugged)"


def test_a_closed_port_is_refused_as_pyserial_refuses_it(pty_pair):
    ends, path = pty_pair
    port = open_port(path, 921600, write_timeout_s=0.5)
    writer = FrameWriter(port, 0.5)
    port.close()
    with pytest.raises(serial.PortNotOpenError):
        writer.write(FRAME)
    with pytest.raises(serial.PortNotOpenError):
        port.write(FRAME)


def test_a_url_port_keeps_pyserials_write():
    received = []
    transport = transport_on("loop://", 0.5, received)
    try:
        assert not transport.writer.direct
        seq = transport.send(p.HEARTBEAT)
        assert wait_for(lambda: received)  # loop:// hands what was written back to the reader
    finally:
        transport.close()
    assert [(frame.kind, frame.seq) for frame in received] == [(p.HEARTBEAT, seq)]
