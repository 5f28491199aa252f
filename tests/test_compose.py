"""Composition: each operation against hand-computed values at known points, sizes reconciled on a
common grid, and ``ultraglide texture compose`` end to end."""

import json

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from PIL import Image
from ultraglide.textures import compose, procedural
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import load_texture, save_texture
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.texture import Texture

# 4 × 2 mm at 1 pixel a mm: pixel centres at x = 0.5 .. 3.5, y = 0.5, 1.5
A = Texture(np.array([[0.2, 0.4, 0.6, 0.8], [0.3, 0.5, 0.7, 0.9]], np.float32), 4.0, 2.0, outside="clamp", name="a")
B = Texture(np.full((2, 4), 0.5, np.float32), 4.0, 2.0, name="b")


def test_mix_min_max_multiply_on_one_grid_are_pixelwise():
    a, b = A.values.astype(float), B.values.astype(float)
    assert compose.mix([A, B], [3, 1]).values == pytest.approx(0.75 * a + 0.25 * b, abs=1e-6)
    assert compose.mix([A, B]).values == pytest.approx(0.5 * a + 0.25, abs=1e-6)
    assert compose.minimum([A, B]).values == pytest.approx(np.minimum(a, 0.5), abs=1e-6)
    assert compose.maximum([A, B]).values == pytest.approx(np.maximum(a, 0.5), abs=1e-6)
    assert compose.multiply([A, B]).values == pytest.approx(a * 0.5, abs=1e-6)
    mixed = compose.mix([A, B], [3, 1])
    assert (mixed.width_mm, mixed.height_mm, mixed.outside) == (4.0, 2.0, "clamp")  # the first input's rule
    assert mixed.authoring["weights"] == pytest.approx([0.75, 0.25]) and mixed.authoring["inputs"] == ["a", "b"]


def test_sizes_are_reconciled_on_the_finest_grid_by_each_inputs_own_rule():
    ramp = Texture(np.array([[0.2, 0.4, 0.6, 0.8]] * 2, np.float32), 4.0, 2.0, name="ramp")  # 1 px/mm, tiles
    # C: 2 × 2 mm at 2 px/mm, tiling, sticky on its left half; the ramp is read at C's finer pitch
    c = Texture(np.array([[1.0, 1.0, 0.0, 0.0]] * 4, np.float32), 2.0, 2.0, name="c")
    result = compose.minimum([ramp, c])
    assert (result.cols, result.rows, result.width_mm, result.height_mm) == (8, 4, 4.0, 2.0)
    # result centres x = 0.25, 0.75, ... 3.75. The ramp, tiled, is bilinear between its centres
    # 0.5, 1.5, 2.5, 3.5; at x = 0.25 between -0.5 (wrapped: 0.8) and 0.5 (0.2): 0.25 × 0.8 + 0.75 × 0.2
    ramp_at = [0.35, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75, 0.65]
    c_at = [1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]  # C's own centres; it repeats every 2 mm
    assert result.values[1] == pytest.approx(np.minimum(ramp_at, c_at), abs=1e-6)
    assert compose.maximum([ramp, c]).values[2] == pytest.approx(np.maximum(ramp_at, c_at), abs=1e-6)
    # a fixed input gives its fixed ratio beyond its edges; a clamped one extends its edge
    small = Texture(np.full((2, 2), 0.3, np.float32), 2.0, 2.0, outside="fixed", outside_ratio=0.9, name="s")
    mixed = compose.mix([ramp.with_(outside="clamp"), small], px_per_mm=1)
    assert mixed.values[0] == pytest.approx([0.25, 0.35, 0.75, 0.85], abs=1e-6)
    assert mixed.outside == "clamp"
    wider = compose.mix([ramp.with_(outside="clamp"), small], size_mm=(6, 2), px_per_mm=1)
    assert wider.values[0, 4:] == pytest.approx([0.85, 0.85], abs=1e-6)  # the ramp's edge 0.8 extends


def test_mask_by_an_image_and_by_a_texture():
    white_left = np.zeros((10, 20))
    white_left[:, :10] = 1.0  # luminance: stretched over the whole 4 × 2 mm result
    masked = compose.mask(A, white_left, other_ratio=1.0, px_per_mm=5)
    expected_left = compose.resample(A, compose.Grid(4.0, 2.0, 5.0))[:, :10]
    assert masked.values[:, :9] == pytest.approx(expected_left[:, :9], abs=1e-6)
    assert masked.values[:, 11:] == pytest.approx(1.0)
    half = Texture(np.full((2, 4), 0.25, np.float32), 4.0, 2.0)
    blended = compose.mask(A, half, other=B)  # a quarter of A, three quarters of B
    assert blended.values == pytest.approx(0.25 * A.values + 0.75 * 0.5, abs=1e-6)


def test_tile_inside_a_region():
    outer = Texture(np.full((40, 80), 0.6, np.float32), 8.0, 4.0, name="outer")
    inner = Texture(np.array([[0.2, 1.0], [1.0, 0.2]], np.float32), 2.0, 2.0, name="inner")  # 1 mm cells
    result = compose.tile_inside(inner, outer, (1.0, 1.0, 5.0, 2.0))
    assert result.width_mm == 8.0 and result.cols == 80  # outer's size, its 10 px/mm
    assert result.values[5, 5] == pytest.approx(0.6) and result.values[15, 5] == pytest.approx(0.6)  # outside
    assert result.values[5, 15] == pytest.approx(0.6) and result.values[15, 65] == pytest.approx(0.6)
    assert result.values[35, 15] == pytest.approx(0.6)
    # inside, the inner tile starts at the region's corner (1, 1). Pixel (15, 15) has its centre at
    # (1.55, 1.55) mm, the inner's (0.55, 0.55): bilinear, 0.05 of the way to the next centre both ways:
    # rows 0.95 × 0.2 + 0.05 × 1.0 = 0.24 and 0.95 × 1.0 + 0.05 × 0.2 = 0.96; then 0.95 × 0.24 + 0.05 × 0.96
    low, high = 0.95 * 0.24 + 0.05 * 0.96, 0.95 * 0.96 + 0.05 * 0.24
    assert result.values[15, 15] == pytest.approx(low, abs=1e-6)
    assert result.values[15, 25] == pytest.approx(high, abs=1e-6)
    assert result.values[25, 15] == pytest.approx(high, abs=1e-6)
    assert result.values[15, 35] == pytest.approx(low, abs=1e-6)  # repeated 2 mm on
    with pytest.raises(TextureError, match="misses"):
        compose.tile_inside(inner, outer, (20, 20, 5, 5))


def test_kinds_do_not_mix_and_weights_are_checked():
    with pytest.raises(TextureError, match="do not combine"):
        compose.mix([procedural.bumps(), procedural.grating()])
    with pytest.raises(TextureError, match="one weight per texture"):
        compose.mix([A, B], [1.0])
    with pytest.raises(TextureError, match="not all zero"):
        compose.mix([A, B], [0, 0])
    with pytest.raises(TextureError, match="two textures"):
        compose.minimum([A])
    heights = compose.maximum([procedural.bumps(size_mm=(20, 20)), procedural.bump(size_mm=(20, 20))])
    assert heights.kind == "gradient" and heights.values.max() == pytest.approx(1.0, abs=0.01)


def test_a_composition_whose_tiles_do_not_fit_warns_of_its_seam():
    with pytest.warns(UserWarning, match="seam"):
        compose.mix([procedural.grating(2.0, size_mm=(20, 10)), procedural.grating(3.0, size_mm=(3, 3))])


def test_compose_command_mix_matches_the_hand_computed_mix(tmp_path):
    out = tmp_path / "mix.png"
    result = run_cli("texture", "compose", "mix", "grating-1mm", "grating-square-4mm", "--weights", "3", "1",
                     "-o", out, check=True)
    assert "weighted mix" in result.stdout
    mixed = load_texture(out)
    one, four = resolve_texture("grating-1mm"), resolve_texture("grating-square-4mm")
    np.testing.assert_allclose(mixed.values, 0.75 * one.values + 0.25 * four.values, rtol=0, atol=2e-5)  # 16-bit
    assert (mixed.width_mm, mixed.height_mm, mixed.outside, mixed.source) == (80.0, 50.0, "tile", "composed")
    info = json.loads(run_cli("texture", "info", out, "--json", check=True).stdout)
    assert info["seams"]["seamless"] and info["authoring"]["operation"] == "mix"


def test_compose_command_mask_by_an_image_file_and_tile(tmp_path):
    mask = tmp_path / "mask.png"
    picture = np.zeros((50, 80), np.uint8)
    picture[:, :40] = 255  # white on the left: the grating; black on the right: --else-ratio
    Image.fromarray(picture).save(mask)
    out = tmp_path / "masked.png"
    run_cli("texture", "compose", "mask", "grating-2mm", mask, "--else-ratio", "0.9", "-o", out, check=True)
    masked = load_texture(out).values
    grating = resolve_texture("grating-2mm").values
    np.testing.assert_allclose(masked[:, :390], grating[:, :390], rtol=0, atol=2e-5)  # numpy's: approx is per value
    np.testing.assert_allclose(masked[:, 410:], 0.9, rtol=0, atol=2e-5)
    tiled = tmp_path / "tiled.png"
    run_cli("texture", "compose", "tile", "dots", "wood", "--region", "10,10,30,20", "-o", tiled, check=True)
    texture = load_texture(tiled)
    wood, dots = resolve_texture("wood"), resolve_texture("dots")
    assert (texture.width_mm, texture.height_mm) == (wood.width_mm, wood.height_mm)
    assert texture.values[5, 5] == pytest.approx(wood.values[5, 5], abs=2e-5)
    # at (10.05, 10.05) mm the dots start with their own first pixel
    assert texture.values[100, 100] == pytest.approx(dots.values[0, 0], abs=0.02)


@pytest.mark.parametrize("args, fragment", [
    (["mix", "grating-1mm", "bumps"], "do not combine"),
    (["mix", "grating-1mm", "grating-2mm", "--weights", "1"], "one weight per texture"),
    (["tile", "dots", "wood", "--region", "500,500,5,5"], "misses"),
    (["tile", "dots", "wood", "--region", "1,2,3"], "X,Y,WIDTH,HEIGHT"),
    (["min", "grating-1mm", "no-such-texture"], "no texture file or library texture"),
    (["max", "grating-1mm", "grating-2mm", "--px-per-mm", "1000"], "too many"),
])
def test_compose_command_bad_input_is_one_line_and_leaves_no_file(tmp_path, args, fragment):
    out = tmp_path / "out.png"
    assert fragment in assert_one_line_error(run_cli("texture", "compose", *args, "-o", out))
    assert not out.exists() and not list(tmp_path.iterdir())


def test_composed_texture_is_an_ordinary_texture_file(tmp_path):
    path = save_texture(compose.mix([A, B]), tmp_path / "m.png")
    again = load_texture(path)
    assert again.source == "composed" and again.values == pytest.approx(0.5 * A.values + 0.25, abs=2e-5)
