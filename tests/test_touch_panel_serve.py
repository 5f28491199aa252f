"""``ultraglide serve --touch-panel``: the engine reads the panel itself (here a real FIFO carrying input_event records
packed from the kernel's layout) and a client only places sprites. Checked at the engine: its envelope record shows
the friction of the sprite under the finger written into the FIFO, at the place the rig's mapping puts it; the
touch as the engine saw it (``touch.seen``) names that sprite; clients' touches are refused; a panel that goes away
ends the service in one line with the plate at rest; bad options are refused in one line, exit 2."""

import json
import os
import struct
import subprocess
import time

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli, start_cli
from service_run import flat_png, png_ratio, read_envelope, read_line, rows_at, running_service

from ultraglide.client import Client

EV_SYN, EV_ABS, SYN_REPORT, SYN_DROPPED = 0, 3, 0, 3  # linux/input-event-codes.h
ABS_MT_SLOT, ABS_MT_POSITION_X, ABS_MT_POSITION_Y, ABS_MT_TRACKING_ID, ABS_MT_PRESSURE = 47, 53, 54, 57, 58


def frame(*events) -> bytes:
    """EV_ABS events (code, value) and their SYN_REPORT, stamped now on the wall clock, as the kernel stamps them."""
    now = time.time()
    seconds, micros = int(now), int((now % 1) * 1e6)
    return b"".join(struct.pack("=qqHHi", seconds, micros, EV_ABS, code, value) for code, value in events) + \
        struct.pack("=qqHHi", seconds, micros, EV_SYN, SYN_REPORT, 0)


def hold(write, seconds: float = 0.3) -> None:
    """Frames with nothing new every 10 ms (a panel reporting a still finger) for ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        time.sleep(0.01)
        write(frame())


def two_sprites(plate) -> None:
    """A 100 × 50 mm view: a slippery sprite on the left half (0.3), a sticky one on the right (0.8)."""
    plate.set_view("main", 100, 50, units="mm")
    plate.load_texture("low", png=flat_png(0.3))
    plate.load_texture("high", png=flat_png(0.8))
    plate.place_sprite("left", "low", 0, 0, 50, 50)
    plate.place_sprite("right", "high", 50, 0, 50, 50)
    plate.wait_rendered()


def seen(plate, timeout_s: float = 10.0) -> list[dict]:
    """The ``touch.seen`` pushes that came within ``timeout_s`` (until one with the finger up)."""
    found = []
    for message in plate.events(timeout_s):
        if message["type"] == "touch.seen":
            found.append(message)
            if not message["down"]:
                break
    return found


def test_the_sprite_under_the_panel_s_finger_is_rendered_and_a_panel_that_goes_away_rests_the_plate(tmp_path):
    fifo, envelope_csv = tmp_path / "panel", tmp_path / "envelope.csv"
    os.mkfifo(fifo)
    with running_service("--port", "0", "--device", "sim", "--touch-panel", fifo, "--touch-range", "x=0:1000",
                         "--touch-range", "y=0:500", "--envelope-csv", envelope_csv) as (process, address):
        assert address["touch_panel"]["kind"] == "fifo"
        writer = os.open(fifo, os.O_WRONLY)
        try:
            with Client(address["url"]) as plate:
                assert plate.welcome["touch_panel"] == str(fifo)
                two_sprites(plate)
                plate.subscribe(touch=True)
                plate.touch(75, 25, "down")  # a client's touch: refused, the panel drives
                plate.state()  # (its refusal has come by the time this is answered)
                assert [error.code for error in plate.errors] == ["touch-panel"]
                # panel units 0..1000 × 0..500 over the 100 × 50 mm view: 0.1 mm a unit
                os.write(writer, frame((ABS_MT_TRACKING_ID, 1), (ABS_MT_POSITION_X, 250), (ABS_MT_POSITION_Y, 250)))
                hold(lambda data: os.write(writer, data))
                os.write(writer, frame((ABS_MT_TRACKING_ID, -1)))
                left = seen(plate)
                os.write(writer, frame((ABS_MT_TRACKING_ID, 2), (ABS_MT_POSITION_X, 800), (ABS_MT_POSITION_Y, 100)))
                hold(lambda data: os.write(writer, data))
                right = seen(plate, 1.0)  # (still down: the panel goes away with the finger on it)
        finally:
            os.close(writer)  # the panel goes away, a finger down
        status = process.wait(60)
        out, err = process.stdout.read(), process.stderr.read()
    assert status == 1 and "Traceback" not in err
    # said in one line, the last (a loaded machine's sim may have said its underruns before it)
    assert err.strip().splitlines()[-1] == f"ultraglide serve: the touch panel {fifo} went away (its events ended)"
    final = json.loads(out.strip().splitlines()[-1])
    assert final["touch_panel"]["gone"] and final["touches"] >= 2
    assert any(m["down"] and m["sprite"] == "left" and (m["x_mm"], m["y_mm"]) == pytest.approx((25, 25)) for m in left)
    assert any(m["down"] and m["sprite"] == "right" and (m["x_mm"], m["y_mm"]) == pytest.approx((80, 10))
               for m in right)
    envelope = read_envelope(envelope_csv)
    under_left, under_right = rows_at(envelope, 25, 25), rows_at(envelope, 80, 10)
    assert len(under_left) > 100 and len(under_right) > 100
    assert np.median(under_left["target_ratio"]) == pytest.approx(png_ratio(0.3), abs=0.01)
    assert np.median(under_right["target_ratio"]) == pytest.approx(png_ratio(0.8), abs=0.01)
    assert len(rows_at(envelope, 75, 25)) == 0  # the client's touch was never rendered
    assert envelope["down"][-1] == 0 and envelope["commanded_um_pp"][-1] == 0.0  # at rest at the end


def test_a_rig_s_panel_is_turned_placed_and_pressed_and_its_drive_rule_holds(tmp_path):
    fifo, envelope_csv, rig = tmp_path / "panel", tmp_path / "envelope.csv", tmp_path / "rig.toml"
    os.mkfifo(fifo)
    touch = ('[touch]\narea_mm = [10.0, 5.0, 80.0, 40.0]\nrotation_deg = 90\npressure_full_scale_n = 4.0\n'
             'drives = "latest"\nx_range = [0, 4000]\ny_range = [0, 2000]\npressure_range = [0, 200]\n')
    text = (ROOT / "examples" / "rig.toml").read_text()
    rig.write_text(text[:text.index("[touch]")] + touch + text[text.index("[display]"):])
    with running_service("--port", "0", "--rig", rig, "--device", "sim", "--touch-panel", fifo,
                         "--envelope-csv", envelope_csv) as (process, address):
        assert "pressure 0..200 (the rig)" in address["touch_panel"]["ranges"]
        writer = os.open(fifo, os.O_WRONLY)
        try:
            with Client(address["url"]) as plate:
                assert plate.welcome["drives"] == "latest"
                two_sprites(plate)
                plate.subscribe(touch=True)
                # slot 0 at the panel's (0.25, 0.75), pressed at 100 of 200 (2 N)
                os.write(writer, frame((ABS_MT_SLOT, 0), (ABS_MT_TRACKING_ID, 5), (ABS_MT_POSITION_X, 1000),
                                       (ABS_MT_POSITION_Y, 1500), (ABS_MT_PRESSURE, 100)))
                hold(lambda data: os.write(writer, data))
                first = [m for m in seen(plate, 1.0) if m["down"]]
                # slot 1 at the panel's (0.75, 0.1), pressed at 50 of 200 (1 N): the latest down drives
                os.write(writer, frame((ABS_MT_SLOT, 1), (ABS_MT_TRACKING_ID, 6), (ABS_MT_POSITION_X, 3000),
                                       (ABS_MT_POSITION_Y, 200), (ABS_MT_PRESSURE, 50)))
                hold(lambda data: os.write(writer, data))
                os.write(writer, frame((ABS_MT_SLOT, 1), (ABS_MT_TRACKING_ID, -1), (ABS_MT_SLOT, 0),
                                       (ABS_MT_TRACKING_ID, -1)))
                second = [m for m in seen(plate) if m["down"]]
                # a finger at the panel's (0.5, 0.5) = the area's (0.5, 0.5) = (50, 25) mm, then the kernel's buffer
                # overflows: the events to the next report are discarded, the finger lifted; its later moves in
                # its slot (to x 0.55 and 0.6: (50, 27) and (50, 29) mm) are not felt: its contact is not known
                os.write(writer, frame((ABS_MT_SLOT, 0), (ABS_MT_TRACKING_ID, 7), (ABS_MT_POSITION_X, 2000),
                                       (ABS_MT_POSITION_Y, 1000)))
                hold(lambda data: os.write(writer, data))
                dropped = struct.pack("=qqHHi", int(time.time()), 0, EV_SYN, SYN_DROPPED, 0)
                os.write(writer, dropped + frame((ABS_MT_POSITION_X, 2200)))
                for _ in range(30):
                    os.write(writer, frame((ABS_MT_POSITION_X, 2400)))
                    time.sleep(0.01)
                after_drop = seen(plate)
        finally:
            os.close(writer)
        process.wait(60)
    assert [m["down"] for m in after_drop][-1] is False and (50, 25) in [(m["x_mm"], m["y_mm"]) for m in after_drop]
    # turned 90° clockwise, the panel's (u, v) is the area's (1 - v, u): (0.25, 0.75) -> (0.25, 0.25) of the
    # 80 × 40 mm area at (10, 5) mm -> (10 + 20, 5 + 10) = (30, 15) mm, on the left sprite; 100 of 200 × 4 N = 2 N
    assert any((m["x_mm"], m["y_mm"]) == pytest.approx((30, 15)) and m["sprite"] == "left"
               and m["force_n"] == pytest.approx(0.5 * 4.0) for m in first)
    # (0.75, 0.1) turned: u' = 0.9, v' = 0.75 -> (10 + 72, 5 + 30) = (82, 35) mm, 50 of 200 × 4 N = 1 N
    assert any((m["x_mm"], m["y_mm"]) == pytest.approx((82, 35)) and m["sprite"] == "right"
               and m["force_n"] == pytest.approx(1.0) for m in second)
    envelope = read_envelope(envelope_csv)
    assert np.median(rows_at(envelope, 30, 15)["target_ratio"]) == pytest.approx(png_ratio(0.3), abs=0.01)
    assert np.median(rows_at(envelope, 82, 35)["target_ratio"]) == pytest.approx(png_ratio(0.8), abs=0.01)
    assert len(rows_at(envelope, 50, 25)) > 100
    assert len(rows_at(envelope, 50, 27, within_mm=0.5)) == 0 and len(rows_at(envelope, 50, 29, within_mm=0.5)) == 0


def test_bad_panel_options_are_one_line_exit_2_before_the_engine_starts(tmp_path):
    fifo = tmp_path / "panel"
    os.mkfifo(fifo)
    cases = [(["--touch-panel", fifo], "is a FIFO, not an evdev device"),
             (["--touch-panel", fifo, "--touch-range", "x=0:100"], "y range is not given"),
             (["--touch-panel", fifo, "--touch-range", "x=100:0", "--touch-range", "y=0:1"], "AXIS=MIN:MAX"),
             (["--touch-panel", "/dev/null"], "not an evdev one"),
             (["--touch-panel", tmp_path / "absent"], "no such file"),
             (["--touch-range", "x=0:100"], "add --touch-panel")]
    for options, said in cases:
        result = run_cli("serve", "--port", "0", *options)
        assert said in assert_one_line_error(result) and result.returncode == 2, options
        assert result.stdout == ""


def test_the_panel_is_said_in_words_at_start(tmp_path):
    fifo = tmp_path / "panel"
    os.mkfifo(fifo)
    process = start_cli("serve", "--port", "0", "--touch-panel", fifo, "--touch-range", "x=0:99",
                        "--touch-range", "y=-5:5", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert read_line(process.stdout, 120).startswith("ws://")  # listening: the panel is open
    finally:
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))  # a writer came and went: the panel's events end
        status = process.wait(60)
    out, err = process.stdout.read(), process.stderr.read()
    assert status == 1 and "went away" in err
    assert (f"touch panel {fifo}: a FIFO of evdev records; x 0..99, y -5..5, no pressure (--touch-range); clients' "
            "touches are refused") in out.splitlines()
