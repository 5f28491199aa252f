"""Authoring from images: every Pillow mode, every bad input, and the CLI end to end."""

import io
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from PIL import Image
from ultraglide.apps.figures import texture_show
from ultraglide.textures.authoring import AuthoringOptions, author_image
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import load_texture
from ultraglide.textures.library import LIBRARY_DIR
from ultraglide.textures.seams import measure_seams
from xvfb import start_xvfb

# a left-to-right ramp, dark to light, 64 × 32 pixels
RAMP = np.tile(np.linspace(0, 255, 64), (32, 1)).astype(np.uint8)


def save(image, path, **kw):
    image.save(path, **kw)
    return path


def ramp_luminance(texture, options=AuthoringOptions()):
    low, high = options.ratio_range
    return (texture.values - low) / (high - low)


@pytest.mark.parametrize("mode", ["L", "RGB", "CMYK", "P", "1", "I;16", "LA", "RGBA"])
def test_every_mode_reads_as_the_same_ramp(tmp_path, mode):
    if mode == "I;16":
        image = Image.fromarray(RAMP.astype(np.uint16) * 257)
    else:
        image = Image.fromarray(RAMP).convert(mode)  # LA and RGBA come out fully opaque
    suffix = ".tif" if mode == "CMYK" else ".png"
    path = save(image, tmp_path / f"ramp{suffix}")
    texture = author_image(path)
    values = ramp_luminance(texture)
    assert texture.values.shape == (32, 64)
    if mode == "1":  # dithered black and white: the mean still follows the ramp
        assert values[:, :16].mean() < 0.3 and values[:, -16:].mean() > 0.7
    elif mode == "P":
        assert values[0] == pytest.approx(np.linspace(0, 1, 64), abs=0.03)
    else:
        assert values[0] == pytest.approx(np.linspace(0, 1, 64), abs=0.01)


def test_sixteen_bit_keeps_its_precision(tmp_path):
    fine = np.tile(np.arange(1000, 1064, dtype=np.uint16), (4, 1))  # steps far below 8-bit resolution
    texture = author_image(save(Image.fromarray(fine), tmp_path / "fine.png"), AuthoringOptions(ratio_range=(0, 1)))
    assert np.all(np.diff(texture.values[0]) > 0)


def test_alpha_is_composited_on_the_background(tmp_path):
    rgba = np.zeros((8, 8, 4), np.uint8)  # black, fully transparent on the left half
    rgba[:, 4:, 3] = 255
    path = save(Image.fromarray(rgba, "RGBA"), tmp_path / "alpha.png")
    white = ramp_luminance(author_image(path))
    assert white[:, :4] == pytest.approx(1.0) and white[:, 4:] == pytest.approx(0.0)
    black = ramp_luminance(author_image(path, AuthoringOptions(background=(0, 0, 0))))
    assert black[:, :4] == pytest.approx(0.0)


def test_palette_with_transparency(tmp_path):
    image = Image.new("P", (4, 4), 0)
    image.putpalette([0, 0, 0, 255, 255, 255])
    image.info["transparency"] = 0
    path = save(image, tmp_path / "p.png", transparency=0)
    assert ramp_luminance(author_image(path)) == pytest.approx(1.0)  # transparent → background white


def test_exif_rotation_is_honoured(tmp_path):
    image = Image.fromarray(RAMP)  # 64 wide, 32 tall, dark on the left
    exif = Image.Exif()
    exif[0x0112] = 6  # "rotate 90° clockwise to display"
    path = save(image, tmp_path / "rot.jpg", exif=exif, quality=95)
    texture = author_image(path)
    assert texture.values.shape == (64, 32)  # now tall
    values = ramp_luminance(texture)
    assert values[0].mean() < 0.1 and values[-1].mean() > 0.9  # dark at the top after rotation


def test_animated_image_uses_first_frame_with_a_warning(tmp_path):
    frames = [Image.fromarray(np.full((8, 8), v, np.uint8)) for v in (0, 255)]
    path = tmp_path / "anim.gif"
    frames[0].save(path, save_all=True, append_images=frames[1:])
    with pytest.warns(UserWarning, match="animated"):
        texture = author_image(path)
    assert ramp_luminance(texture).max() < 0.05


def test_float_tiff(tmp_path):
    values = np.linspace(0, 1, 32, dtype=np.float32)[None, :].repeat(4, 0)
    texture = author_image(save(Image.fromarray(values, "F"), tmp_path / "f.tif"))
    assert ramp_luminance(texture)[0] == pytest.approx(values[0], abs=1e-6)


def test_mappings_levels_gamma_invert_blur_crop(tmp_path):
    path = save(Image.fromarray(RAMP), tmp_path / "ramp.png")
    base = dict(ratio_range=(0.0, 1.0))
    levels = author_image(path, AuthoringOptions(black=0.25, white=0.75, **base)).values[0]
    assert levels[:16].max() == 0.0 and levels[-16:].min() == 1.0
    gamma = author_image(path, AuthoringOptions(gamma=2.0, **base)).values[0]
    assert gamma[32] == pytest.approx(np.sqrt(RAMP[0, 32] / 255), abs=1e-3)
    inverted = author_image(path, AuthoringOptions(invert=True, **base)).values[0]
    assert inverted[0] == pytest.approx(1.0) and inverted[-1] == pytest.approx(0.0)
    step = save(Image.fromarray(np.where(np.arange(64) < 32, 0, 255).astype(np.uint8)[None, :].repeat(16, 0)),
                tmp_path / "step.png")
    edges = author_image(step, AuthoringOptions(mode="edges", **base)).values[8]
    assert np.argmax(edges) in (31, 32) and edges[5] == 0.0
    cropped = author_image(path, AuthoringOptions(crop=(16, 0, 32, 8), width_mm=10, **base))
    assert cropped.values.shape == (8, 32) and cropped.height_mm == pytest.approx(2.5)
    # 64 px over 80 mm: a 2.5 mm sigma is 2 px; a unit step then rises at most 1/(2 sqrt(2 pi)) a pixel
    blurred = author_image(step, AuthoringOptions(blur_mm=2.5, **base)).values[8]
    assert np.max(np.diff(blurred)) == pytest.approx(1 / (2 * np.sqrt(2 * np.pi)), abs=0.02)
    gradient = author_image(path, AuthoringOptions(mode="gradient", **base))
    assert gradient.kind == "gradient"
    dpi = author_image(path, AuthoringOptions(dpi=254))
    assert dpi.width_mm == pytest.approx(6.4)


def test_bad_images(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "text.png").write_text("hello, I am not a picture")
    data = io.BytesIO()
    Image.fromarray(RAMP).save(data, format="PNG")
    (tmp_path / "truncated.png").write_bytes(data.getvalue()[: len(data.getvalue()) // 2])
    for name, message in (("empty.png", "not an image"), ("text.png", "not an image"),
                          ("truncated.png", "damaged or truncated"), ("missing.png", "no such image file")):
        with pytest.raises(TextureError, match=message):
            author_image(tmp_path / name)
    with pytest.raises(TextureError, match="directory"):
        author_image(tmp_path)
    big = save(Image.fromarray(RAMP), tmp_path / "big.png")
    with pytest.raises(TextureError, match="over the limit of 1,000; .* larger max_pixels"):
        author_image(big, AuthoringOptions(max_pixels=1000))


@pytest.mark.parametrize("options", [dict(width_mm=-5), dict(ratio_range=(0.2, 1.4)), dict(gamma=0),
                                     dict(black=0.8, white=0.2), dict(blur_mm=-1), dict(mode="sparkle"),
                                     dict(width_mm=10, dpi=100)])
def test_nonsensical_options(options):
    with pytest.raises(TextureError):
        AuthoringOptions(**options)


def test_author_cli_end_to_end(tmp_path):
    source = save(Image.fromarray(RAMP).convert("RGB"), tmp_path / "ramp.jpg", quality=95)
    out, preview = tmp_path / "t.png", tmp_path / "preview.png"
    result = run_cli("author", source, "-o", out, "--width-mm", "64", "--range", "0.3", "0.9",
                     "--preview", preview, check=True)
    assert "wrote" in result.stdout
    texture = load_texture(out)
    assert texture.width_mm == 64 and texture.height_mm == 32
    assert texture.values.min() == pytest.approx(0.3, abs=0.01) and texture.values.max() == pytest.approx(0.9, abs=0.01)
    with Image.open(preview) as image:
        assert image.width > 800


@pytest.mark.parametrize("args, fragment", [
    (["--width-mm", "-3"], "positive"), (["--range", "0.2", "1.5"], "0..1"), (["--gamma", "0"], "gamma"),
    (["--crop", "0,0,0,5"], "crop"), (["--max-pixels", "10"], "max-pixels"),
])
def test_author_cli_bad_options_leave_no_file(tmp_path, args, fragment):
    source = save(Image.fromarray(RAMP), tmp_path / "ramp.png")
    out = tmp_path / "t.png"
    assert fragment in assert_one_line_error(run_cli("author", source, "-o", out, *args))
    assert not out.exists()
    assert not list(tmp_path.glob(".t*"))  # no temporary left behind


def test_author_cli_bad_files(tmp_path):
    (tmp_path / "empty.jpg").write_bytes(b"")
    assert "not an image" in assert_one_line_error(run_cli("author", tmp_path / "empty.jpg", "-o", tmp_path / "o.png"))
    assert not (tmp_path / "o.png").exists()


def test_texture_new_and_textures_cli(tmp_path):
    out = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--wavelength-mm", "2", "--size-mm", "40x20", "-o", out, check=True)
    texture = load_texture(out)
    assert (texture.width_mm, texture.height_mm) == (40, 20)
    assert texture.authoring["wavelength_mm"] == 2
    bad = run_cli("texture", "new", "grating", "--wavelength-mm", "0", "-o", out)
    assert "positive" in assert_one_line_error(bad)
    listing = json.loads(run_cli("textures", "--json", check=True).stdout)
    assert len(listing) >= 10 and {"name", "width_mm", "height_mm", "description"} <= set(listing[0])


# ---- seamless tiles, auto-levels, invert: through the command --------------------------------------

def _photo(tmp_path, name="photo.png"):
    """A photo-like image that does not tile: smooth random blobs plus a left-to-right shading."""
    rng = np.random.default_rng(11)
    from scipy import ndimage

    field = ndimage.gaussian_filter(rng.standard_normal((120, 160)), 6)
    field = (field - field.min()) / (field.max() - field.min())
    field = 0.7 * field + 0.3 * np.linspace(0, 1, 160)[None, :]
    return save(Image.fromarray((field * 255).astype(np.uint8)), tmp_path / name)


def test_author_warns_of_a_seam_and_seamless_removes_it(tmp_path):
    photo = _photo(tmp_path)
    plain, tiled = tmp_path / "plain.png", tmp_path / "tiled.png"
    result = run_cli("author", photo, "-o", plain, "--width-mm", "80", check=True)
    assert "tiles with a seam" in result.stderr and "--seamless" in result.stderr
    assert measure_seams(load_texture(plain).values).visible
    result = run_cli("author", photo, "-o", tiled, "--width-mm", "80", "--seamless", "--blur-mm", "0.5", check=True)
    assert "seam" not in result.stderr
    texture = load_texture(tiled)
    report = measure_seams(texture.values)
    assert report.seam_max <= report.interior_max + 1e-6 and not report.visible
    # cross-fade: the tile is shorter by the 12.5 % band, and features keep their size (0.5 mm a pixel)
    assert (texture.cols, texture.rows) == (140, 105)
    assert texture.width_mm == pytest.approx(70.0) and texture.height_mm == pytest.approx(52.5)
    # away from the bands the picture is the photo's own (same pixels, in the same place)
    source = np.asarray(Image.open(photo), dtype=float) / 255
    assert texture.values[40:60, 60:80] == pytest.approx(0.4 + 0.6 * ndimage_blur(source, 1.0)[40:60, 60:80],
                                                         abs=0.01)


def ndimage_blur(values, sigma_px):
    from scipy import ndimage

    return ndimage.gaussian_filter(values, sigma_px, mode="nearest")


def test_author_seamless_mirror(tmp_path):
    photo = _photo(tmp_path)
    out = tmp_path / "m.png"
    run_cli("author", photo, "-o", out, "--width-mm", "80", "--seamless", "--seam-method", "mirror",
            "--range", "0", "1", check=True)
    texture = load_texture(out)
    assert (texture.cols, texture.rows) == (320, 240) and texture.width_mm == pytest.approx(160)
    values = texture.values
    assert np.array_equal(values[:, ::-1], values) and np.array_equal(values[::-1], values)
    source = np.asarray(Image.open(photo), dtype=np.float32) / 255
    assert values[:120, :160] == pytest.approx(source, abs=1e-3)


def test_author_auto_levels_stretches_a_narrow_image(tmp_path):
    narrow = np.tile(np.linspace(0.3, 0.6, 101), (10, 1))  # uses 30 % of the range
    path = save(Image.fromarray(np.round(narrow * 65535).astype(np.uint16)), tmp_path / "narrow.png")
    out = tmp_path / "a.png"
    run_cli("author", path, "-o", out, "--auto-levels", "--auto-levels-clip", "0", "--range", "0.2", "1",
            "--outside", "clamp", check=True)
    texture = load_texture(out)
    assert texture.values[0] == pytest.approx(0.2 + 0.8 * np.linspace(0, 1, 101), abs=1e-3)
    run_cli("author", path, "-o", out, "--auto-levels", "--range", "0", "1", "--outside", "clamp", check=True)
    # 1 % clipped at each end: the 1st and 99th percentiles of the ramp become 0 and 1
    values = load_texture(out).values[0]
    assert values[0] == 0 and values[-1] == 1
    assert values[50] == pytest.approx(0.5, abs=1e-3) and values[2] == pytest.approx(1 / 98, abs=2e-3)
    both = run_cli("author", path, "-o", tmp_path / "b.png", "--auto-levels", "--levels", "0.1", "0.9")
    assert "not both" in assert_one_line_error(both)
    uniform = save(Image.fromarray(np.full((8, 8), 99, np.uint8)), tmp_path / "flat.png")
    assert "uniform" in assert_one_line_error(run_cli("author", uniform, "-o", tmp_path / "c.png", "--auto-levels"))
    assert not (tmp_path / "b.png").exists() and not (tmp_path / "c.png").exists()


def test_author_invert_through_the_command(tmp_path):
    source = save(Image.fromarray(RAMP), tmp_path / "ramp.png")
    straight, inverted = tmp_path / "s.png", tmp_path / "i.png"
    run_cli("author", source, "-o", straight, "--range", "0.3", "0.9", "--outside", "clamp", check=True)
    run_cli("author", source, "-o", inverted, "--range", "0.3", "0.9", "--outside", "clamp", "--invert", check=True)
    a, b = load_texture(straight).values, load_texture(inverted).values
    assert a[0, 0] == pytest.approx(0.3, abs=1e-4) and b[0, 0] == pytest.approx(0.9, abs=1e-4)  # black: slippery
    assert a + b == pytest.approx(np.full_like(a, 1.2), abs=1e-4)  # mirrored within the range
    assert load_texture(inverted).authoring["invert"] is True


@pytest.mark.parametrize("args, fragment", [(["--seam-band", "0.7"], "seam-band"),
                                            (["--seam-method", "twirl"], "invalid choice"),
                                            (["--auto-levels", "--auto-levels-clip", "60"], "auto-levels")])
def test_author_seamless_bad_options(tmp_path, args, fragment):
    photo = _photo(tmp_path)
    out = tmp_path / "x.png"
    assert fragment in assert_one_line_error(run_cli("author", photo, "-o", out, "--seamless", *args))
    assert not out.exists()


# ---- looking at textures: texture show and texture info ---------------------------------------------

def _colourful_run(picture: np.ndarray, row: int) -> tuple[int, int]:
    """First and last column of the first run of saturated colour on a row of an RGB picture."""
    line = picture[row].astype(int)
    colourful = (line.max(axis=1) - line.min(axis=1)) > 40
    start = int(np.argmax(colourful))
    stop = start + int(np.argmin(colourful[start:]))
    return start, stop


def test_texture_show_png_is_print_quality_and_at_physical_size(tmp_path):
    out = tmp_path / "show.png"
    result = run_cli("texture", "show", "grating-2mm", "-o", out, "--force", "0.4", check=True)
    assert "at physical size" in result.stdout  # by default a page (7.16 in): the 80 mm texture fits at 1:1
    with Image.open(out) as image:
        assert image.format == "PNG"
        assert image.info["dpi"][0] == pytest.approx(300, abs=0.5)
        picture = np.asarray(image.convert("RGB"))
    assert picture.shape[1] == pytest.approx(7.16 * 300, abs=2)  # the whole page is saved
    # the 80 mm wide friction map spans 80 mm of the page: 945 pixels at 300 dpi, from the 14 mm margin
    rows = np.flatnonzero(((picture.max(axis=2).astype(int) - picture.min(axis=2)) > 40).sum(axis=1) > 500)
    start, stop = _colourful_run(picture, int(rows[10]))
    assert stop - start == pytest.approx(80 / 25.4 * 300, abs=4)
    assert start == pytest.approx(texture_show.LEFT_MM / 25.4 * 300, abs=4)
    column = run_cli("texture", "show", "grating-2mm", "-o", out, "--figure-width", "column", check=True)
    room = 3.5 * 25.4 - texture_show.LEFT_MM - texture_show.RIGHT_MM  # what a column leaves the map, mm
    assert f"at 1:{80 / room:.3g}" in column.stdout


def test_texture_show_vector_formats_and_a_large_texture_scaled(tmp_path):
    big = tmp_path / "big.png"
    run_cli("texture", "new", "checkerboard", "--size-mm", "340x100", "--px-per-mm", "2", "-o", big, check=True)
    pdf, svg = tmp_path / "show.pdf", tmp_path / "show.svg"
    result = run_cli("texture", "show", big, "-o", pdf, "--model", "paper", check=True)
    room = 7.16 * 25.4 - texture_show.LEFT_MM - texture_show.RIGHT_MM  # 340 mm does not fit a page's 151 mm
    assert f"at 1:{340 / room:.3g}" in result.stdout
    assert pdf.read_bytes().startswith(b"%PDF")
    run_cli("texture", "show", "bumps", "-o", svg, check=True)
    import xml.etree.ElementTree as ElementTree

    root = ElementTree.parse(svg).getroot()
    assert root.tag.endswith("svg") and root.get("width").endswith("pt")
    assert float(root.get("width")[:-2]) == pytest.approx(7.16 * 72, abs=1)  # the page, in points
    text = svg.read_text()
    assert "x (mm)" in text and "friction ratio" in text


@pytest.mark.parametrize("args, fragment", [(["-o", "x.jpg"], ".png, .pdf or .svg"),
                                            (["-o", "x.png", "--model", "nonsense"], "unknown model"),
                                            (["-o", "x.png", "--profile", "nonsense"], "plate profile")])
def test_texture_show_bad_options(tmp_path, args, fragment):
    args = [str(tmp_path / a) if a.startswith("x.") else a for a in args]
    assert fragment in assert_one_line_error(run_cli("texture", "show", "grating-1mm", *args))
    assert not list(tmp_path.iterdir())


def test_texture_info_words_and_json(tmp_path):
    words = run_cli("texture", "info", "grating-diagonal-2mm", check=True).stdout
    assert "80 × 50 mm" in words and "seamless" in words and "it repeats" in words
    facts = json.loads(run_cli("texture", "info", "wood", "--json", check=True).stdout)
    wood = load_texture(LIBRARY_DIR / "wood.png")
    assert facts["width_mm"] == pytest.approx(wood.width_mm) and facts["cols"] == wood.cols
    assert facts["friction"]["mean"] == pytest.approx(float(wood.values.mean()), abs=1e-5)  # to 16 bits
    assert facts["seams"]["seamless"] is True and facts["outside"] == "tile"
    fabric = json.loads(run_cli("texture", "info", "fabric", "--json", check=True).stdout)
    assert fabric["authoring"]["seamless"] == "crossfade"
    assert "no texture file" in assert_one_line_error(run_cli("texture", "info", "nothing-here"))


@pytest.mark.skipif(not (shutil.which("Xvfb") and shutil.which("xdotool") and shutil.which("import")),
                    reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
def test_texture_show_window_under_xvfb(tmp_path):
    xvfb, display = start_xvfb(1280, 1024)
    env = {**os.environ, "DISPLAY": display}
    env.pop("SDL_VIDEODRIVER", None)
    show = subprocess.Popen([sys.executable, "-m", "ultraglide", "texture", "show", "dots", "--window"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        window = subprocess.run(["xdotool", "search", "--sync", "--pid", str(show.pid)], env=env,
                                capture_output=True, text=True, timeout=60).stdout.split()
        assert window, "the window did not appear"
        shot = tmp_path / "window.png"
        deadline = time.monotonic() + 30
        while True:  # wait until the figure is drawn: a large share of viridis colour on the screen
            subprocess.run(["import", "-window", "root", str(shot)], env=env, check=True, timeout=20)
            picture = np.asarray(Image.open(shot).convert("RGB")).astype(int)
            colourful = np.mean((picture.max(axis=2) - picture.min(axis=2)) > 40)
            if colourful > 0.05 or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        assert colourful > 0.05
        # SDL may make more than one X window for the process: press Esc in the focused one, and in each of
        # the process's that still exists, until the program ends
        deadline = time.monotonic() + 30
        while show.poll() is None and time.monotonic() < deadline:
            subprocess.run(["xdotool", "key", "Escape"], env=env, timeout=10)
            for candidate in subprocess.run(["xdotool", "search", "--pid", str(show.pid)], env=env,
                                            capture_output=True, text=True, timeout=10).stdout.split():
                subprocess.run(["xdotool", "key", "--window", candidate, "Escape"], env=env, timeout=10,
                               capture_output=True)
            try:
                show.wait(timeout=1)
            except subprocess.TimeoutExpired:
                pass
        assert show.wait(timeout=30) == 0, show.stderr.read()
    finally:
        if show.poll() is None:
            show.kill()
        xvfb.terminate()
        xvfb.wait(timeout=10)


def test_texture_new_grating_tiles_unless_exact_and_the_new_kinds(tmp_path):
    tiled, exact = tmp_path / "t.png", tmp_path / "e.png"
    result = run_cli("texture", "new", "grating", "--wavelength-mm", "3", "--angle-deg", "30", "-o", tiled,
                     check=True)
    assert "snapped from 3 mm at 30°" in result.stdout
    run_cli("texture", "new", "grating", "--wavelength-mm", "3", "--angle-deg", "30", "--exact", "-o", exact,
            check=True)
    snapped, kept = load_texture(tiled), load_texture(exact)
    assert snapped.outside == "tile" and measure_seams(snapped.values).seamless
    assert kept.outside == "clamp" and measure_seams(kept.values).visible
    assert kept.authoring["tile_wavelength_mm"] == pytest.approx(3.0)
    for kind, extra in (("fractal", ["--hurst", "0.6"]), ("gabor", []), ("bump", []), ("edge", []),
                        ("lines", ["--widths-mm", "1", "3"])):
        out = tmp_path / f"{kind}.png"
        run_cli("texture", "new", kind, *extra, "-o", out, check=True)
        assert load_texture(out).authoring["generator"] == kind
    bad = run_cli("texture", "new", "fractal", "--hurst", "1.5", "-o", tmp_path / "x.png")
    assert "Hurst" in assert_one_line_error(bad)


def test_texture_show_window_without_a_display_is_one_line(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")}
    result = subprocess.run([sys.executable, "-m", "ultraglide", "texture", "show", "dots", "--window"],
                            capture_output=True, text=True, env=env, timeout=120)
    assert "-o FILE.png" in assert_one_line_error(result)
