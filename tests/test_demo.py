"""The demo: headless with SDL's dummy driver, and a real window under Xvfb driven by xdotool."""

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture

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
    from ultraglide.apps.demo_app import DemoApp

    demo = DemoApp([halves], windowed=True, screen_width_mm=338.7)  # 1280 px: 0.2646 mm a pixel
    demo.wait_ready()
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
    return app.link.device.telemetry.measured_um_pp


def test_touch_positions_reach_the_renderer_in_millimetres(app):
    pg = app.pg
    app._act("texture")
    w, h = app.screen.get_size()
    x_px, y_px = 200, app.area.top + 100
    finger(pg, pg.FINGERDOWN, x_px / w, y_px / h)
    run_for(app, 0.05)
    fit = app.link.renderer.trajectory._fit
    assert fit.x_ref == pytest.approx(x_px * app.mm_per_px, abs=0.3)
    assert fit.y_ref == pytest.approx(100 * app.mm_per_px, abs=0.3)
    assert fit.down


def test_the_plate_follows_the_texture_under_the_finger(app):
    pg = app.pg
    app._act("texture")
    w, h = app.screen.get_size()
    y = (app.area.top + 150) / h
    finger(pg, pg.FINGERDOWN, 100 / w, y)  # left: slippery, strong vibration
    for i in range(30):
        finger(pg, pg.FINGERMOTION, (100 + i) / w, y)
        run_for(app, 0.01)
    run_for(app, 0.3)
    slippery = measured(app)
    for i in range(60):  # slide across into the right half: at rest
        finger(pg, pg.FINGERMOTION, (130 + i * 10) / w, y)
        run_for(app, 0.01)
    run_for(app, 0.3)
    at_rest = measured(app)
    assert slippery > 3.0 and at_rest < 0.3, (slippery, at_rest)
    finger(pg, pg.FINGERUP, 700 / w, y)
    run_for(app, 0.2)
    assert measured(app) < 0.05


def test_mouse_drives_but_its_copies_of_touches_are_ignored(app):
    pg = app.pg
    app._act("texture")
    y = app.area.top + 150
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, y), button=1, touch=True)
    post(pg, pg.MOUSEMOTION, pos=(110, y), rel=(10, 0), buttons=(1, 0, 0), touch=True)
    run_for(app, 0.05)
    assert app.pushed == 0  # synthesised from a touch: not counted twice
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, y), button=1, touch=False)
    post(pg, pg.MOUSEMOTION, pos=(110, y), rel=(10, 0), buttons=(1, 0, 0), touch=False)
    run_for(app, 0.3)
    assert app.pushed == 2 and measured(app) > 3.0
    assert app.link.renderer.trajectory._fit.x_ref == pytest.approx(110 * app.mm_per_px, abs=0.1)  # merged
    post(pg, pg.MOUSEBUTTONUP, pos=(110, y), button=1, touch=False)
    run_for(app, 0.2)
    assert measured(app) < 0.05


def test_second_finger_is_shown_but_does_not_drive(app):
    pg = app.pg
    app._act("texture")
    w, h = app.screen.get_size()
    y = (app.area.top + 150) / h
    finger(pg, pg.FINGERDOWN, 700 / w, y, finger_id=1)  # at rest side
    finger(pg, pg.FINGERDOWN, 100 / w, y, finger_id=2)  # slippery side, but second
    finger(pg, pg.FINGERMOTION, 105 / w, y, finger_id=2)
    run_for(app, 0.3)
    assert set(app.fingers) == {1, 2} and app.driving == 1
    assert measured(app) < 0.3


def test_toolbar_and_keys_switch_scene_force_model_and_pause(app):
    pg = app.pg
    center = lambda action: next(b.rect.center for b in app.buttons if b.action == action)  # noqa: E731
    assert app.scene == "gallery"
    post(pg, pg.MOUSEBUTTONDOWN, pos=center("widgets"), button=1, touch=False)
    run_for(app, 0.05)
    assert app.scene == "widgets" and app.link.renderer.texture.name == "widgets"
    force = app.link.renderer.default_force_n
    post(pg, pg.KEYDOWN, key=pg.K_UP, mod=0, unicode="", scancode=0)
    post(pg, pg.MOUSEBUTTONDOWN, pos=center("model"), button=1, touch=False)
    run_for(app, 0.05)
    assert app.link.renderer.default_force_n == pytest.approx(force * 1.25)
    assert app.model_name == "paper" and app.link.renderer.model.name == "paper"
    post(pg, pg.KEYDOWN, key=pg.K_SPACE, mod=0, unicode=" ", scancode=0)
    run_for(app, 0.05)
    assert app.user_paused and app.link.renderer.paused
    post(pg, pg.KEYDOWN, key=pg.K_ESCAPE, mod=0, unicode="", scancode=0)
    run_for(app, 0.05)
    assert not app.running


def test_gallery_tap_chooses_a_texture(app):
    pg = app.pg
    tile = app.tiles[0]
    post(pg, pg.MOUSEBUTTONDOWN, pos=tile.center, button=1, touch=False)
    run_for(app, 0.05)
    assert app.scene == "texture" and app.link.renderer.texture.name == "halves"


def test_closing_rests_the_plate(app):
    pg = app.pg
    app._act("texture")
    post(pg, pg.MOUSEBUTTONDOWN, pos=(100, app.area.top + 150), button=1, touch=False)
    run_for(app, 0.3)
    assert measured(app) > 3.0
    plate = app.link.device.plate
    app.close()
    assert not plate.simulator.enabled and plate.simulator.amplitude_um_pp < 0.5


def test_no_display_is_one_clear_line():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")}
    result = subprocess.run([sys.executable, "-m", "ultraglide", "demo"], capture_output=True, text=True, env=env,
                            cwd=ROOT, timeout=60)
    assert "ultraglide export" in assert_one_line_error(result)


@pytest.mark.skipif(not (shutil.which("Xvfb") and shutil.which("xdotool") and shutil.which("import")),
                    reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
def test_demo_under_xvfb_driven_by_xdotool(tmp_path):
    display = ":97"
    xvfb = subprocess.Popen(["Xvfb", display, "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    env = {**os.environ, "DISPLAY": display}
    env.pop("SDL_VIDEODRIVER", None)
    try:
        time.sleep(1.0)
        demo = subprocess.Popen([sys.executable, "-m", "ultraglide", "demo", "--windowed"], env=env, cwd=ROOT,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(1.0)
        assert demo.poll() is None, demo.communicate()[1]

        def xdo(*args):
            subprocess.run(["xdotool", *map(str, args)], env=env, check=True, timeout=10)

        def shot(name):
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            path = ARTIFACTS / f"{name}.png"
            subprocess.run(["import", "-window", "root", str(path)], env=env, check=True, timeout=20)
            return path

        # SDL types WM_NAME as UTF-8, which xdotool's --name does not match: find the window by its process
        window = subprocess.run(["xdotool", "search", "--sync", "--pid", str(demo.pid)], env=env,
                                capture_output=True, text=True, timeout=30).stdout.split()
        assert window, "the demo window did not appear"
        time.sleep(1.0)
        screenshots = [shot("1-gallery")]
        xdo("mousemove", 110, 100, "click", 1)  # the first tile
        time.sleep(0.5)
        xdo("mousemove", 200, 300, "mousedown", 1)
        for x in range(200, 700, 25):
            xdo("mousemove", x, 300)
            time.sleep(0.02)
        screenshots.append(shot("2-texture"))
        xdo("mouseup", 1)
        xdo("key", "w")
        time.sleep(0.5)
        screenshots.append(shot("3-widgets"))
        xdo("key", "Escape")
        assert demo.wait(timeout=15) == 0
        from PIL import Image

        pictures = [np.asarray(Image.open(path).convert("RGB"), dtype=float) for path in screenshots]
        for picture in pictures:
            assert picture.shape == (800, 1280, 3) and picture.std() > 10  # something was drawn
        assert np.abs(pictures[0] - pictures[1]).mean() > 5 and np.abs(pictures[1] - pictures[2]).mean() > 5
    finally:
        if demo.poll() is None:
            demo.kill()
        xvfb.terminate()
        xvfb.wait(timeout=10)


def test_bad_demo_texture_is_one_line(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"nope")
    result = run_cli("demo", str(tmp_path / "bad.png"), env={"SDL_VIDEODRIVER": "dummy"})
    assert "not an image" in assert_one_line_error(result)
    assert Path(tmp_path / "bad.png").exists()
