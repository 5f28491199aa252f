"""The service's protocol through the Python client, on a real socket, against a real ``ultraglide serve``: what the
engine rendered (its envelope record) is the friction of the sprite under the finger."""

import asyncio

import numpy as np
import pytest
from service_run import flat_png, hold, png_ratio, read_envelope, rows_at, running_service
from ultraglide.devices.profiles import load_profile

from ultraglide.client import AsyncClient, BadMessage, Busy, Client, ReadOnly, Unknown


def expect_ratio(envelope, x_mm, y_mm, ratio):
    rows = rows_at(envelope, x_mm, y_mm)
    assert len(rows) > 100, f"no rows rendered at ({x_mm}, {y_mm})"
    # the first rows may still carry the composition before the change: all but a few agree
    assert np.median(rows["target_ratio"]) == pytest.approx(ratio, abs=0.01)
    assert np.mean(np.abs(rows["target_ratio"] - ratio) < 0.01) > 0.9


def test_the_engine_renders_the_sprite_under_the_finger_as_sprites_move_turn_and_hide(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            assert plate.welcome["protocol"] == 1 and plate.welcome["role"] == "control"
            assert plate.welcome["limit_um_pp"] == load_profile("sim-plate").max_amplitude_um_pp
            plate.set_view("main", 400, 200, units="px", width_mm=100, height_mm=50, background_ratio=0.95)
            plate.load_texture("low", png=flat_png(0.3))
            plate.load_texture("high", png=flat_png(0.8))
            plate.place_sprite("a", "low", 40, 40, 120, 80)  # 10..40 × 10..30 mm
            plate.place_sprite("b", "high", 240, 40, 120, 80)  # 60..90 mm
            plate.wait_rendered()
            hold(plate, 100, 100)  # (25, 25) mm: on a
            hold(plate, 300, 100)  # (75, 25) mm: on b
            hold(plate, 200, 160)  # (50, 40) mm: the background
            plate.update_sprite("b", x=60, z=1)  # b over a: 15..45 mm
            plate.wait_rendered()
            hold(plate, 120, 80)  # (30, 20) mm: both, b on top
            plate.reorder_sprite("b", -1)
            plate.wait_rendered()
            hold(plate, 124, 84)  # (31, 21) mm: both, a on top now
            plate.hide_sprite("a")
            plate.wait_rendered()
            hold(plate, 128, 88)  # (32, 22) mm: a hidden, b felt
            plate.remove_sprite("b")
            plate.place_sprite("bar", "low", 120, 80, 160, 40, rotation_deg=90)  # 40 × 10 mm about (50, 25): upright
            plate.wait_rendered()
            hold(plate, 200, 30)  # (50, 7.5) mm: on the turned bar
            hold(plate, 140, 100)  # (35, 25) mm: where it lay before turning: background
            assert [s["sprite"] for s in plate.state()["sprites"]] == ["a", "bar"]
    envelope = read_envelope(envelope_csv)
    low, high = png_ratio(0.3), png_ratio(0.8)
    expect_ratio(envelope, 25, 25, low)
    expect_ratio(envelope, 75, 25, high)
    expect_ratio(envelope, 50, 40, 0.95)
    expect_ratio(envelope, 30, 20, high)
    expect_ratio(envelope, 31, 21, low)
    expect_ratio(envelope, 32, 22, high)
    expect_ratio(envelope, 50, 7.5, low)
    expect_ratio(envelope, 35, 25, 0.95)


def test_a_second_controller_is_refused_and_observers_are_read_only(tmp_path):
    with running_service("--port", "0", "grating-1mm") as (process, address):
        with Client(address["url"]) as plate:
            with pytest.raises(Busy, match="another client controls the plate"):
                Client(address["url"])
            with Client(address["url"], role="observe") as watcher:
                assert watcher.welcome["role"] == "observe"
                assert [s["texture"] for s in watcher.state()["sprites"]] == ["t1"]  # the texture named at start
                with pytest.raises(ReadOnly):
                    watcher.move_sprite("s1", 10, 10)
                with pytest.raises(ReadOnly):
                    watcher.load_texture("x", library="bumps")
                watcher.touch(10, 10, "down")  # unanswered: refused once, later
                watcher.subscribe(status=20)
                statuses = [e for e in watcher.events(2.0) if e["type"] == "status"]
                assert statuses and statuses[-1]["role"] == "observe" and statuses[-1]["touches"] == 0
                assert any(error.code == "read-only" for error in watcher.errors)
            with pytest.raises(Unknown, match="no sprite"):
                plate.remove_sprite("nothing")
            with pytest.raises(Unknown, match="no sprite 'new'"):
                plate.update_sprite("new", x=3)
            with pytest.raises(BadMessage, match="needs width, height"):
                plate.update_sprite("new", texture="t1", x=3, y=4)
        # the controller gone, another may take the plate
        with Client(address["url"]) as second:
            assert second.welcome["role"] == "control"


def test_subscriptions_report_the_rendered_friction_the_touch_as_seen_and_the_status(tmp_path):
    with running_service("--port", "0") as (process, address):
        with Client(address["url"]) as plate:
            plate.set_view("main", 100, 50, units="mm")
            plate.load_texture("low", png=flat_png(0.4))
            plate.place_sprite("a", "low", 0, 0, 50, 50)
            plate.wait_rendered()
            assert plate.subscribe(status=True, output=200, touch=True) == \
                {"type": "ok", "status": 2.0, "output": 200.0, "touch": True, "scene": False}
            plate.touch(20, 20, "down")
            events = []
            for event in plate.events(1.0):
                events.append(event)
                plate.touch(20, 20, "move")
            plate.touch(20, 20, "up")
            events += list(plate.events(0.5))
    seen = [e for e in events if e["type"] == "touch.seen" and e["down"]]
    assert seen and seen[0]["x_mm"] == pytest.approx(20) and seen[0]["sprite"] == "a"
    rows = [e for e in events if e["type"] == "output"]
    ratios = np.concatenate([e["ratio"] for e in rows])
    amplitudes = np.concatenate([e["amplitude_um_pp"] for e in rows])
    times = np.concatenate([e["t"] for e in rows])
    assert np.all(np.diff(times) >= 1 / 200 * 0.999)  # at most the rate asked for
    assert np.any(np.abs(ratios - png_ratio(0.4)) < 0.01)  # the sprite's friction, while the finger was down
    assert amplitudes.max() > 0.5  # and the amplitude that renders it
    status = [e for e in events if e["type"] == "status"][-1]
    assert status["device"] == "sim" and status["limit_um_pp"] == 6.0
    # a loaded machine's underruns and overruns are not faults of the plate
    assert set(status["faults"]) <= {"underrun", "overrun"}, status["faults"]


def test_the_asyncio_client_drives_the_same_calls(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"

    async def session(url):
        async with await AsyncClient.connect(url) as plate:
            await plate.set_view("main", 80, 40, units="mm")
            texture = await plate.load_texture("low", png=flat_png(0.5), width_mm=20)
            assert texture["width_mm"] == pytest.approx(20) and texture["height_mm"] == pytest.approx(20)
            await plate.place_sprite("a", "low", 40, 0, 40, 40)
            await plate.wait_rendered()
            plate.touch(60, 20, "down")
            for _ in range(15):
                await asyncio.sleep(0.01)
                plate.touch(60, 20, "move")
            plate.touch(60, 20, "up")
            with pytest.raises(Unknown):
                await plate.move_sprite("nobody", 1, 1)
            assert (await plate.state())["sprites"][-1]["sprite"] == "a"

    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        asyncio.run(session(address["url"]))
    expect_ratio(read_envelope(envelope_csv), 60, 20, png_ratio(0.5))
