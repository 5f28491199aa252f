"""The page ``ultraglide serve --page`` serves, in a real headless Chromium (Debian's ``chromium`` and
``chromium-driver``, driven by Selenium): synthesized touch and pen input drive the engine, whose envelope record
shows the friction of the sprite under the synthesized finger; the sprites are drawn where they are felt; a PNG
dropped on the page (CDP's drag events with the file) is placed where it fell and felt there; two fingers follow the
rig's rule for which drives."""

import io
import time

import numpy as np
import pytest
from chromium_cdp import chromium, needed, pen_at, touch_at
from conftest import ROOT
from PIL import Image
from service_run import flat_png, png_ratio, read_envelope, rows_at, running_service
from ultraglide.textures.fileformat import load_texture, save_texture
from ultraglide.textures.texture import Texture

from ultraglide.client import Client

pytestmark = needed

MM_PER_PX = 0.25


@pytest.fixture
def browser(tmp_path):
    with chromium(tmp_path / "profile") as driver:
        yield driver


def flat_texture(path, ratio):
    save_texture(Texture(np.full((50, 50), ratio, dtype=np.float32), 20.0, 20.0, name=path.stem), path)
    return float(load_texture(path).values.mean())  # as the file holds it (8 bits)


def test_touch_and_pen_on_the_page_are_felt_as_the_sprite_under_them(tmp_path, browser):
    low = flat_texture(tmp_path / "low.png", 0.3)
    high = flat_texture(tmp_path / "high.png", 0.8)
    envelope_csv = tmp_path / "envelope.csv"
    with running_service(tmp_path / "low.png", tmp_path / "high.png", "--port", "0", "--page",
                         "--envelope-csv", envelope_csv) as (process, address):
        browser.get(address["page"] + f"?mm_per_px={MM_PER_PX}")
        deadline = time.monotonic() + 60
        while not browser.execute_script("return window.ultraglide && window.ultraglide.ready"):
            assert time.monotonic() < deadline, browser.execute_script("return document.body.innerText")
            time.sleep(0.05)
        width, height = browser.execute_script(
            "const c = document.getElementById('view'); return [c.clientWidth, c.clientHeight]")
        scene = browser.execute_script("return window.ultraglide.scene()")
        view = next(v for v in scene["views"] if v["view"] == "main")
        assert (view["width"], view["height"]) == (width, height)
        assert view["width_mm"] == pytest.approx(width * MM_PER_PX)
        # the two textures named at start fill the view side by side: low on the left half, high on the right
        left, right = (round(width * 0.25), round(height / 2)), (round(width * 0.75), round(height / 2))
        deadline = time.monotonic() + 30  # the sprites' images drawn
        while True:
            shot = Image.open(io.BytesIO(browser.get_screenshot_as_png())).convert("L")
            scale = shot.width / width
            seen = [shot.getpixel((round(x * scale), round(y * scale))) for x, y in (left, right)]
            if abs(seen[0] - low * 255) <= 2 and abs(seen[1] - high * 255) <= 2 or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        assert seen[0] == pytest.approx(low * 255, abs=2) and seen[1] == pytest.approx(high * 255, abs=2)
        touch_at(browser, *left)
        pen_at(browser, *right)
        send_times = browser.execute_script("return window.ultraglide.sendTimes()")
        assert browser.execute_script("return window.ultraglide.errors") == []
    envelope = read_envelope(envelope_csv)
    for (x, y), ratio in ((left, low), (right, high)):
        rows = rows_at(envelope, x * MM_PER_PX, y * MM_PER_PX)
        assert len(rows) > 100, f"nothing rendered under ({x}, {y}) px"
        assert np.median(rows["target_ratio"]) == pytest.approx(ratio, abs=0.01)
        assert rows["commanded_um_pp"].max() > 0.5  # felt: the plate played it
    assert len(send_times) >= 4 and all(t >= 0 for t in send_times)  # down and up of each (a still finger moves not)


def drop_file(driver, path, x, y):
    """A file dragged from outside the window and dropped at (x, y) CSS px: CDP's drag events, which the browser
    turns into the page's own dragenter, dragover and drop (a DataTransfer holding the file)."""
    data = {"items": [], "files": [str(path)], "dragOperationsMask": 1}
    for kind in ("dragEnter", "dragOver", "drop"):
        driver.execute_cdp_cmd("Input.dispatchDragEvent", {"type": kind, "x": x, "y": y, "data": data})


def test_a_png_dropped_on_the_page_is_placed_where_it_fell_and_felt_there(tmp_path, browser):
    dropped = tmp_path / "dropped.png"
    dropped.write_bytes(flat_png(0.4, 80, 80))  # a plain image: its brightness is its friction ratio
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--page", "--envelope-csv", envelope_csv) as (process, address):
        browser.get(address["page"] + f"?mm_per_px={MM_PER_PX}")
        deadline = time.monotonic() + 60
        while not browser.execute_script("return window.ultraglide && window.ultraglide.ready"):
            assert time.monotonic() < deadline, browser.execute_script("return document.body.innerText")
            time.sleep(0.05)
        width, height = browser.execute_script(
            "const c = document.getElementById('view'); return [c.clientWidth, c.clientHeight]")
        at = (round(width * 0.6), round(height * 0.4))
        drop_file(browser, dropped, *at)
        with Client(address["url"], role="observe") as watcher:
            deadline = time.monotonic() + 30
            while not any(s["sprite"] == "drop1" for s in watcher.state()["sprites"]):
                assert time.monotonic() < deadline, browser.execute_script("return window.ultraglide.errors")
                time.sleep(0.05)
            state = watcher.wait_rendered(30)
        sprite = next(s for s in state["sprites"] if s["sprite"] == "drop1")
        texture = next(t for t in state["textures"] if t["texture"] == "drop1")
        # centred where it fell, at its physical size on this screen's pitch
        assert sprite["width"] == pytest.approx(texture["width_mm"] / MM_PER_PX)
        assert sprite["height"] == pytest.approx(texture["height_mm"] / MM_PER_PX)
        assert sprite["x"] + sprite["width"] / 2 == pytest.approx(at[0], abs=1)
        assert sprite["y"] + sprite["height"] / 2 == pytest.approx(at[1], abs=1)
        assert texture["name"] == "dropped"
        touch_at(browser, *at)  # a finger on it
        off = (round(sprite["x"] - 20), at[1])  # and beside it, on the bare view
        touch_at(browser, *off)
        assert browser.execute_script("return window.ultraglide.errors") == []
    envelope = read_envelope(envelope_csv)
    for (x, y), ratio in ((at, png_ratio(0.4)), (off, 1.0)):
        rows = rows_at(envelope, x * MM_PER_PX, y * MM_PER_PX)
        assert len(rows) > 100, f"nothing rendered under ({x}, {y}) px"
        assert np.median(rows["target_ratio"]) == pytest.approx(ratio, abs=0.01)


def test_two_fingers_on_the_page_follow_the_rig_s_rule(tmp_path, browser):
    low = flat_texture(tmp_path / "low.png", 0.3)
    high = flat_texture(tmp_path / "high.png", 0.8)
    rig = tmp_path / "rig.toml"  # the panel's rule: the newest finger down takes over
    rig.write_text((ROOT / "examples" / "rig.toml").read_text().replace('drives = "first"', 'drives = "latest"'))
    envelope_csv = tmp_path / "envelope.csv"
    with running_service(tmp_path / "low.png", tmp_path / "high.png", "--port", "0", "--page", "--rig", rig,
                         "--device", "sim", "--envelope-csv", envelope_csv) as (process, address):
        browser.get(address["page"] + f"?mm_per_px={MM_PER_PX}")
        deadline = time.monotonic() + 60
        while not browser.execute_script("return window.ultraglide && window.ultraglide.ready"):
            assert time.monotonic() < deadline, browser.execute_script("return document.body.innerText")
            time.sleep(0.05)
        width, height = browser.execute_script(
            "const c = document.getElementById('view'); return [c.clientWidth, c.clientHeight]")
        left = {"x": round(width * 0.25), "y": round(height / 2), "radiusX": 5, "radiusY": 5, "force": 0.6, "id": 1}
        right = {"x": round(width * 0.75), "y": round(height / 2), "radiusX": 5, "radiusY": 5, "force": 0.6, "id": 2}

        def touches(kind, points, seconds=0.0):
            browser.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                time.sleep(0.01)
                browser.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": points})

        touches("touchStart", [left], 0.3)  # one finger on the left half
        touches("touchStart", [left, right], 0.3)  # a second on the right: it takes over
        touches("touchEnd", [right])  # the second lifts (CDP's touchEnd names the points lifted)
        left_again = {**left, "y": left["y"] + 8}  # the first, still down, drives again as it moves on
        touches("touchMove", [left_again], 0.3)
        touches("touchEnd", [left_again])
        assert browser.execute_script("return window.ultraglide.errors") == []
    envelope = read_envelope(envelope_csv)
    mm = {name: (p["x"] * MM_PER_PX, p["y"] * MM_PER_PX) for name, p in (("left", left), ("right", right))}
    first, second = rows_at(envelope, *mm["left"]), rows_at(envelope, *mm["right"])
    for rows, ratio in ((first, low), (second, high)):
        assert len(rows) > 100 and np.median(rows["target_ratio"]) == pytest.approx(ratio, abs=0.01)
    assert first["t_s"].min() < second["t_s"].min()  # the left finger, then the right one took over
    # once the right one lifted, the left one (still down) drives again: felt on the left half as it moves on (its
    # x stays; its y the engine predicts from the one move the browser sent)
    down = envelope[envelope["down"] > 0.5]
    after = down[down["t_s"] > second["t_s"].max()]
    assert len(after) > 100 and np.all(np.abs(after["x_mm"] - mm["left"][0]) < 0.05)
    assert np.median(after["target_ratio"]) == pytest.approx(low, abs=0.01)
    assert after["y_mm"].max() > mm["left"][1] + 1.0  # it moved on: the left finger's move, not the right's lift
