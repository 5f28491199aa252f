"""Hostile and careless clients of ``ultraglide serve``, on real sockets against a real service: a page of another
origin, no token beyond loopback, oversized, malformed and flooding messages, a client that does not read, and
one killed with its finger down; the engine goes on and the plate stays within its limit."""

import contextlib
import itertools
import json
import math
import signal
import socket
import subprocess
import sys
import textwrap
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from service_run import flat_png, read_envelope, read_line, running_service, stop
from ultraglide.devices.profiles import load_profile
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from ultraglide.client import BadMessage, Busy, Client, ConnectionFailed, TooBig


def raw(url, **options):
    """A bare WebSocket (no hello), for messages the client would never send."""
    return connect(url, proxy=None, open_timeout=30, **options).__enter__()


def ask(ws, text, timeout_s=30.0) -> dict:
    ws.send(text)
    return json.loads(ws.recv(timeout=timeout_s))


def test_a_page_of_another_origin_cannot_connect_and_the_served_page_can():
    with running_service("--port", "0", "--page") as (process, address):
        page = address["page"].rstrip("/")
        port = page.rsplit(":", 1)[1]
        for origin in ("http://evil.example", f"http://127.0.0.1:{int(port) + 1}", "null", f"https://127.0.0.1:{port}"):
            with pytest.raises(ConnectionFailed, match="403"):
                Client(address["url"], origin=origin)
        with Client(address["url"], origin=page) as plate:  # the page's own origin
            assert plate.welcome["role"] == "control"
        with Client(address["url"], origin=f"http://localhost:{port}", role="observe") as other:  # the same page
            assert other.welcome["role"] == "observe"
        with urllib.request.urlopen(address["page"], timeout=30) as response:
            assert response.headers["Content-Type"].startswith("text/html")
            assert b'<script type="module" src="/page.js">' in response.read()
    with running_service("--port", "0") as (process, address):  # no page: no browser origin at all
        with pytest.raises(ConnectionFailed, match="403"):
            Client(address["url"], origin=f"http://{address['url'].split('/')[2]}")
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(address["url"].replace("ws://", "http://").replace("/ws", "/"), timeout=30)


def test_beyond_the_usual_loopback_a_token_is_printed_and_required():
    with running_service("--host", "127.0.0.2", "--port", "0", "--page") as (process, address):
        token = address["token"]
        assert token and len(token) >= 20 and f"token={token}" in address["url"]
        bare = address["url"].split("?")[0]
        with pytest.raises(ConnectionFailed, match="401"):
            Client(bare)
        with pytest.raises(ConnectionFailed, match="401"):
            Client(bare + "?token=" + token[:-1] + ("A" if token[-1] != "A" else "B"))
        with Client(address["url"]) as plate:
            assert plate.welcome["role"] == "control"
            texture = plate.state()["textures"]
        assert texture == []
        with pytest.raises(urllib.error.HTTPError, match="401"):
            urllib.request.urlopen(address["page"].split("?")[0] + "texture/t1.png", timeout=30)
    with running_service("--port", "0") as (process, address):
        assert address["token"] is None and "token" not in address["url"]


def controlling_client(url: str, deadline_s: float = 60.0) -> Client:
    """A client that controls the plate, once the service has released the last controller (a connection it
    closed goes through its closing handshake first): asked again while it answers Busy."""
    end = time.monotonic() + deadline_s
    while True:
        try:
            return Client(url)
        except Busy:
            if time.monotonic() > end:
                raise
            time.sleep(0.05)


def test_oversized_malformed_and_flooding_messages_are_refused_in_one_line_and_the_engine_goes_on(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv, "--json") as (process, address):
        ws = raw(address["url"], max_size=None)
        assert ask(ws, json.dumps({"type": "state", "id": 1}))["code"] == "no-hello"
        assert ask(ws, json.dumps({"type": "hello", "id": 2, "protocol": 1}))["role"] == "control"
        bad = {
            "not json": "bad-message", "[]": "bad-message", '"text"': "bad-message", "{}": "bad-message",
            '{"type": "launch"}': "bad-message", '{"type": "touch", "x": 1, "y": 2}': "bad-message",
            '{"type": "touch", "phase": "down", "x": NaN, "y": 2}': "bad-message",
            '{"type": "touch", "phase": "down", "x": 1e999, "y": 2}': "bad-message",
            '{"type": "touch", "phase": "down", "x": "1", "y": 2}': "bad-message",
            '{"type": "touch", "phase": "jump", "x": 1, "y": 2}': "bad-message",
            '{"type": "touch", "phase": "down", "x": 1, "y": 2, "force_n": 500}': "bad-message",
            '{"type": "sprite.set", "sprite": "s", "texture": "t", "x": 0, "y": 0, "width": -1, "height": 1}':
                "bad-message",
            '{"type": "view.set", "view": "v", "width": 10, "height": 10}': "bad-message",
            '{"type": "state", "surprise": 1}': "bad-message",
            '{"type": "state", "id": [1]}': "bad-message",
            '{"type": "texture.load", "texture": "t", "png": "!!"}': "bad-message",
            '{"type": "texture.load", "texture": "t", "png": "aGVsbG8="}': "texture",
            '{"type": "texture.load", "texture": "t", "library": "no-such-texture"}': "texture",
            '{"type": "texture.load", "texture": "t", "file": "/dev/zero"}': "texture",
            '{"type": "effects.set", "effects": {"version": 99}}': "engine",
            '{"type": "sprite.remove", "sprite": "ghost"}': "unknown",
            "[" * 5000 + "]" * 5000: "bad-message",
            json.dumps({"type": "state", "pad": "x" * 100_000}): "too-big",
        }
        for text, code in bad.items():
            answer = ask(ws, text)
            assert answer["type"] == "error" and answer["code"] == code, (text[:80], answer)
            assert "\n" not in answer["message"] and 0 < len(answer["message"]) <= 600
        ws.send(b"\x00binary")
        assert json.loads(ws.recv(timeout=30))["code"] == "bad-message"
        # a PNG too large for a sprite: refused from its header
        big = flat_png(0.5, 2500, 2000)
        answer = ask(ws, json.dumps({"type": "texture.load", "id": 3, "texture": "big",
                                     "png": __import__("base64").b64encode(big).decode()}))
        assert answer["code"] == "limit" and "4,000,000" in answer["message"]
        # a flood: 20 000 touches as fast as they go; refused past the rate, in one line (and one more a thousand)
        flood = json.dumps({"type": "touch", "phase": "move", "x": 10, "y": 10})
        for _ in range(20_000):
            ws.send(flood)
        # the refusals (if the service read them faster than its rate: a loaded one may not), then the answer
        refusals = []
        deadline = time.monotonic() + 300
        answer = {}
        while answer.get("id") != 5 and time.monotonic() < deadline:  # dropped unanswered while over the rate
            ws.send(json.dumps({"type": "state", "id": 5}))
            with contextlib.suppress(TimeoutError):
                while answer.get("id") != 5:
                    answer = json.loads(ws.recv(timeout=2.0))
                    refusals.append(answer)
        assert answer.get("id") == 5 and answer["type"] == "ok"
        assert all(r["code"] == "rate" and "messages a second" in r["message"] for r in refusals[:-1])
        assert len(refusals) - 1 <= 1 + 20_000 // 1000  # one line for the first, one a thousand after
        # past the limit: the socket closes (1009), the service goes on
        ws.send("x" * (4 * 1024 * 1024 + 1))
        with pytest.raises(ConnectionClosed) as closed:
            while True:
                ws.recv(timeout=30)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009
        with controlling_client(address["url"]) as plate:  # once the service has let the closed one go
            with pytest.raises(TooBig):
                plate.set_effects({"pad": "y" * 70_000})
            with pytest.raises(BadMessage, match="every number must be finite"):
                plate.place_sprite("s", "t", math.inf, 0, 1, 1)
            plate.subscribe(status=20)
            status = next(e for e in plate.events(5.0) if e["type"] == "status")
            # a loaded machine's underruns and overruns are not faults the bad messages caused
            assert status["state"] == "running" and set(status["faults"]) <= {"underrun", "overrun"}
        assert process.poll() is None
        assert stop(process) == 128 + signal.SIGTERM
        final = [json.loads(line) for line in process.stdout.read().splitlines() if line.startswith("{")][-1]
        faults = {name: count for name, count in final["faults"].items() if name not in ("underrun", "overrun")}
        assert final["error"] is None and not any(faults.values()), final["faults"]


def test_a_client_that_does_not_read_holds_up_nobody_and_is_let_go():
    from websockets.client import ClientProtocol
    from websockets.uri import parse_uri

    with running_service("--port", "0", "grating-1mm") as (process, address):
        # a client that never reads a byte after its handshake (the protocol's bytes made by websockets' sans-I/O)
        host, port = address["url"].split("/")[2].split(":")
        sock = socket.create_connection((host, int(port)), timeout=30)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        protocol = ClientProtocol(parse_uri(address["url"]))
        protocol.send_request(protocol.connect())
        sock.sendall(b"".join(protocol.data_to_send()))
        while protocol.state.name == "CONNECTING":
            protocol.receive_data(sock.recv(4096))

        def send(message):
            protocol.send_text(json.dumps(message).encode())
            sock.sendall(b"".join(protocol.data_to_send()))

        send({"type": "hello", "id": 0, "protocol": 1, "role": "observe"})
        send({"type": "subscribe", "id": 1, "status": 20, "output": 1000, "touch": True, "scene": True})
        with Client(address["url"]) as plate:
            plate.subscribe(status=20)
            for k in range(60):  # a scene of some 10 kB: each state the slow one asks for is as large
                plate.place_sprite(f"extra{k}", "t1", k, k, 5, 5, visible=False)
            worst = 0.0
            clients = []
            deadline = time.monotonic() + 90
            for k in itertools.count():  # requests from the slow one, none read; the other served meanwhile
                if time.monotonic() > deadline:
                    break
                with contextlib.suppress(OSError):  # once let go, its socket is closed under it
                    for _ in range(10):
                        send({"type": "state", "id": k})
                started = time.monotonic()
                plate.move_sprite("s1", k % 7, 0)
                worst = max(worst, time.monotonic() - started)
                clients += [e["clients"] for e in plate.events() if e["type"] == "status"]
                if clients and clients[-1] == 1:
                    break
            assert worst < 2.0  # generous: a loaded machine; a service waiting on the slow one would not answer
            assert 2 in clients and clients[-1] == 1  # it was there, and it was let go
        sock.close()


KILLED_CLIENT = textwrap.dedent("""
    import sys, time
    from ultraglide.client import Client
    plate = Client(sys.argv[1])
    plate.set_view("main", 100, 50, units="mm")
    plate.load_texture("slip", png=bytes.fromhex(sys.argv[2]))
    plate.place_sprite("a", "slip", 0, 0, 100, 50)
    plate.wait_rendered()
    plate.touch(50, 25, "down")
    print("down", flush=True)
    while True:
        time.sleep(0.005)
        plate.touch(50, 25, "move")
""")


RELEASE_S = 0.5  # the aim is 100 ms (issue 41); a test on a loaded machine bounds it at five times that


def test_a_client_killed_with_its_finger_down_releases_it(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    profile = load_profile("sim-plate")
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        client = subprocess.Popen([sys.executable, "-c", KILLED_CLIENT, address["url"], flat_png(0.2).hex()],
                                  stdout=subprocess.PIPE, text=True)
        try:
            assert read_line(client.stdout, 120).strip() == "down"
            with Client(address["url"], role="observe") as watcher:
                watcher.subscribe(output=200)
                assert any(max(e["amplitude_um_pp"]) > 1.0 for e in watcher.events(3.0) if e["type"] == "output")
                killed_s = time.perf_counter()
                client.send_signal(signal.SIGKILL)
                client.wait(30)
                # gone: its socket closed by the kernel (on a loaded machine, tearing down a killed process takes
                # the kernel tens of ms of the dying process's own turn on a CPU, which is not the service's)
                gone_s = time.perf_counter()
                after = [e for e in watcher.events(RELEASE_S + 1.0) if e["type"] == "output"]
        finally:
            if client.poll() is None:
                client.kill()
    # the engine's own record of each block (the watcher's output rows: commanded µm p-p at the block's time)
    times = np.concatenate([e["t"] for e in after])
    amplitude = np.concatenate([e["amplitude_um_pp"] for e in after])
    at_rest = amplitude < 0.01 * profile.max_amplitude_um_pp
    assert times[-1] > gone_s + RELEASE_S + 0.1 and at_rest[times > gone_s + RELEASE_S].all()
    assert times[at_rest & (times > killed_s)][0] - gone_s < RELEASE_S  # and at rest since then
    # the envelope record agrees wherever it has rows (its writer may drop some on a busy machine, and says so)
    envelope = read_envelope(envelope_csv)
    rows = envelope[envelope["t_s"] >= gone_s + RELEASE_S]
    assert (rows["commanded_um_pp"] < 0.01 * profile.max_amplitude_um_pp).all() and (rows["down"] < 0.5).all()


def test_whatever_a_client_sends_the_plate_stays_within_its_limit(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    profile = load_profile("sim-plate")
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            plate.set_view("main", 100, 50, units="mm", background_ratio=0.0)  # asks for no friction at all
            plate.load_texture("stripes", png=_stripes())
            plate.place_sprite("a", "stripes", 0, 0, 50, 50)
            plate.wait_rendered()
            rng = np.random.default_rng(7)
            plate.touch(10, 10, "down", force_n=50.0)
            for k in range(1500):  # a finger jumping across the plate at 1 kHz, the heaviest force allowed
                plate.touch(*rng.uniform(-50, 150, 2), "move", force_n=float(rng.choice([0.0, 50.0])))
                if k % 300 == 299:
                    plate.touch(10, 10, "up")
                    plate.touch(10, 10, "down", pressure=1.0)
                time.sleep(0.001)
            plate.touch(10, 10, "up")
            plate.state()
    envelope = read_envelope(envelope_csv)
    commanded = envelope["commanded_um_pp"]
    assert commanded.max() > 0.9 * profile.max_amplitude_um_pp  # it did push the plate hard
    assert commanded.max() <= profile.max_drive_um_pp * (1 + 1e-9)
    # the fastest plate the limiter allows for (half the profile's Q), driven by what the device was given
    dt = float(np.median(np.diff(envelope["t_s"])))
    tau = 0.5 * profile.q / (math.pi * profile.resonance_hz)
    gain = 1.0 - math.exp(-dt / tau)
    plate_um_pp = 0.0
    worst = 0.0
    for value in commanded:
        plate_um_pp += gain * (value - plate_um_pp)
        worst = max(worst, plate_um_pp)
    assert worst <= profile.max_amplitude_um_pp * 1.001


def _stripes() -> bytes:
    import io

    from PIL import Image

    values = np.zeros((40, 40), dtype=np.uint8)
    values[:, ::4] = 255
    stream = io.BytesIO()
    Image.fromarray(values, mode="L").save(stream, "PNG")
    return stream.getvalue()
