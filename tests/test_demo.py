"""The demo: headless with SDL's dummy driver, and a real window under Xvfb driven by xdotool."""

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture
from xvfb_demo import XvfbDemo, descendants, tools_missing

ARTIFACTS = ROOT / "artifacts" / "screenshots"


@pytest.fixture
def halves(tmp_path):
    """A 200 × 150 mm texture: slippery (0.2) on the left, at rest (1.0) on the right."""
    values = np.ones((150, 200), np.float32)
    values[:, :100] = 0.2
    return save_texture(Texture(values, 200.0, 150.0, outside="clamp", name="halves"), tmp_path / "halves.png")


@pytest.fixture
def app(halves, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    demo = DemoApp([halves], windowed=True, screen_width_mm=338.7)  # 1280 px: 0.2646 mm a pixel
    demo.wait_ready()
    yield demo
    demo.close()


@pytest.fixture
def plate():
    """The simulated plate served in the test's process on a real pty: the demo's engine drives it through
    the real serial driver, and the test reads the plate's own amplitude beside it."""
    from ultraglide.devices.profiles import load_profile
    from ultraglide.devices.sim.pty_plate import PtyPlate

    served = PtyPlate(load_profile("sim-plate")).start()
    yield served
    served.stop()


@pytest.fixture
def plated(halves, plate, monkeypatch):
    """The demo on the plate above."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    demo = DemoApp([halves], device_url=f"serial:{plate.path}", windowed=True, screen_width_mm=338.7)
    demo.wait_ready()
    demo.plate = plate
    yield demo
    demo.close()


def post(pg, kind, **fields):
    pg.event.post(pg.event.Event(kind, **fields))


def run_for(app, seconds):
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        app.step()
        time.sleep(0.001)


def finger(pg, kind, x, y, finger_id=1):
    post(pg, kind, x=x, y=y, dx=0.0, dy=0.0, finger_id=finger_id, touch_id=1, pressure=1.0)


def measured(app):
    """The plate's own amplitude, µm p-p (the simulated plate served beside the demo)."""
    return app.plate.simulator.amplitude_um_pp


def run_until(app, condition, timeout_s=30.0):
    """Step the demo until ``condition()`` holds (True) or the deadline passes (False)."""
    deadline = time.perf_counter() + timeout_s
    while time.perf_counter() < deadline:
        app.step()
        if condition():
            return True
        time.sleep(0.002)
    return False


def engine(app):
    return app.link.status(0.0).engine


def test_touch_positions_reach_the_renderer_in_millimetres(app):
    pg = app.pg
    app.act("texture")
    w, h = app.screen.get_size()
    x_px, y_px = 200, app.area.top + 100
    finger(pg, pg.FINGERDOWN, x_px / w, y_px / h)
    assert run_until(app, lambda: engine(app).last_touch is not None)  # the engine's block path took it
    x_mm, y_mm, force_n, down = engine(app).last_touch
    assert x_mm == pytest.approx(x_px * app.mm_per_px, abs=0.3)
    assert y_mm == pytest.approx(100 * app.mm_per_px, abs=0.3)
    assert down


def test_the_plate_follows_the_texture_under_the_finger(plated):
    app = plated
    pg = app.pg
    app.act("texture")
    w, h = app.screen.get_size()
    y = (app.area.top + 150) / h
    finger(pg, pg.FINGERDOWN, 100 / w, y)  # left: slippery, strong vibration
    for i in range(30):
        finger(pg, pg.FINGERMOTION, (100 + i) / w, y)
        run_for(app, 0.01)
    assert run_until(app, lambda: measured(app) > 3.0), measured(app)  # slippery: strong vibration
    for i in range(60):  # slide across into the right half: at rest
        finger(pg, pg.FINGERMOTION, (130 + i * 10) / w, y)
        run_for(app, 0.01)
    assert run_until(app, lambda: measured(app) < 0.3), measured(app)
    finger(pg, pg.FINGERUP, 700 / w, y)
    assert run_until(app, lambda: measured(app) < 0.05), measured(app)


def test_mouse_drives_but_its_copies_of_touches_are_ignored(plated):
    app = plated
    pg = app.pg
    app.act("texture")
    y = app.area.top + 150
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, y), button=1, touch=True)
    post(pg, pg.MOUSEMOTION, pos=(110, y), rel=(10, 0), buttons=(1, 0, 0), touch=True)
    run_for(app, 0.05)
    assert app.pushed == 0  # synthesised from a touch: not counted twice
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, y), button=1, touch=False)
    post(pg, pg.MOUSEMOTION, pos=(110, y), rel=(10, 0), buttons=(1, 0, 0), touch=False)
    assert run_until(app, lambda: measured(app) > 3.0), measured(app)
    assert app.pushed == 2 and engine(app).touches == 2
    assert engine(app).last_touch[0] == pytest.approx(110 * app.mm_per_px, abs=0.1)
    post(pg, pg.MOUSEBUTTONUP, pos=(110, y), button=1, touch=False)
    assert run_until(app, lambda: measured(app) < 0.05), measured(app)


def test_second_finger_is_shown_but_does_not_drive(plated):
    app = plated
    pg = app.pg
    app.act("texture")
    w, h = app.screen.get_size()
    y = (app.area.top + 150) / h
    finger(pg, pg.FINGERDOWN, 700 / w, y, finger_id=1)  # at rest side
    finger(pg, pg.FINGERDOWN, 100 / w, y, finger_id=2)  # slippery side, but second
    finger(pg, pg.FINGERMOTION, 105 / w, y, finger_id=2)
    assert run_until(app, lambda: engine(app).touches >= 1)
    run_for(app, 0.3)
    assert set(app.fingers) == {1, 2} and app.driving == 1
    assert engine(app).touches == 1 and engine(app).last_touch[0] == pytest.approx(700 * app.mm_per_px, abs=0.3)
    assert measured(app) < 0.3


def test_toolbar_and_keys_switch_scene_force_model_and_pause(app):
    pg = app.pg
    center = lambda action: next(b.rect.center for b in app.buttons if b.action == action)  # noqa: E731
    post(pg, pg.KEYDOWN, key=pg.K_g, mod=0, unicode="g", scancode=0)
    run_for(app, 0.05)
    assert app.scene == "gallery"
    post(pg, pg.MOUSEBUTTONDOWN, pos=center("widgets"), button=1, touch=False)
    run_for(app, 0.05)
    assert app.scene == "widgets" and run_until(app, lambda: engine(app).texture == "widgets"), engine(app).texture
    force = engine(app).force_n
    post(pg, pg.KEYDOWN, key=pg.K_UP, mod=0, unicode="", scancode=0)
    post(pg, pg.MOUSEBUTTONDOWN, pos=center("model"), button=1, touch=False)
    run_for(app, 0.05)
    assert run_until(app, lambda: engine(app).force_n == pytest.approx(force * 1.25)), engine(app).force_n
    # the model button steps from the default, dynamic (stretched with the published dynamics), to the next
    # with the dynamics kept; the link's name changes once the engine took it (the engine names the kind alone)
    assert app.model_name == "dynamic:squeeze-film" and \
        run_until(app, lambda: app.link.model_name == "dynamic:squeeze-film"), app.link.model_name
    assert engine(app).model == "dynamic"
    post(pg, pg.MOUSEBUTTONDOWN, pos=(600, app.area.top + 100), button=1, touch=False)  # a finger on: it runs
    assert run_until(app, lambda: engine(app).state == "running"), engine(app).state
    post(pg, pg.KEYDOWN, key=pg.K_SPACE, mod=0, unicode=" ", scancode=0)
    run_for(app, 0.05)
    assert app.user_paused and run_until(app, lambda: engine(app).state == "paused"), engine(app).state
    post(pg, pg.KEYDOWN, key=pg.K_ESCAPE, mod=0, unicode="", scancode=0)
    run_for(app, 0.05)
    assert not app.running


def test_the_model_key_keeps_a_dynamic_models_dynamics_and_comes_back_to_it(halves, monkeypatch):
    """Started with ``--model dynamic`` (planning against the finger's dynamics), the M key steps through the
    built-in models with the dynamics kept, and round to the start again; before, it fell to static models."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    demo = DemoApp([halves], model="dynamic", windowed=True, screen_width_mm=338.7)
    try:
        demo.wait_ready()
        pg = demo.pg
        seen = []
        for _ in range(4):
            post(pg, pg.KEYDOWN, key=pg.K_m, mod=0, unicode="m", scancode=0)
            # the link's model changes once the engine took it (a pipe round trip); a dynamic model's status
            # names its kind, "dynamic", whatever the static model inside (before: "squeeze-film", static)
            assert run_until(demo, lambda: demo.link.model_name != (seen or ["dynamic"])[-1]), demo.model_name
            assert run_until(demo, lambda: engine(demo).model == "dynamic"), engine(demo).model
            seen.append(demo.link.model_name)
        assert seen == ["dynamic:squeeze-film", "dynamic:exponential", "dynamic:paper", "dynamic"]
    finally:
        demo.close()


def test_the_demos_engine_is_forked_from_it_not_spawned(app):
    """Its process is started on the demo's one thread, so it begins with what the demo imported (in a test
    worker: numba and the kernels, a second of CPU a spawned interpreter would spend again)."""
    engine = app.link.engine.process.pid
    own = Path(f"/proc/{os.getpid()}/cmdline").read_bytes()
    assert Path(f"/proc/{engine}/cmdline").read_bytes() == own  # a spawned one runs multiprocessing's spawn_main


def test_a_texture_named_on_the_command_line_is_on_screen_at_once(app):
    """``demo halves.png --record drag.csv``: the finger is on halves at once, not on the gallery."""
    assert app.scene == "texture" and app.scenes.current.name == "halves"
    assert run_until(app, lambda: engine(app).texture == "halves"), engine(app).texture


def test_a_burst_of_moves_reaches_the_engine_as_the_newest(app):
    """A loop that fell behind finds twenty moves queued: the engine gets where the finger is now, once, not
    twenty positions stamped within a millisecond (a jump the renderer would blur over centimetres)."""
    pg = app.pg
    y = app.area.top + 100
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, y), button=1, touch=False)
    assert run_until(app, lambda: engine(app).touches == 1)
    for x in range(110, 310, 10):
        post(pg, pg.MOUSEMOTION, pos=(x, y), rel=(10, 0), buttons=(1, 0, 0), touch=False)
    app.step()
    assert app.pushed == 2 and run_until(app, lambda: engine(app).touches == 2)
    assert engine(app).last_touch[0] == pytest.approx(300 * app.mm_per_px, abs=0.1)


def test_bursts_keep_each_pointers_newest_move_and_every_press_and_lift():
    from types import SimpleNamespace

    from ultraglide.apps.demo.input import newest_motions

    pg = SimpleNamespace(FINGERDOWN=1, FINGERMOTION=2, FINGERUP=3, MOUSEBUTTONDOWN=4, MOUSEMOTION=5, MOUSEBUTTONUP=6)

    def finger(kind, finger_id, x):
        return SimpleNamespace(type=kind, finger_id=finger_id, x=x)

    events = [finger(2, 1, 0.1), finger(2, 2, 0.5), finger(2, 1, 0.2), finger(3, 1, 0.25), finger(1, 1, 0.3),
              finger(2, 1, 0.4), finger(2, 1, 0.45), finger(2, 2, 0.6), SimpleNamespace(type=5, touch=False, x=1),
              SimpleNamespace(type=5, touch=True, x=2), SimpleNamespace(type=5, touch=False, x=3)]
    kept = [(e.type, getattr(e, "finger_id", None), e.x) for e in newest_motions(events, pg)]
    assert kept == [(2, 1, 0.2), (3, 1, 0.25), (1, 1, 0.3), (2, 1, 0.45), (2, 2, 0.6), (5, None, 2), (5, None, 3)]


def test_gallery_tap_chooses_a_texture(app):
    pg = app.pg
    app.act("gallery")
    tile = app.tiles[0]
    post(pg, pg.MOUSEBUTTONDOWN, pos=tile.center, button=1, touch=False)
    run_for(app, 0.05)
    assert app.scene == "texture" and run_until(app, lambda: engine(app).texture == "halves"), engine(app).texture


def test_closing_rests_the_plate(plated):
    app = plated
    pg = app.pg
    app.act("texture")
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, app.area.top + 150), button=1, touch=False)
    assert run_until(app, lambda: measured(app) > 3.0), measured(app)
    simulator = app.plate.simulator
    app.close()
    assert not simulator.enabled and simulator.amplitude_um_pp < 0.5  # disabled before close() returned
    assert not app.link.engine.alive and app.final_status.state == "stopped"


def test_panel_pressure_sets_the_force_only_where_the_panel_reports_it(app):
    pg = app.pg
    app.act("texture")
    w, h = app.screen.get_size()
    y = (app.area.top + 150) / h
    post(pg, pg.FINGERDOWN, x=100 / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
    assert run_until(app, lambda: engine(app).touches == 1)
    assert np.isnan(engine(app).last_touch[2])  # 1.0 from a panel without a sensor: the default
    assert "Up/Down keys" in app.status_words()
    post(pg, pg.FINGERMOTION, x=120 / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=0.3)
    assert run_until(app, lambda: engine(app).touches == 2)
    assert engine(app).last_touch[2] == pytest.approx(0.3 * 2.0)  # PRESSURE_FULL_SCALE_N
    assert "touch pressure" in app.status_words()


def test_status_line_says_device_state_model_force_limits_and_faults(app):
    import re

    words = app.status_words()
    for phrase in ("simulated plate running", "dynamic model", "0.50 N (Up/Down keys)",
                   "within the plate's limit on this texture", "H: help"):
        assert phrase in words, words
    # a loaded machine may starve the simulated plate: then its faults are named and counted
    assert re.search(r"running, (no faults|faults: [a-z-]+ ×\d+)", words) and re.search(r"\d+ underruns?,", words)
    app.act("force+")
    app.act("model")
    run_for(app, 0.05)
    assert "0.62 N" in app.status_words() and "dynamic:squeeze-film model" in app.status_words()


def test_limited_share_is_measured_and_resets_with_the_texture(tmp_path, monkeypatch, halves):
    """A texture asking for no friction at all is beyond any plate: every sample is limited, until the texture
    changes, when the count starts again."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    unreachable = save_texture(Texture(np.zeros((50, 80), np.float32), 80.0, 50.0, outside="clamp",
                                       name="unreachable"), tmp_path / "unreachable.png")
    app = DemoApp([unreachable, halves], windowed=True, screen_width_mm=338.7)
    try:
        app.wait_ready()
        pg = app.pg
        app.act("texture")
        y = app.area.top + 50
        post(pg, pg.MOUSEBUTTONDOWN, pos=(60, y), button=1, touch=False)
        for i in range(40):
            post(pg, pg.MOUSEMOTION, pos=(60 + i, y), rel=(1, 0), buttons=(1, 0, 0), touch=False)
            run_for(app, 0.02)
        # the engine's share is of the last second's samples: a finger held a second longer fills it
        assert run_until(app, lambda: app.link.status().limited_pct > 90, 10), app.link.status()
        status = app.link.status()
        assert status.limited_samples > 0.5 * 12000 * 0.9, status
        assert "held at the limit" in app.status_words() and "samples on this texture" in app.status_words()
        post(pg, pg.MOUSEBUTTONUP, pos=(100, y), button=1, touch=False)
        run_for(app, 0.05)
        app.act("next")  # halves: the right half is at rest, nothing to limit
        assert app.link.status().limited_samples == 0
        post(pg, pg.MOUSEBUTTONDOWN, pos=(900, y), button=1, touch=False)
        run_for(app, 0.5)
        assert app.link.status().limited_samples == 0 and app.link.status().limited_pct == 0
    finally:
        app.close()


@pytest.mark.parametrize("width_px", [1024, 1280, 1600])
def test_the_status_line_fits_and_keeps_help_the_recording_and_watch_errors(halves, tmp_path, monkeypatch, width_px):
    """Two lines at any common width: each fits; help, the recording and --watch's errors are always on them."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp
    from ultraglide.apps.demo.draw import ACCENT
    from ultraglide.apps.demo.status import HELP, SEPARATOR, status_lines

    app = DemoApp([halves], windowed=True, size=(width_px, 800), record=str(tmp_path / "drag.csv"))
    try:
        app.wait_ready()
        app.watch_errors = ["cannot reload halves.png: the file is not a PNG image (it may be half-written)",
                            "cannot reload wood.png: no such file"]
        app.user_paused = True
        first, second = status_lines(app, app.font, width_px)
        help_w = app.font.size(SEPARATOR + HELP)[0]
        assert app.font.size(SEPARATOR.join(text for text, _ in first))[0] <= width_px - 16 - help_w
        assert app.font.size(SEPARATOR.join(text for text, _ in second))[0] <= width_px - 16
        line = SEPARATOR.join(text for text, _ in first + second)
        assert "simulated plate paused" in line or "sim paused" in line
        assert "recording drag.csv: 0 touches" in line or "rec 0" in line
        assert "cannot reload halves.png" in line and "cannot reload wood.png" in line
        if width_px >= 1280:  # everything the plate does, in words, at the widths of common screens
            assert "dynamic model" in line and "0.50 N" in line and "within the plate's limit" in line
        app.painter.status(force=True)
        pixels = app.pg.surfarray.array3d(app.screen)
        rect = app.layout.status_rect
        help_area = pixels[rect.right - 8 - app.font.size(HELP)[0]:rect.right - 8, rect.top:rect.top + 25]
        assert np.all(help_area == ACCENT, axis=-1).sum() > 20  # "H: help" drawn at the right end
    finally:
        app.close()


def test_touches_before_the_engine_is_ready_are_drawn_counted_and_not_felt(halves, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    app = DemoApp([halves], windowed=True, screen_width_mm=338.7)
    try:
        pg = app.pg
        app.act("texture")
        post(pg, pg.MOUSEBUTTONDOWN, pos=(100, app.area.top + 150), button=1, touch=False)
        post(pg, pg.MOUSEMOTION, pos=(110, app.area.top + 150), rel=(10, 0), buttons=(1, 0, 0), touch=False)
        app.step()
        assert app.link is None  # the engine process is still importing numpy: it cannot be ready yet
        assert app.unfelt == 2 and "2 touches before it was ready: not felt" in app.status_words()
        app.wait_ready()
        assert engine(app).touches == 0  # nothing queued: a finger's old positions are never felt late
        post(pg, pg.MOUSEMOTION, pos=(120, app.area.top + 150), rel=(10, 0), buttons=(1, 0, 0), touch=False)
        assert run_until(app, lambda: engine(app).touches == 1)
    finally:
        app.close()


def _rewrite(path, left_ratio, in_place):
    """Save the halves texture with another left half: atomically (a new file renamed over it, as most
    editors save) or in place (the same file truncated and written, as others do)."""
    values = np.ones((150, 200), np.float32)
    values[:, :100] = left_ratio
    other = save_texture(Texture(values, 200.0, 150.0, outside="clamp", name="halves"),
                         path.with_name("next-" + path.name))
    if in_place:
        data = other.read_bytes()
        other.unlink()
        with open(path, "r+b") as file:
            file.truncate(0)
            file.write(data)
    else:
        os.replace(other, path)


def test_watch_reloads_a_changed_texture_file_and_the_plate_feels_it(halves, plate, monkeypatch):
    """The finger rests on the left half; the file is rewritten under it (atomically, then in place):
    the plate's own amplitude follows each new texture."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    app = DemoApp([halves], device_url=f"serial:{plate.path}", windowed=True, screen_width_mm=338.7, watch=True)
    try:
        app.plate = plate
        app.wait_ready()
        pg = app.pg
        app.act("texture")
        post(pg, pg.MOUSEBUTTONDOWN, pos=(100, app.area.top + 150), button=1, touch=False)
        assert run_until(app, lambda: measured(app) > 3.0), measured(app)  # 0.2: slippery
        _rewrite(Path(halves), 1.0, in_place=False)
        assert run_until(app, lambda: measured(app) < 0.3), measured(app)  # 1.0: at rest
        _rewrite(Path(halves), 0.2, in_place=True)
        assert run_until(app, lambda: measured(app) > 3.0), measured(app)
        assert app.textures[0].values[0, 0] == pytest.approx(0.2, abs=1e-3) and not app.watch_errors
    finally:
        app.close()


def test_widgets_are_laid_out_for_the_screen(app):
    app.act("widgets")
    texture, placements = app.widgets
    assert texture.width_mm == pytest.approx(app.area.width * app.mm_per_px, rel=1e-3)
    assert texture.height_mm == pytest.approx(app.area.height * app.mm_per_px, rel=1e-3)
    boxes = [(p.x_mm, p.y_mm, p.x_mm + p.texture.width_mm, p.y_mm + p.texture.height_mm) for p in placements]
    for left, top, right, bottom in boxes:
        assert 0 <= left < right <= texture.width_mm and 0 <= top < bottom <= texture.height_mm
    for i, a in enumerate(boxes):  # no two overlap
        for b in boxes[i + 1:]:
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
    used = sum((r - left) * (b - t) for left, t, r, b in boxes)
    assert used > 0.25 * texture.width_mm * texture.height_mm  # they use the screen, not a corner of it


def test_labels_are_shortened_to_fit(app):
    from ultraglide.apps.demo.draw import fit_text

    long = "a texture with a very long name indeed, longer than any tile"
    short = fit_text(app.font, long, 120)
    assert short.endswith("…") and app.font.size(short)[0] <= 120 and long.startswith(short[:-1])
    assert fit_text(app.font, "wood", 120) == "wood"
    for tile, texture in zip(app.tiles, app.textures, strict=True):
        assert app.font.size(fit_text(app.font, texture.name, tile.width - 8))[0] <= tile.width - 8


def test_chart_puts_values_on_its_scales(app):
    """Friction steps from 1 to 0.25 at -1500 ms; 3 µm commanded on a 6 µm full scale; the limit at 4.5 µm."""
    from ultraglide.apps.demo.draw import CHART_COLOURS, LIMIT, draw_chart

    surface = app.pg.Surface((1000, 200))
    t = np.linspace(10.0, 13.0, 3001)
    friction = np.column_stack((t, np.where(t < 11.5, 1.0, 0.25)))
    commanded = np.column_stack((t, np.full_like(t, 3.0)))
    plot = draw_chart(surface, app.font, surface.get_rect(), {"friction": friction, "commanded": commanded},
                      3.0, 6.0, 4.5, "plate µm p-p")
    pixels = app.pg.surfarray.array3d(surface)  # (x, y, rgb)

    def rows_of(colour, x):
        return np.flatnonzero(np.all(pixels[x, plot.top:plot.bottom + 1] == colour, axis=1)) + plot.top

    quarter, three_quarters = plot.left + plot.width // 4, plot.left + 3 * plot.width // 4
    assert abs(np.median(rows_of(CHART_COLOURS["friction"], quarter)) - plot.top) <= 2  # ratio 1 at the top
    assert abs(np.median(rows_of(CHART_COLOURS["friction"], three_quarters)) - (plot.bottom - 0.25 * plot.height)) <= 2
    assert abs(np.median(rows_of(CHART_COLOURS["commanded"], quarter)) - (plot.bottom - 0.5 * plot.height)) <= 2
    limit_rows = [rows_of(LIMIT, x) for x in range(plot.left, plot.left + 12)]
    assert abs(np.median(np.concatenate(limit_rows)) - (plot.bottom - 0.75 * plot.height)) <= 1
    step_row = int(plot.bottom - 0.6 * plot.height)  # the step's vertical edge, halfway along the time axis
    edge = np.flatnonzero(np.all(pixels[plot.left:plot.right, step_row] == CHART_COLOURS["friction"], axis=1))
    assert abs(np.median(edge) + plot.left - plot.centerx) <= 2


def test_chart_draws_a_fine_texture_as_its_envelope_not_an_aliased_block(app):
    """A 1 mm grating under a finger at 100 mm/s: friction swings 0.4-1.0 at 100 Hz, 3 periods in 10 columns.
    Drawn as lines it filled the plot in solid colour; drawn as its envelope it is a translucent band from
    0.4 to 1.0 with an outline, and a steady stretch after it is still a line."""
    from ultraglide.apps.demo.draw import BAND_ALPHA, CHART_COLOURS, GRID, LIMIT, PANEL, draw_chart

    surface = app.pg.Surface((1000, 200))
    t = np.arange(0.0, 3.0, 1 / 12000)
    friction = np.where(t < 2.0, 0.7 + 0.3 * np.sin(2 * np.pi * 100 * t), 0.5)
    plot = draw_chart(surface, app.font, surface.get_rect(), {"friction": np.column_stack((t, friction))},
                      3.0, 8.0, 6.0, "plate µm p-p")
    pixels = app.pg.surfarray.array3d(surface).astype(int)
    colour = np.array(CHART_COLOURS["friction"])
    blended = (np.array(PANEL) * (1 - BAND_ALPHA) + colour * BAND_ALPHA).astype(int)  # the band over the panel
    over_grid = (np.array(GRID) * (1 - BAND_ALPHA) + colour * BAND_ALPHA).astype(int)  # and over a gridline
    row_of = lambda ratio: plot.bottom - ratio * plot.height  # noqa: E731
    for x in range(plot.left + 50, plot.left + plot.width * 2 // 3 - 10, 7):
        column = pixels[x, plot.top + 1:plot.bottom]
        solid = np.flatnonzero(np.all(column == colour, axis=1)) + plot.top + 1
        assert len(solid) <= 3, (x, solid)  # the outline's top and bottom, not a block of line
        band = np.flatnonzero(np.minimum(np.abs(column - blended).sum(axis=1),
                                         np.abs(column - over_grid).sum(axis=1)) <= 6) + plot.top + 1
        assert abs(band.min() - row_of(1.0)) <= 2 and abs(band.max() - row_of(0.4)) <= 2, (x, band.min(), band.max())
    steady = plot.left + plot.width * 5 // 6
    solid = np.flatnonzero(np.all(pixels[steady, plot.top:plot.bottom] == colour, axis=1)) + plot.top
    assert abs(np.median(solid) - row_of(0.5)) <= 1.5 and len(solid) <= 3  # a line at 0.5
    y_limit = round(row_of(0.75))  # the limit, 6 of 8 µm, where the friction axis has its 0.75 gridline
    assert not np.all(pixels[plot.left + 1:plot.right - 1, y_limit] == GRID, axis=1).any()
    assert np.all(pixels[plot.left:plot.left + 6, y_limit] == LIMIT, axis=1).all()  # the limit's first dash


@pytest.mark.parametrize("outside", ["tile", "clamp"])
def test_a_texture_smaller_than_the_screen_shows_its_edge(tmp_path, monkeypatch, outside):
    """A 40 × 30 mm texture on a 338 mm wide screen: outlined where it ends; its repeats, when it tiles, are
    drawn fainter than itself, so the eye tells the texture from what lies beyond it."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp
    from ultraglide.apps.demo.draw import EDGE

    values = np.tile(np.linspace(0.2, 1.0, 40, dtype=np.float32), (30, 1))
    small = save_texture(Texture(values, 40.0, 30.0, outside=outside, name="small"), tmp_path / "small.png")
    app = DemoApp([small], device_url="null", windowed=True, screen_width_mm=338.7)
    try:
        app.painter.area()
        pixels = app.pg.surfarray.array3d(app.screen).astype(int)
        area = app.layout.area
        w, h = round(40.0 / app.mm_per_px), round(30.0 / app.mm_per_px)
        right = pixels[area.left + w, area.top + 5:area.top + h - 5]
        bottom = pixels[area.left + 5:area.left + w - 5, area.top + h]
        assert np.all(right == EDGE) and np.all(bottom == EDGE)
        inside = pixels[area.left + 5:area.left + w - 5, area.top + 5:area.top + h - 5]
        beyond = pixels[area.left + w + 5:area.left + 2 * w - 5, area.top + 5:area.top + h - 5]
        if outside == "tile":  # the same pattern, fainter
            assert 0.3 * inside.mean() < inside.mean() - beyond.mean()
            assert np.corrcoef(inside.mean(axis=(1, 2)), beyond.mean(axis=(1, 2)))[0, 1] > 0.99
        else:  # the outside rule's colour: the edge's own friction (1.0), flat
            assert beyond.std(axis=(0, 1)).max() < 1
    finally:
        app.close()


def test_recording_survives_a_crash_and_is_renamed_when_done(tmp_path):
    from ultraglide.apps.demo.record import TouchRecorder
    from ultraglide.render.touch_log import read_touch_log

    path = tmp_path / "log.csv"
    recorder = TouchRecorder(path)
    geometry = {"screen_px": [1280, 800], "mm_per_px": 0.25}
    recorder.touch(10.0, 1.0, 2.0, None, "wood", geometry)
    recorder.touch(10.5, 3.0, 2.5, 0.7, "wood", geometry)
    recorder.lift(10.6)
    recorder.touch(11.0, 4.0, 2.0, None, "grating-1mm", geometry)
    partial = read_touch_log(tmp_path / "log.csv.part")  # as a crash would leave it: every row there
    assert list(partial.t_s) == [0.0, 0.5, 1.0] and list(partial.x_mm) == [1.0, 3.0, 4.0]
    assert list(partial.force_n) == [0.5, 0.7, 0.5]
    assert not path.exists()
    assert recorder.close() == path and path.exists() and not (tmp_path / "log.csv.part").exists()
    text = path.read_text()
    assert '"texture": "wood"' in text and "# lift at t_s=0.600000" in text and '# texture "grating-1mm"' in text
    empty = TouchRecorder(tmp_path / "empty.csv")
    assert empty.close() is None and not list(tmp_path.glob("empty.csv*"))


def test_bad_model_found_after_the_first_frame_is_still_one_line():
    """The renderer starts after the window is up; its errors still end the demo with one line."""
    result = run_cli("demo", "--windowed", "--model", "table:/nonexistent.csv", env={"SDL_VIDEODRIVER": "dummy"})
    assert "nonexistent.csv" in assert_one_line_error(result)
    assert "first frame drawn" in result.stdout


def test_bad_record_and_stats_names_are_one_line(tmp_path):
    result = run_cli("demo", "--record", tmp_path / "log.txt", env={"SDL_VIDEODRIVER": "dummy"})
    assert "--record needs a .csv file" in assert_one_line_error(result)
    result = run_cli("demo", "--stats", tmp_path / "s.txt", env={"SDL_VIDEODRIVER": "dummy"})
    assert "--stats needs a .json file" in assert_one_line_error(result)
    result = run_cli("demo", "--record", tmp_path / "missing" / "log.csv", env={"SDL_VIDEODRIVER": "dummy"})
    line = assert_one_line_error(result)  # refused before any work, as every output (test_outputs_checked.py)
    assert line.count("--record") == 1 and f"{tmp_path / 'missing'} does not exist" in line
    assert not list(tmp_path.iterdir())


def test_no_display_is_one_clear_line():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")}
    result = subprocess.run([sys.executable, "-m", "ultraglide", "demo"], capture_output=True, text=True, env=env,
                            cwd=ROOT, timeout=60)
    assert "ultraglide export" in assert_one_line_error(result)


needs_xvfb = pytest.mark.skipif(bool(tools_missing()), reason="needs Xvfb, xdotool and ImageMagick "
                                                                  "(./run tests installs them)")


@needs_xvfb
def test_demo_under_xvfb_driven_by_xdotool(tmp_path):
    """Each scene is on screen when the demo says it has drawn it: no sleeps, screenshots never black."""
    with XvfbDemo() as demo:
        demo.wait_for("first frame drawn", 60)
        demo.wait_for("^frame drawn: gallery", 30)
        screenshots = [demo.shot(ARTIFACTS / "1-gallery.png")]
        demo.wait_for("^renderer ready", 60)
        demo.xdo("mousemove", 110, 100, "click", 1)  # the first tile
        demo.wait_for("^frame drawn: texture", 30)
        demo.drag([(x, 300) for x in range(200, 700, 10)])
        screenshots.append(demo.shot(ARTIFACTS / "2-texture.png"))
        demo.xdo("key", "w")
        demo.wait_for("^frame drawn: widgets$", 30)
        screenshots.append(demo.shot(ARTIFACTS / "3-widgets.png"))
        demo.xdo("key", "h")
        demo.wait_for("^frame drawn: widgets help", 30)
        screenshots.append(demo.shot(ARTIFACTS / "4-help.png"))
        assert demo.quit() == 0
    from PIL import Image

    pictures = [np.asarray(Image.open(path).convert("RGB"), dtype=float) for path in screenshots]
    for picture in pictures:
        assert picture.shape == (800, 1280, 3) and picture.std() > 10  # something was drawn
    for before, after in zip(pictures, pictures[1:], strict=False):
        assert np.abs(before - after).mean() > 3  # and each scene differs from the one before


@needs_xvfb
def test_demo_idles_cold_under_xvfb():
    """Nothing moves: the whole process tree (window, event loop, and the engine process with the renderer
    and the null device) uses at most 10 % of a core."""
    with XvfbDemo("--device", "null") as demo:
        demo.wait_for("^renderer ready", 120)  # after the first frames
        assert descendants(demo.demo.pid)  # the engine is a process of its own, counted below
        cpu_before, wall_before = demo.tree_cpu_s(), time.perf_counter()
        deadline = wall_before + 4.0
        while time.perf_counter() < deadline:  # CPU time, not wall time: sleeping costs nothing
            time.sleep(0.2)
        share = (demo.tree_cpu_s() - cpu_before) / (time.perf_counter() - wall_before)
        assert share <= 0.10, f"{share:.1%} of a core while idle"
        assert demo.quit() == 0


@needs_xvfb
def test_recorded_drag_replays_to_a_wav_that_follows_it(halves, tmp_path):
    """A drag from the slippery half into the sticky half, recorded, exported: the WAV's envelope is high
    exactly while the recorded finger was over the slippery half, and the log's positions are the pointer's."""
    import json

    import soundfile
    from ultraglide.render.touch_log import read_touch_log

    record, stats = tmp_path / "drag.csv", tmp_path / "stats.json"
    with XvfbDemo(str(halves), "--device", "null", "--record", str(record), "--stats", str(stats)) as demo:
        demo.wait_for("^renderer ready", 60)  # halves is on screen from the start, as the README runs it
        demo.wait_for("^frame drawn: texture", 30)
        # across the boundary (378 px), each move once the demo has taken the one before: moves sent on a timer
        # reached a loaded demo in bursts, stamped as it read them, a jump of millimetres in a millisecond
        # that the renderer's band limit (rightly) blurred across the boundary
        demo.drag_recorded([(x, 300) for x in range(100, 704, 4)], tmp_path / "drag.csv.part")
        assert demo.quit() == 0
    assert record.exists() and not (tmp_path / "drag.csv.part").exists()
    comments = [line for line in record.read_text().splitlines() if line.startswith("#")]
    meta = json.loads(comments[1][1:])
    assert meta["texture"] == "halves" and meta["screen_px"] == [1280, 800]
    log = read_touch_log(record)
    mm_per_px = meta["mm_per_px"]
    assert mm_per_px == pytest.approx(25.4 / 96)
    assert log.x_mm[0] == pytest.approx(100 * mm_per_px, abs=0.01)
    assert log.x_mm[-1] == pytest.approx(700 * mm_per_px, abs=0.01)
    assert np.allclose(log.y_mm, (300 - meta["texture_area_px"][1]) * mm_per_px, atol=0.01)
    assert len(log.t_s) > 50 and np.all(log.force_n == 0.5)

    wav = tmp_path / "drag.wav"
    # the static law, whose envelope follows the finger's position: the default plans the friction felt and raises
    # it before the sticky half by up to its horizon (100 ms), more than the margin below where a loaded demo's
    # drag lingers near the edge
    run_cli("export", halves, "--trajectory", record, "--model", "stretched", "-o", wav, check=True)
    signal, rate = soundfile.read(wav)
    window = rate // 1000  # 1 ms: 25 carrier periods
    envelope = np.abs(signal[: len(signal) // window * window]).reshape(-1, window).max(axis=1)
    t_ms = np.arange(len(envelope)) + 0.5
    x_at = np.interp(t_ms / 1000, log.t_s, log.x_mm)
    crossing_ms = 1000 * np.interp(100.0, log.x_mm, log.t_s)
    # away from the edge in time and in space: the lookup is bilinear on 1 mm texels, so within a texel of the edge
    # the finger feels a mix of the halves, however long a slow step of a loaded demo leaves it there
    settled = (t_ms > 30) & (np.abs(t_ms - crossing_ms) > 30) & (t_ms < 1000 * log.t_s[-1]) & (np.abs(x_at - 100) > 1)
    slippery, sticky = settled & (x_at < 100), settled & (x_at > 100)
    assert slippery.sum() > 50 and sticky.sum() > 50
    assert envelope[slippery].min() > 0.3, envelope[slippery].min()  # strong vibration over 0.2 friction
    assert envelope[sticky].max() < 0.02, envelope[sticky].max()  # at rest over 1.0

    figures = json.loads(stats.read_text())
    assert figures["blocks_rendered"] > 100 and figures["touches"] == len(log.t_s)
    assert figures["touches_received_by_engine"] == figures["touches"] + 1  # all, and the lift
    assert 0 < figures["block_p50_us"] <= figures["block_p99_us"]
    assert figures["underruns"] >= figures["underruns_at_first_touch"] >= 0 and figures["late_blocks"] >= 0


def test_bad_demo_texture_is_one_line(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"nope")
    result = run_cli("demo", str(tmp_path / "bad.png"), env={"SDL_VIDEODRIVER": "dummy"})
    assert "not an image" in assert_one_line_error(result)
    assert Path(tmp_path / "bad.png").exists()


@pytest.mark.slow
def test_closed_loop_shows_the_measured_friction_beside_the_target_and_says_the_loops_state(halves, monkeypatch):
    """--closed-loop on sim: a simulated finger (its law 30 % off the host's, with a floor) under the plate's force
    sensors; sliding on the slippery half (target 0.2), the loop follows, the status says so and, once it has
    learnt the finger, the chart draws the friction the sensors measure near the target."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp
    from ultraglide.apps.demo.draw import CHART_COLOURS
    from ultraglide.apps.demo.painter import CHART_SPAN_S
    from ultraglide.render.engine.finger_setup import FingerConfig

    finger_config = FingerConfig(drift=0.0, force="0.5")  # 0.2 within the limit's reach all along (0.105 at 6 µm)
    app = DemoApp([halves], windowed=True, screen_width_mm=338.7, closed_loop=True, finger=finger_config)
    try:
        app.wait_ready()
        pg = app.pg
        w, h = app.screen.get_size()
        y = (app.area.top + 150) / h
        finger(pg, pg.FINGERDOWN, 60 / w, y)
        began = time.perf_counter()
        state = {"x": 60.0}

        def slide_and_follow():
            # back and forth on the slippery half (ratio 0.2), 40-320 px at about 120 mm/s whatever the UI's pace
            phase = ((time.perf_counter() - began) * 450.0) % 560.0
            state["x"] = 40.0 + (phase if phase < 280.0 else 560.0 - phase)
            finger(pg, pg.FINGERMOTION, state["x"] / w, y)
            return "closed loop: following" in app.status_words()

        assert run_until(app, slide_and_follow, 60.0), app.status_words()
        learnt = time.perf_counter() + 2.0  # the loop's first seconds: it learns the finger (as the bench allows)
        seen = {"measured": np.array([])}

        def learnt_and_near_the_target():
            slide_and_follow()
            if time.perf_counter() < learnt:
                return False
            chart = app.link.status(CHART_SPAN_S).chart
            recent = chart[chart[:, 0] > chart[-1, 0] - 1.5]
            seen["measured"] = measured = recent[np.isfinite(recent[:, 4]), 4]
            # near the target, far from the 1.0 of a plate that does not vibrate (the loop's accuracy is the bench's)
            return len(measured) > 0 and abs(np.median(measured) - 0.2) < 0.15

        # waited for while sliding: a loaded machine may leave the finger a moment still (the loop then rests)
        assert run_until(app, learnt_and_near_the_target, 60.0), (seen["measured"], app.status_words())
        app.painter.everything()
        pixels = pg.surfarray.array3d(app.screen)
        area = app.layout.chart_rect
        drawn = np.all(pixels[area.left:area.right, area.top:area.bottom] == CHART_COLOURS["measured"], axis=2)
        assert drawn.sum() > 50  # the measured friction's trace (and its legend)
        finger(pg, pg.FINGERUP, state["x"] / w, y)
        assert run_until(app, lambda: "open loop" in app.status_words(), 30.0), app.status_words()
    finally:
        app.close()
