"""``demo --watch`` against hostile files (issue 26): whatever the watched texture file becomes (a named pipe, a
device node, a directory, half a file, a metadata of 5 000-digit numbers or nested 100 000 deep, a huge file, a
loop of links, nothing at all), the demo keeps the texture it last loaded, says what is wrong in one line on its
status line, never raises and never blocks; once the file is good again it is loaded.

The watcher is driven directly (it is the demo's only reader of changing files), on real named pipes and
``mknod`` device nodes; the last test runs it inside the demo, a real pygame window on SDL's dummy driver.
"""

import json
import os
import stat
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import wait_for
from PIL import Image, PngImagePlugin
from test_inputs import no_hang
from ultraglide.apps.demo.watch import TextureWatcher
from ultraglide.textures.fileformat import CHUNK, load_texture, save_texture
from ultraglide.textures.texture import Texture

ROOT_USER = os.geteuid() == 0


def halves(path: Path, left: float) -> Path:
    values = np.ones((30, 40), np.float32)
    values[:, :20] = left
    return save_texture(Texture(values, 40.0, 30.0, outside="clamp", name="halves"), path)


def with_metadata(path: Path, text: str) -> None:
    """A 16-bit PNG whose ultraglide metadata chunk is ``text``, written in place (as an editor saving)."""
    info = PngImagePlugin.PngInfo()
    info.add_itxt(CHUNK, text)
    with open(path, "r+b") as stream:
        stream.truncate(0)
        Image.fromarray(np.full((30, 40), 30000, np.uint16)).save(stream, format="PNG", pnginfo=info)


def replace_with_fifo(path: Path) -> None:
    path.unlink()
    os.mkfifo(path)


def replace_with_zero(path: Path) -> None:
    path.unlink()
    os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 5))


def replace_with_directory(path: Path) -> None:
    path.unlink()
    path.mkdir()


def truncate_mid_write(path: Path) -> None:
    data = path.read_bytes()
    with open(path, "r+b") as stream:
        stream.truncate(len(data) // 2)


def huge_integers(path: Path) -> None:
    meta = json.loads(Image.open(halves(path.with_name("model.png"), 0.5)).text[CHUNK])
    text = json.dumps(meta).replace(f'"width_mm": {meta["width_mm"]}', '"width_mm": ' + "9" * 5000)
    with_metadata(path, text)


def deep_nesting(path: Path) -> None:
    with_metadata(path, '{"authoring": ' + "[" * 100_000 + "]" * 100_000 + "}")


def huge_file(path: Path) -> None:
    with open(path, "r+b") as stream:  # 8 GiB that the file system does not store: zeros after a PNG's start
        stream.truncate(100)
        stream.truncate(8 << 30)


def link_loop(path: Path) -> None:
    path.unlink()
    other = path.with_name("other.png")
    other.symlink_to(path)
    path.symlink_to(other)


def removed(path: Path) -> None:
    path.unlink()


HOSTILE = {  # what the file becomes, and what the status line says
    "named pipe": (replace_with_fifo, "named pipe"),
    "device node": (replace_with_zero, "character device"),
    "directory": (replace_with_directory, "directory"),
    "truncated mid-write": (truncate_mid_write, "halves.png"),
    "5 000-digit integer": (huge_integers, "width_mm"),
    "nested 100 000 deep": (deep_nesting, "nested too deeply"),
    "huge file": (huge_file, "halves.png"),
    "loop of links": (link_loop, "loop of symbolic links"),
    "removed": (removed, "removed"),
}


def restore(path: Path) -> None:
    """The file made good again: a new texture (left half 0.6), as an editor's atomic save leaves it."""
    if path.is_symlink() or path.is_file() or path.exists() and not path.is_dir():
        path.unlink()
    elif path.is_dir():
        path.rmdir()
    halves(path.with_name("next.png"), 0.6).rename(path)


def poll_until(watcher: TextureWatcher, condition, timeout: float = 60.0) -> list:
    """Poll as the demo does (every 200 ms there; here back to back) until ``condition(reloaded)`` holds."""
    found = []

    def polled():
        found[:] = watcher.poll()
        return condition(found)

    assert wait_for(polled, timeout=timeout), watcher.errors
    return found


@pytest.mark.parametrize("hostile", sorted(HOSTILE))
def test_the_watcher_keeps_the_last_texture_and_says_what_is_wrong(tmp_path, hostile):
    if hostile == "device node" and not ROOT_USER:
        pytest.skip("mknod needs root")
    path = halves(tmp_path / "halves.png", 0.2)
    make, words = HOSTILE[hostile]
    watcher = TextureWatcher({0: (path, load_texture(path))})
    assert watcher.poll() == [] and watcher.errors == []
    make(path)
    with no_hang(120):
        poll_until(watcher, lambda reloaded: bool(watcher.errors))
        assert len(watcher.errors) == 1 and "\n" not in watcher.errors[0]
        assert watcher.errors[0].startswith("cannot reload halves.png: ") and words in watcher.errors[0], watcher.errors
        for _ in range(5):  # it stays said, and nothing is loaded, while the file stays so
            assert watcher.poll() == [] and watcher.errors and words in watcher.errors[0]
        restore(path)
        reloaded = poll_until(watcher, bool)
    assert [index for index, _ in reloaded] == [0] and reloaded[0][1].values[0, 0] == pytest.approx(0.6, abs=1e-3)
    assert watcher.errors == []


def test_a_bad_file_is_tried_again_only_when_it_changes(tmp_path, monkeypatch):
    """A damaged file costs a look a poll, not a decode: the demo stays smooth while it stays damaged."""
    import ultraglide.apps.demo.watch as watch

    path = halves(tmp_path / "halves.png", 0.2)
    watcher = TextureWatcher({0: (path, load_texture(path))})
    truncate_mid_write(path)
    loads = []
    real_load = watch.TextureWatcher._load
    monkeypatch.setattr(watch.TextureWatcher, "_load", staticmethod(lambda *a: loads.append(1) or real_load(*a)))
    poll_until(watcher, lambda reloaded: bool(watcher.errors))
    for _ in range(20):
        watcher.poll()
    assert len(loads) == 1 and watcher.errors


def test_a_source_image_that_goes_away_is_no_error(tmp_path):
    image = tmp_path / "photo.png"
    Image.fromarray(np.tile(np.linspace(0, 255, 40, dtype=np.uint8), (30, 1))).save(image)
    from ultraglide.textures.authoring import AuthoringOptions, author_image

    path = save_texture(author_image(image, AuthoringOptions(outside="clamp")), tmp_path / "t.png")
    watcher = TextureWatcher({0: (path, load_texture(path))})
    assert watcher.watched[0].source == image
    image.unlink()
    for _ in range(5):
        assert watcher.poll() == [] and watcher.errors == []


@pytest.mark.slow
def test_the_demo_keeps_running_on_its_last_texture_and_says_so(tmp_path, monkeypatch):
    """In the demo itself: the file becomes a named pipe nobody writes; the window keeps drawing the texture it
    had, the status line says why, and the good file is shown again once saved."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    path = halves(tmp_path / "halves.png", 0.2)
    app = DemoApp([str(path)], device_url="null", windowed=True, watch=True)
    try:
        app.wait_ready()
        replace_with_fifo(path)
        with no_hang(120):
            assert wait_for(lambda: app.step() or "named pipe" in app.status_words(), timeout=60)
            assert app.running and app.textures[0].values[0, 0] == pytest.approx(0.2, abs=1e-3)
            restore(path)
            assert wait_for(lambda: app.step() or app.textures[0].values[0, 0] == pytest.approx(0.6, abs=1e-3),
                            timeout=60)
            assert wait_for(lambda: app.step() or "cannot reload" not in app.status_words(), timeout=60)
    finally:
        app.close()


def test_a_slow_load_does_not_hold_the_poll(tmp_path, monkeypatch):
    """A large image decodes for seconds: the poll (the demo's loop) returns while it does, and a later poll
    takes the texture once it is ready."""
    import ultraglide.apps.demo.watch as watch

    path = halves(tmp_path / "halves.png", 0.2)
    watcher = TextureWatcher({0: (path, load_texture(path))})
    release, started = threading.Event(), threading.Event()
    real_load = watch.TextureWatcher._load

    def held_load(*args):
        started.set()
        assert release.wait(120)
        return real_load(*args)

    monkeypatch.setattr(watch.TextureWatcher, "_load", staticmethod(held_load))
    restore(path)
    with no_hang(120):
        assert wait_for(lambda: watcher.poll() == [] and started.is_set())  # the load began; the poll came back
        for _ in range(5):
            assert watcher.poll() == [] and watcher.errors == []  # still loading: the old texture stays
        release.set()
        reloaded = poll_until(watcher, bool)
    assert [index for index, _ in reloaded] == [0] and reloaded[0][1].values[0, 0] == pytest.approx(0.6, abs=1e-3)
