"""Textures: sampling by hand, band limiting, gradients, procedural patterns, the file format."""

import json

import numpy as np
import pytest
from PIL import Image
from ultraglide.textures import procedural
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import load_texture, save_texture
from ultraglide.textures.library import library_entries, resolve_texture
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

# 2 × 2 pixels of 1 mm: centres at x = 0.5, 1.5 and y = 0.5, 1.5
SMALL = np.array([[0.0, 1.0], [0.5, 0.25]], dtype=np.float32)


def small(outside="clamp", **kw):
    return Texture(SMALL, 2.0, 2.0, outside=outside, **kw)


def test_bilinear_by_hand():
    sampler = Sampler(small())
    x = np.array([0.5, 1.5, 1.0, 1.0, 0.75])
    y = np.array([0.5, 1.5, 0.5, 1.0, 1.25])
    # centre values; midway on the top row: 0.5; the middle: mean of four = 0.4375;
    # (0.75, 1.25): fu = 0.25, fv = 0.75: top 0.25, bottom 0.5 - 0.0625 = 0.4375 → 0.25 + 0.75 × 0.1875
    expected = [0.0, 0.25, 0.5, 0.4375, 0.25 + 0.75 * 0.1875]
    assert sampler.ratio(x, y) == pytest.approx(expected, abs=1e-6)


def test_outside_rules():
    x = np.array([-0.5, 2.5, 3.5])
    y = np.array([0.5, 0.5, 1.5])
    # clamp: the edge pixel's value continues
    assert Sampler(small("clamp")).ratio(x, y) == pytest.approx([0.0, 1.0, 0.25])
    # tile: x = -0.5 is x = 1.5 of the copy to the left; 2.5 is 0.5; 3.5 is 1.5
    assert Sampler(small("tile")).ratio(x, y) == pytest.approx([1.0, 0.0, 0.25])
    # fixed: everything beyond the edges is the fixed ratio
    fixed = Sampler(small("fixed", outside_ratio=0.7)).ratio(np.append(x, 1.0), np.append(y, 1.0))
    assert fixed == pytest.approx([0.7, 0.7, 0.7, 0.4375])


def test_tiling_wraps_between_last_and_first_pixel():
    # halfway between the last centre (1.5) and the next tile's first (2.5): mean of 1.0 and 0.0
    assert Sampler(small("tile")).ratio([2.0], [0.5]) == pytest.approx([0.5])


def test_grating_period_and_values():
    texture = procedural.grating(2.0, size_mm=(20, 10), ratio_range=(0.2, 1.0))
    sampler = Sampler(texture)
    x = np.array([0.0, 1.0, 0.5, 2.0, 19.0])
    expected = 0.2 + 0.8 * (0.5 + 0.5 * np.cos(2 * np.pi * x / 2.0))
    assert sampler.ratio(x, np.full(5, 5.0)) == pytest.approx(expected, abs=5e-3)


def _spurious_low_frequency(sampler, step_mm):
    x = np.arange(2000) * step_mm + 0.3
    signal = sampler.ratio(x, np.full_like(x, 25.0), step_mm=step_mm)
    return np.std(signal)


def test_fast_swipe_over_fine_grating_does_not_alias():
    # a 0.25 mm grating read every 0.95 mm: point sampling folds 4 cycles/mm down to a strong
    # tone at 0.21 cycles/mm; the band-limited lookup leaves only the mean
    grating = procedural.grating(0.25, size_mm=(80, 50), ratio_range=(0.0, 1.0))
    naive = Sampler(grating, band_limited=False)
    limited = Sampler(grating)
    x = np.arange(2000) * 0.95 + 0.3
    y = np.full_like(x, 25.0)
    aliased = naive.ratio(x, y, step_mm=0.95)
    spectrum = np.abs(np.fft.rfft(aliased - aliased.mean())) / len(x)
    assert spectrum.max() > 0.15  # the naive lookup really aliases: a tone of amplitude ~0.5
    clean = limited.ratio(x, y, step_mm=0.95)
    assert np.std(clean) < 0.02
    assert np.mean(clean) == pytest.approx(0.5, abs=0.02)


def test_band_limiting_keeps_detail_the_sampling_can_follow():
    grating = procedural.grating(4.0, size_mm=(80, 50), ratio_range=(0.0, 1.0))
    x = np.arange(4000) * 0.05
    y = np.full_like(x, 25.0)
    limited = Sampler(grating).ratio(x, y, step_mm=0.05)
    exact = 0.5 + 0.5 * np.cos(2 * np.pi * x / 4.0)
    assert np.max(np.abs(limited - exact)) < 0.01


def test_gradient_bump_feels_like_a_bump_from_every_direction():
    texture = procedural.bumps(pitch_mm=20, diameter_mm=16, size_mm=(40, 40), ratio_range=(0.2, 1.0))
    sampler = Sampler(texture)
    centre = np.array([10.0, 10.0])
    for angle in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        before = centre - 4 * direction  # climbing the near side
        after = centre + 4 * direction  # descending the far side
        d = ([direction[0]], [direction[1]])
        up = sampler.ratio([before[0]], [before[1]], direction=d)[0]
        down = sampler.ratio([after[0]], [after[1]], direction=d)[0]
        top = sampler.ratio([centre[0]], [centre[1]], direction=d)[0]
        assert up > 0.8 and down < 0.4
        assert top == pytest.approx(0.6, abs=0.02)  # flat at the summit: the middle of the range


def test_procedural_generators_all_make_valid_textures():
    for name, generator in procedural.GENERATORS.items():
        texture = generator()
        assert texture.values.min() >= 0 and texture.values.max() <= 1, name
        assert texture.width_mm > 0 and texture.description


def test_chirp_wavelength_sweeps():
    texture = procedural.chirp(4.0, 1.0, size_mm=(60, 10), ratio_range=(0, 1))
    x = np.linspace(0, 60, 24000, endpoint=False)
    row = Sampler(texture).ratio(x, np.full_like(x, 5.0))
    crossings = np.flatnonzero(np.diff(np.sign(row - 0.5)) != 0)
    spacing = np.diff(x[crossings]) * 2  # two crossings a wavelength
    assert spacing[0] == pytest.approx(4.0, rel=0.1) and spacing[-1] == pytest.approx(1.0, rel=0.1)


@pytest.mark.parametrize("bad", [dict(wavelength_mm=0), dict(wavelength_mm=-1), dict(size_mm=(0, 10)),
                                 dict(ratio_range=(0.5, 0.2)), dict(ratio_range=(-0.1, 1)), dict(shape="saw")])
def test_procedural_bad_parameters(bad):
    with pytest.raises(TextureError):
        procedural.grating(**bad)


def test_file_round_trip_is_exact_to_16_bits(tmp_path):
    texture = procedural.noise(1.0, size_mm=(30, 20), seed=3)
    path = save_texture(texture, tmp_path / "n.png")
    loaded = load_texture(path)
    assert np.max(np.abs(loaded.values - texture.values)) <= 0.5 / 65535 + 1e-7
    again = load_texture(save_texture(loaded, tmp_path / "n2.png"))
    assert np.array_equal(again.values, loaded.values)
    for field in ("width_mm", "height_mm", "kind", "outside", "ratio_range", "name", "description", "authoring"):
        assert getattr(loaded, field) == getattr(texture, field), field
    with Image.open(path) as image:  # any viewer sees a 16-bit grayscale PNG
        assert image.format == "PNG" and image.mode.startswith("I")
        meta = json.loads(image.info["ultraglide"])
        assert meta["format_version"] == 1


def test_gradient_texture_round_trip(tmp_path):
    texture = procedural.bumps()
    loaded = load_texture(save_texture(texture, tmp_path / "b.png"))
    assert loaded.kind == "gradient"
    assert loaded.full_slope_per_mm == pytest.approx(texture.full_slope_per_mm)


def test_plain_png_loads_with_defaults_and_a_warning(tmp_path):
    path = tmp_path / "plain.png"
    Image.fromarray(np.full((20, 30), 128, np.uint8)).save(path)
    with pytest.warns(UserWarning, match="no ultraglide metadata"):
        texture = load_texture(path)
    assert texture.width_mm == pytest.approx(3.0)  # 10 px/mm
    assert texture.values.max() == pytest.approx(128 / 255)


@pytest.mark.parametrize("meta, message", [
    ({"format_version": 99, "width_mm": 1, "height_mm": 1}, "version"),
    ({"format_version": 1, "width_mm": -1, "height_mm": 1}, "width_mm"),
    ({"format_version": 1, "width_mm": 1, "height_mm": 1, "kind": "velvet"}, "kind"),
])
def test_bad_metadata_is_explained(tmp_path, meta, message):
    from PIL import PngImagePlugin
    info = PngImagePlugin.PngInfo()
    info.add_itxt("ultraglide", json.dumps(meta))
    path = tmp_path / "bad.png"
    Image.fromarray(np.zeros((4, 4), np.uint16)).save(path, pnginfo=info)
    with pytest.raises(TextureError, match=message):
        load_texture(path)


def test_library_has_the_promised_textures():
    entries = {entry.name: entry for entry in library_entries()}
    assert len(entries) >= 10
    for wanted in ("grating-1mm", "checkerboard-5mm", "noise-2mm", "bumps", "button", "slider", "wood", "fabric"):
        assert wanted in entries
    assert resolve_texture("grating-1mm").width_mm == 80.0
    with pytest.raises(TextureError, match="library"):
        resolve_texture("no-such-texture")
