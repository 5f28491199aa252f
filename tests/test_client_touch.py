"""The clients' short path for a touch (``Client.touch``, ``AsyncClient.touch``): its JSON is what the general
encoder writes, character for character, and its frames are WebSocket frames a real websockets server reads as the
messages sent, in order, with the general path's refusals and failures; the asyncio client's touch is on its way
when its call returns."""

import asyncio
import json
import math
import threading
import time

import numpy as np
import pytest

from ultraglide.client import AsyncClient, BadMessage, Client, ConnectionFailed, touch_text

NUMBERS = [0.0, -0.0, 1.0, -1.5, 20.5, 0.1 + 0.2, 1e-7, 1.5e-5, 123456789.125, 1e16, 1.7976931348623157e308,
           5e-324, 2.2250738585072014e-308, 3, 0, -7, 2**53 + 1, 10**30]


def general(x, y, phase, pointer, t, pressure=None, force_n=None) -> str:
    """The general path's text: the fields in its order, Nones left out, ``json.dumps`` as the client calls it."""
    fields = {"type": "touch", "x": x, "y": y, "phase": phase, "pointer": pointer, "pressure": pressure,
              "force_n": force_n, "t": t}
    return json.dumps({k: v for k, v in fields.items() if v is not None}, separators=(",", ":"), allow_nan=False)


def test_the_short_text_is_the_general_encoder_s_character_for_character():
    rng = np.random.default_rng(41)
    randoms = [float(v) for v in rng.normal(0, 1e3, 200)] + [float(v) for v in 10.0 ** rng.uniform(-300, 300, 200)]
    for k, x in enumerate(NUMBERS + randoms):
        y = NUMBERS[k % len(NUMBERS)]
        phase = ("down", "move", "up", "cancel")[k % 4]
        extra = [{}, {"pressure": 0.5}, {"force_n": 0.25}, {"pressure": 1, "force_n": 2.0}][k % 4]
        text = touch_text(x, y, phase, k % 11, 1234.5 + k, **extra)
        assert text == general(x, y, phase, k % 11, 1234.5 + k, **extra)
        back = json.loads(text)
        assert back["x"] == x and math.copysign(1, back["x"]) == math.copysign(1, x) and back["y"] == y


@pytest.mark.parametrize("fields", [
    {"x": math.nan}, {"y": math.inf}, {"t": -math.inf}, {"pressure": math.nan},  # JSON has no such numbers
    {"x": True}, {"pointer": False}, {"x": np.float64(1.5)}, {"pointer": np.int64(2)}, {"x": "1"},  # not plain
    {"phase": "hover"}, {"phase": None},  # not a phase: the general path sends it and the service says so
])
def test_anything_but_plain_finite_numbers_and_known_phases_is_left_to_the_general_path(fields):
    call = {"x": 1.0, "y": 2.0, "phase": "move", "pointer": 0, "t": 3.0, **fields}
    assert touch_text(call.pop("x"), call.pop("y"), call.pop("phase"), call.pop("pointer"), call.pop("t"),
                      **call) is None


class Recorder:
    """A real websockets server (on loopback, in a thread of its own) that answers every request ``ok`` and keeps
    every text it receives, in order, and how each connection ended."""

    def __init__(self):
        self.texts: list[str] = []
        self.closes: list = []
        self.ready = threading.Event()
        self.stop = threading.Event()
        self.release = threading.Event()  # a connection that read a "hold" reads nothing more until this is set
        self.thread = threading.Thread(target=asyncio.run, args=(self._serve(),), daemon=True)

    async def _serve(self):
        from websockets.asyncio.server import serve

        async def handler(connection):
            try:
                async for text in connection:
                    self.texts.append(text)
                    message = json.loads(text)
                    if message.get("type") == "goodbye":
                        await connection.close(1000, "goodbye")
                        return
                    if message.get("type") == "hold":
                        await asyncio.to_thread(self.release.wait, 60.0)
                    if "id" in message:
                        await connection.send(json.dumps({"type": "ok", "id": message["id"], "role": "control"}))
            finally:
                self.closes.append((connection.close_code, connection.close_reason))

        async with serve(handler, "127.0.0.1", 0, compression=None) as server:
            self.url = f"ws://127.0.0.1:{server.sockets[0].getsockname()[1]}/ws"
            self.ready.set()
            await asyncio.to_thread(self.stop.wait)

    def __enter__(self):
        self.thread.start()
        assert self.ready.wait(30), "the server did not start"
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.release.set()
        self.thread.join(30)

    def wait_for(self, count: int, timeout_s: float = 30.0) -> list[dict]:
        deadline = time.monotonic() + timeout_s
        while len(self.texts) < count and time.monotonic() < deadline:
            time.sleep(0.005)
        return [json.loads(text) for text in self.texts]


def test_short_and_general_touches_reach_a_websockets_server_as_sent_and_in_order():
    with Recorder() as server:
        with Client(server.url) as plate:
            assert plate._frame_parts is not None, "this websockets has what the short path needs"
            sent = []
            for k in range(300):
                x, y = 0.5 * k + 0.1, 100.0 - k / 3
                if k % 3 == 2:  # a view or a pointer type: the general path
                    plate.touch(x, y, "move", pointer=k % 4, t=float(k), view="main", pointer_type="pen")
                    sent.append({"type": "touch", "x": x, "y": y, "phase": "move", "pointer": k % 4, "view": "main",
                                 "t": float(k), "pointer_type": "pen"})
                else:
                    plate.touch(x, y, "down" if k == 0 else "move", pointer=k % 4, t=float(k), pressure=0.25)
                    sent.append({"type": "touch", "x": x, "y": y, "phase": "down" if k == 0 else "move",
                                 "pointer": k % 4, "pressure": 0.25, "t": float(k)})
            plate.state()  # answered: the server has read everything before it
        received = server.wait_for(len(sent) + 2)
    assert [m["type"] for m in received[:1]] == ["hello"]
    assert received[1:len(sent) + 1] == sent  # every one, in order, as sent
    assert received[len(sent) + 1]["type"] == "state"
    # the server read every frame as valid (a client's frame unmasked or malformed closes it with 1002 or 1007)
    assert server.closes and server.closes[0][0] == 1000, server.closes


def test_a_touch_that_is_not_finite_is_refused_and_nothing_of_it_is_sent():
    with Recorder() as server:
        with Client(server.url) as plate:
            with pytest.raises(BadMessage, match="finite"):
                plate.touch(math.nan, 1.0)
            plate.touch(1.0, 2.0, t=5.0)
            plate.state()
        received = server.wait_for(3)
    assert [m["type"] for m in received] == ["hello", "touch", "state"] and received[1]["x"] == 1.0


def test_touches_after_the_service_closed_the_connection_raise_connection_failed():
    with Recorder() as server:
        plate = Client(server.url)
        plate.touch(1.0, 2.0, "down")
        plate._post("goodbye")  # the server closes the connection when it reads this
        deadline = time.monotonic() + 30.0
        with pytest.raises(ConnectionFailed, match="lost"):
            while time.monotonic() < deadline:
                plate.touch(1.0, 2.0, "move")
                time.sleep(0.005)
        plate.close()
        received = server.wait_for(3)
    assert [m["type"] for m in received[:3]] == ["hello", "touch", "goodbye"]


def test_async_short_and_general_touches_reach_a_websockets_server_as_sent_and_in_order():
    async def swipe(url):
        async with await AsyncClient.connect(url) as plate:
            assert plate._frame_parts is not None, "this websockets has what the async short path needs"
            sent = []
            for k in range(300):
                x, y = 0.5 * k + 0.1, 100.0 - k / 3
                if k % 7 == 3:  # a view or a pointer type: the general path (a task), and the touches behind it
                    plate.touch(x, y, "move", pointer=k % 4, t=float(k), view="main", pointer_type="pen")
                    sent.append({"type": "touch", "x": x, "y": y, "phase": "move", "pointer": k % 4, "view": "main",
                                 "t": float(k), "pointer_type": "pen"})
                else:
                    plate.touch(x, y, "down" if k == 0 else "move", pointer=k % 4, t=float(k), pressure=0.25)
                    sent.append({"type": "touch", "x": x, "y": y, "phase": "down" if k == 0 else "move",
                                 "pointer": k % 4, "pressure": 0.25, "t": float(k)})
                if k % 5 == 0:
                    await asyncio.sleep(0)  # the loop turns: the general path's tasks run, the short path resumes
            await plate.state()  # answered: the server has read everything before it
            return sent

    with Recorder() as server:
        sent = asyncio.run(swipe(server.url))
        received = server.wait_for(len(sent) + 2)
    assert [m["type"] for m in received[:1]] == ["hello"]
    assert received[1:len(sent) + 1] == sent  # every one, in order, as sent
    assert received[len(sent) + 1]["type"] == "state"
    assert server.closes and server.closes[0][0] == 1000, server.closes  # every frame read as valid


def test_an_async_short_touch_is_on_its_way_when_the_call_returns_and_one_behind_a_general_one_comes_after_it():
    """The program's loop held (a blocking wait inside it): a usual touch still reaches the server (written by the
    call); one with a view (a task, once the loop turns), and a usual one made just after it, arrive in order."""
    async def touches(server):
        async with await AsyncClient.connect(server.url) as plate:
            plate.touch(1.0, 2.0, "down", t=1.0)
            arrived_while_held = len(server.wait_for(2, timeout_s=30.0))  # (blocks this loop: nothing of it runs)
            plate.touch(3.0, 4.0, "move", t=2.0, view="main")
            plate.touch(5.0, 6.0, "move", t=3.0)  # behind a touch not yet written: after it, by the same path
            await plate.state()
            return arrived_while_held

    with Recorder() as server:
        arrived_while_held = asyncio.run(touches(server))
        received = server.wait_for(5)
    assert arrived_while_held == 2
    assert [(m["type"], m.get("x")) for m in received] == [("hello", None), ("touch", 1.0), ("touch", 3.0),
                                                           ("touch", 5.0), ("state", None)]
    assert received[2]["view"] == "main" and "view" not in received[3]


def test_async_touches_whose_writes_are_held_back_go_by_the_general_path_and_all_arrive_in_order():
    """A server that stops reading: the kernel's socket buffers fill, then the transport's own, and websockets holds
    the connection's writes back (flow control). Touches made then are not written into the transport (its buffer
    would grow without bound) but sent by the general path's tasks, in order, once the server reads again."""
    async def touches(server):
        async with await AsyncClient.connect(server.url) as plate:
            await plate._send({"type": "hold"})  # the server reads this, then nothing until released
            ws, sent, k = plate._ws, [], 0
            deadline = time.monotonic() + 60.0
            while not ws.paused and time.monotonic() < deadline:  # short-path touches until the writes are held
                plate.touch(float(k), 1.0, "down" if k == 0 else "move", t=float(k))
                sent.append(k)
                k += 1
                if k % 500 == 0:
                    await asyncio.sleep(0)  # the loop turns: the transport tries to write, and says it is full
            assert ws.paused, f"{k} touches written and the connection's writes never held back"
            buffered = ws.transport.get_write_buffer_size()
            for _ in range(2000):  # held back: each takes the general path, a task that waits for the writes
                plate.touch(float(k), 1.0, "move", t=float(k))
                sent.append(k)
                k += 1
            waiting = plate._posting
            assert ws.transport.get_write_buffer_size() == buffered  # nothing more put into the full transport
            server.release.set()
            await plate.state()  # answered: the server has read everything before it
            return sent, waiting

    with Recorder() as server:
        sent, waiting = asyncio.run(touches(server))
        received = server.wait_for(len(sent) + 3, timeout_s=120.0)
    assert waiting == 2000
    assert [m["type"] for m in received[:2]] == ["hello", "hold"]
    touches_received = received[2:len(sent) + 2]
    assert [m["t"] for m in touches_received] == [float(k) for k in sent]  # every one, once, in order
    assert all(m["type"] == "touch" for m in touches_received) and received[len(sent) + 2]["type"] == "state"
    assert server.closes and server.closes[0][0] == 1000, server.closes  # every frame read as valid


def test_an_async_touch_that_is_not_finite_is_refused_and_nothing_of_it_is_sent():
    async def touches(url):
        async with await AsyncClient.connect(url) as plate:
            with pytest.raises(BadMessage, match="finite"):
                plate.touch(math.nan, 1.0)
            plate.touch(1.0, 2.0, t=5.0)
            await plate.state()

    with Recorder() as server:
        asyncio.run(touches(server.url))
        received = server.wait_for(3)
    assert [m["type"] for m in received] == ["hello", "touch", "state"] and received[1]["x"] == 1.0


def test_async_touches_after_the_service_closed_the_connection_raise_connection_failed():
    async def touches(url):
        plate = await AsyncClient.connect(url)
        plate.touch(1.0, 2.0, "down")
        await plate._send({"type": "goodbye"})  # the server closes the connection when it reads this
        deadline = time.monotonic() + 30.0
        with pytest.raises(ConnectionFailed, match="lost"):
            while time.monotonic() < deadline:
                plate.touch(1.0, 2.0, "move")
                await asyncio.sleep(0.005)
        await plate.close()

    with Recorder() as server:
        asyncio.run(touches(server.url))
        received = server.wait_for(3)
    assert [m["type"] for m in received[:3]] == ["hello", "touch", "goodbye"]
