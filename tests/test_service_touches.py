"""Two pointers down at once through the client, on a real ``ultraglide serve``: which one the engine renders is the
rule ``touches.set`` chooses (``first``, ``latest``, ``none``, as a rig's ``[touch] drives``), read from the envelope
record: the rows under each pointer, and when they were rendered."""

import time

import numpy as np
import pytest
from service_run import flat_png, png_ratio, read_envelope, rows_at, running_service

from ultraglide.client import BadMessage, Client


def held(plate, pointers: dict, seconds: float = 0.3) -> tuple[float, float]:
    """Every pointer of ``pointers`` ({id: (x, y)}) moved where it is every 10 ms for ``seconds``; the span's
    perf_counter times (start, end)."""
    start = time.perf_counter()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        time.sleep(0.01)
        for pointer, (x, y) in pointers.items():
            plate.touch(x, y, "move", pointer=pointer)
    return start, time.perf_counter()


def rendered_between(envelope, span, within_s=0.05, before_s=0.005):
    """The rows with the finger down from ``within_s`` after the span's start to ``before_s`` before its end (a
    report's time is the client's, shifted onto the engine's clock: the next one may land a fraction of a ms
    before the span's end as this process read it)."""
    t = envelope["t_s"]
    return envelope[(t > span[0] + within_s) & (t < span[1] - before_s) & (envelope["down"] > 0.5)]


def setup(plate):
    plate.set_view("main", 100, 50, units="mm")
    plate.load_texture("low", png=flat_png(0.3))
    plate.load_texture("high", png=flat_png(0.8))
    plate.place_sprite("left", "low", 0, 0, 50, 50)
    plate.place_sprite("right", "high", 50, 0, 50, 50)
    plate.wait_rendered()


def test_the_first_pointer_drives_until_it_lifts_and_the_second_is_not_felt(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            assert plate.welcome["drives"] == "first"
            setup(plate)
            plate.touch(25, 25, "down", pointer=1)
            held(plate, {1: (25, 25)})
            plate.touch(75, 25, "down", pointer=2)
            both = held(plate, {1: (25, 25), 2: (75, 25)})
            plate.touch(25, 25, "up", pointer=1)
            alone = held(plate, {2: (76, 26)})  # the first lifted: the second still does not drive
            plate.touch(76, 26, "up", pointer=2)
            with pytest.raises(BadMessage, match="first, latest, none"):
                plate.set_drives("loudest")
    envelope = read_envelope(envelope_csv)
    assert np.median(rows_at(envelope, 25, 25)["target_ratio"]) == pytest.approx(png_ratio(0.3), abs=0.01)
    during = rendered_between(envelope, both)
    assert len(during) > 100 and np.all(np.abs(during["x_mm"] - 25) < 0.05)  # only the first, all along
    assert len(rows_at(envelope, 75, 25)) == 0 and len(rows_at(envelope, 76, 26)) == 0
    assert len(rendered_between(envelope, alone)) == 0  # the plate at rest


def test_the_latest_pointer_takes_over_and_hands_back_when_it_lifts(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            setup(plate)
            assert plate.set_drives("latest")["drives"] == "latest"
            plate.touch(20, 20, "down", pointer=1)
            first = held(plate, {1: (20, 20)})
            plate.touch(80, 20, "down", pointer=2)
            second = held(plate, {1: (21, 21), 2: (80, 20)})  # the newest drives; the first moves unfelt
            # and rests, unfelt still, where it is felt again: taken over mid-move, the engine's prediction would
            # render it on its way for as long as the next report took (on a loaded machine, most of the span)
            moved = held(plate, {1: (22, 22), 2: (80, 20)}, 0.2)
            plate.touch(80, 20, "up", pointer=2)
            back = held(plate, {1: (22, 22)})  # the first again, where it is now
            plate.touch(22, 22, "up", pointer=1)
    envelope = read_envelope(envelope_csv)
    for span, (x, y), ratio in ((first, (20, 20), 0.3), (second, (80, 20), 0.8), (back, (22, 22), 0.3)):
        rows = rendered_between(envelope, span)
        assert len(rows) > 100, f"nothing rendered while ({x}, {y}) should drive"
        assert np.median(rows["x_mm"]) == pytest.approx(x, abs=0.05)
        assert np.median(rows["y_mm"]) == pytest.approx(y, abs=0.05)
        assert np.median(rows["target_ratio"]) == pytest.approx(png_ratio(ratio), abs=0.01)
    # the first's moves while the second drove were not rendered; where it is, once it takes over
    assert len(rows_at(envelope, 21, 21)) == 0 and np.all(rows_at(envelope, 22, 22)["t_s"] > moved[1])


def test_with_drives_none_two_pointers_rest_the_plate_until_one_is_left(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            setup(plate)
            plate.set_drives("none")
            plate.touch(30, 30, "down", pointer=7)
            alone = held(plate, {7: (30, 30)})
            plate.touch(70, 30, "down", pointer=8)
            both = held(plate, {7: (31, 31), 8: (70, 30)})
            plate.touch(70, 30, "up", pointer=8)
            left = held(plate, {7: (32, 32)})  # one left: it drives, from where it was last
            plate.touch(32, 32, "up", pointer=7)
    envelope = read_envelope(envelope_csv)
    rows = rendered_between(envelope, alone)
    assert len(rows) > 100 and np.median(rows["target_ratio"]) == pytest.approx(png_ratio(0.3), abs=0.01)
    # two down: the plate at rest (the span's ends left out: the first's lift, and its return once the second lifted,
    # which a loaded machine may render some ms before this process read the clock)
    assert len(rendered_between(envelope, both, within_s=0.1, before_s=0.05)) == 0
    assert len(rows_at(envelope, 70, 30)) == 0  # the second never drove
    rows = rendered_between(envelope, left)
    assert len(rows) > 100 and np.median(rows["x_mm"]) == pytest.approx(32, abs=0.05)
    assert np.median(rows["target_ratio"]) == pytest.approx(png_ratio(0.3), abs=0.01)


def test_a_rig_s_touch_panel_rule_is_the_service_s_at_start(tmp_path):
    from conftest import ROOT

    rig = tmp_path / "rig.toml"
    rig.write_text((ROOT / "examples" / "rig.toml").read_text().replace('drives = "first"', 'drives = "latest"'))
    with running_service("--port", "0", "--rig", rig, "--device", "sim") as (process, address):
        with Client(address["url"]) as plate:
            assert plate.welcome["drives"] == "latest"
