"""The demo's status line says what a finger with friction dynamics keeps of the texture at its own speed."""

import math
import re
import time

import numpy as np
import pytest
from ultraglide.apps.demo.felt import SPEEDS_MM_S, FeltContrast, finger_speed_mm_s
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.planning import swipe_contrast
from ultraglide.textures import procedural
from ultraglide.textures.fileformat import save_texture


def test_the_fingers_speed_is_its_path_over_the_last_150_ms():
    # 10 px every 10 ms at 0.25 mm a pixel: 250 mm/s; a report older than 150 ms is left out
    trace = [(0.0, 0.0, 0.0)] + [(1.0 + k * 0.01, 500.0 + 6 * k, 300.0 + 8 * k) for k in range(10)]
    assert finger_speed_mm_s(trace, 0.25, 1.09) == pytest.approx(250.0)
    assert finger_speed_mm_s(trace[:2], 0.25, 1.0) is None  # too few reports
    resting = [(1.0 + k * 0.01, 500.0, 300.0) for k in range(10)]
    assert finger_speed_mm_s(resting, 0.25, 1.09) is None


def test_a_busy_ui_reading_few_reports_takes_the_speed_from_its_last_three():
    # a report every 100 ms (a UI drawing slowly), 10 px each at 0.25 mm a pixel: 25 mm/s from the last three
    sparse = [(1.0 + k * 0.1, 500.0 + 10 * k, 300.0) for k in range(6)]
    assert finger_speed_mm_s(sparse, 0.25, 1.55) == pytest.approx(25.0)
    # but three reports spread over more than half a second say nothing about the finger now
    stale = [(1.0 + k * 0.3, 500.0 + 10 * k, 300.0) for k in range(3)]
    assert finger_speed_mm_s(stale, 0.25, 1.65) is None


def test_the_figures_are_the_planners_at_each_speed_and_interpolated_in_log_speed_between():
    texture = procedural.grating(2.0, (60.0, 40.0))
    model = load_model("dynamic")
    felt = FeltContrast()
    assert felt.at(texture, "dynamic", 100.0) is None  # nothing worked out yet
    felt.work_out(texture, "dynamic", model.dynamics, 0.2)
    table = {speed: swipe_contrast(texture, model.dynamics, speed, 0.2, longest_s=0.5) for speed in SPEEDS_MM_S}
    assert felt.at(texture, "dynamic", 100.0) == pytest.approx((table[100.0].planned, table[100.0].instantaneous))
    between = felt.at(texture, "dynamic", math.sqrt(50.0 * 100.0))  # half-way in log speed
    assert between[1] == pytest.approx((table[50.0].instantaneous + table[100.0].instantaneous) / 2)
    assert felt.at(texture, "dynamic", 1000.0) == felt.at(texture, "dynamic", 400.0)  # held at the ends


def test_figures_asked_for_another_floor_are_worked_out_anew_and_the_old_ones_never_given():
    # the demo's force keys move the floor within the plate's limit (0.17 at 0.5 N, 0.41 at 1.9 N for the default
    # model): figures worked out for the old floor must not be said for the new one
    texture = procedural.grating(4.0, (60.0, 40.0), ratio_range=(0.05, 1.0))
    model = load_model("dynamic")
    felt = FeltContrast()
    expected = {}
    for floor in (0.17, 0.41):
        kept = swipe_contrast(texture, model.dynamics, 100.0, floor, longest_s=0.5)
        expected[floor] = (kept.planned, kept.instantaneous)
    assert expected[0.17] != pytest.approx(expected[0.41], abs=0.02)  # the floor matters on this texture
    for floor in (0.17, 0.41):
        felt.request(texture, "dynamic", model, floor)
        deadline = time.perf_counter() + 60.0
        while (said := felt.at(texture, "dynamic", 100.0)) is None and time.perf_counter() < deadline:
            time.sleep(0.01)  # worked out in its own thread
        assert said == pytest.approx(expected[floor])


def test_the_status_line_says_the_contrast_kept_at_the_fingers_speed(tmp_path, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    path = save_texture(procedural.grating(4.0, (200.0, 150.0)).with_(name="coarse"), tmp_path / "coarse.png")
    app = DemoApp([path], model="dynamic", windowed=True, screen_width_mm=338.7)
    try:
        app.wait_ready()
        app.act("texture")
        pg = app.pg
        w, h = app.screen.get_size()
        y = (app.area.top + 150) / h
        said = None
        deadline = time.perf_counter() + 60
        k = 0
        while said is None and time.perf_counter() < deadline:  # a finger sliding to and fro at ~2 px a step
            x = (200 + abs((k % 400) - 200) * 2) / w
            pg.event.post(pg.event.Event(pg.FINGERDOWN if k == 0 else pg.FINGERMOTION, x=x, y=y, dx=0.0, dy=0.0,
                                         finger_id=1, touch_id=1, pressure=1.0))
            app.step()
            said = re.search(r"felt at (\d+) mm/s: (\d+) % of its contrast \(asked instantly, (\d+) %\)",
                             app.status_words())
            k += 1
            time.sleep(0.004)
        assert said is not None, app.status_words()
        texture = app.scenes.current
        model = load_model("dynamic")
        floor = float(model.relative_friction(np.array([app.link.profile.max_amplitude_um_pp]), app.force_n)[0])
        speed = float(said[1])
        logs = [math.log(s) for s in SPEEDS_MM_S]
        kept = [swipe_contrast(texture, model.dynamics, s, floor, longest_s=0.5) for s in SPEEDS_MM_S]
        where = min(max(math.log(speed), logs[0]), logs[-1])
        planned = np.interp(where, logs, [k.planned for k in kept])
        instantaneous = np.interp(where, logs, [k.instantaneous for k in kept])
        assert abs(int(said[2]) - 100 * planned) <= 2 and abs(int(said[3]) - 100 * instantaneous) <= 2
    finally:
        app.close()


def test_figures_for_a_floor_no_longer_asked_for_are_given_up_before_any_swipe():
    """A force key held down asks for a new floor at each step; a worker whose floor was superseded stops before
    its next swipe instead of rendering all five. Its dynamics here are no dynamics at all: a swipe started with
    them would raise."""
    texture = procedural.grating(2.0, (60.0, 40.0))
    felt = FeltContrast()
    felt.work_out(texture, "dynamic", load_model("dynamic").dynamics, 0.41)  # the figures for the floor now asked
    felt.work_out(texture, "dynamic", object(), 0.17)  # a worker started for the floor asked before: gives up
    assert felt.at(texture, "dynamic", 100.0) is not None
    with pytest.raises(AttributeError):  # a worker for the floor asked now does swipe
        felt.work_out(texture, "dynamic", object(), 0.41)
