"""The sampling's tests."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.textures import procedural
from ultraglide.textures.sampling import Sampler, gradient_maps
from ultraglide.textures.texture import Texture


def test_a_strip_four_pixels_tall_is_band_limited_at_a_two_pixel_step():
    texture = procedural.grating(2.0, size_mm=(64.0, 0.5), px_per_mm=8.0, ratio_range=(0.0, 1.0))
    assert texture.values.shape == (4, 512)  # a 16-pixel period along x, 4 pixels tall
    pixel_mm = texture.pixel_mm[0]
    x = 0.37 * pixel_mm + np.arange(4000) * 2.0 * pixel_mm  # two pixels a sample
    y = np.full_like(x, 0.25)
    limited = Sampler(texture).ratio(x, y, step_mm=2.0 * pixel_mm)
    plain = Sampler(texture, band_limited=False).ratio(x, y)
    tone = np.exp(-2j * np.pi * x / 2.0)
    gain = abs(np.mean((limited - limited.mean()) * tone)) / abs(np.mean((plain - plain.mean()) * tone))
    # level 1 (2 pixels tall): a Gaussian of sigma 1 pixel keeps exp(-2 pi^2 / 16^2) of a 16-pixel period,
    # the 2:1 linear decimation cos(pi / 16), linear interpolation at 8 pixels a period sinc^2(1/8)
    expected = np.exp(-2 * np.pi ** 2 / 16 ** 2) * np.cos(np.pi / 16) * np.sinc(1 / 8) ** 2
    assert gain == pytest.approx(expected, abs=0.03)


def _sine_heights(outside: str):
    """Heights 0.5 + 0.25 sin(2 pi i / 16) + 0.2 cos(2 pi j / 10) on 16 x 10 pixels of 0.5 x 2 mm."""
    i, j = np.arange(16), np.arange(10)[:, None]
    values = (0.5 + 0.25 * np.sin(2 * np.pi * i / 16) + 0.2 * np.cos(2 * np.pi * j / 10)).astype(np.float32)
    return Texture(values, 8.0, 20.0, kind="gradient", outside=outside), values.astype(float), i, j


def test_slopes_of_a_tiled_height_map_are_central_differences_round_the_seam():
    texture, _, i, j = _sine_heights("tile")
    slope_x, slope_y = gradient_maps(texture)
    # (sin(a + d) - sin(a - d)) / 2h = cos(a) sin(d) / h, on every pixel, the first and last included
    expected_x = 0.25 * np.cos(2 * np.pi * i / 16) * np.sin(2 * np.pi / 16) / 0.5
    expected_y = -0.2 * np.sin(2 * np.pi * j / 10) * np.sin(2 * np.pi / 10) / 2.0
    np.testing.assert_allclose(slope_x, np.broadcast_to(expected_x, (10, 16)), atol=2e-6)
    np.testing.assert_allclose(slope_y, np.broadcast_to(expected_y, (10, 16)), atol=2e-6)


def test_slopes_of_a_clamped_height_map_are_one_sided_at_the_edges():
    texture, values, i, j = _sine_heights("clamp")
    slope_x, slope_y = gradient_maps(texture)
    inner_x = 0.25 * np.cos(2 * np.pi * i[1:-1] / 16) * np.sin(2 * np.pi / 16) / 0.5
    inner_y = -0.2 * np.sin(2 * np.pi * j[1:-1] / 10) * np.sin(2 * np.pi / 10) / 2.0
    np.testing.assert_allclose(slope_x[:, 1:-1], np.broadcast_to(inner_x, (10, 14)), atol=2e-6)
    np.testing.assert_allclose(slope_y[1:-1, :], np.broadcast_to(inner_y, (8, 16)), atol=2e-6)
    np.testing.assert_allclose(slope_x[:, 0], (values[:, 1] - values[:, 0]) / 0.5, atol=2e-6)  # no wrap
    np.testing.assert_allclose(slope_y[-1, :], (values[-1, :] - values[-2, :]) / 2.0, atol=2e-6)


def _level_gain(level: int, period_px: float = 16.0) -> float:
    """Amplitude kept by pyramid level ``level`` of a sine ``period_px`` pixels long, read bilinearly: each
    level down, a Gaussian of sigma 1 pixel keeps exp(-2 pi^2 / P^2) and the 2:1 linear decimation (a
    midpoint of two pixels) cos(pi / P); linear interpolation at P pixels a period keeps sinc^2(1 / P)."""
    gain = 1.0
    for _ in range(level):
        gain *= np.exp(-2 * np.pi ** 2 / period_px ** 2) * np.cos(np.pi / period_px)
        period_px /= 2
    return gain * np.sinc(1 / period_px) ** 2


def _blend(level: float, top: int = 2) -> float:
    """The gain read at a fractional ``level``: the two levels around it in proportion (trilinear); a level
    beyond the top one reads the top one alone."""
    level = min(level, top)
    low = int(level)
    return (1 - (level - low)) * _level_gain(low) + (level - low) * _level_gain(min(low + 1, top))


# pyramid level read (a fraction blends the two around it; 5 is beyond the top level, 2) -> expected gain
BLENDS = {0.0: _level_gain(0), 0.75: 0.25 * _level_gain(0) + 0.75 * _level_gain(1),
          1.25: 0.75 * _level_gain(1) + 0.25 * _level_gain(2), 5.0: _level_gain(2)}


def _sine_strip(axis: str, across_px: int = 8, **kind):
    """A sine of 16 pixels (4 mm) along ``axis``, 64 x ``across_px`` pixels of 0.25 mm along it by 0.5 mm
    across (with 8 pixels across three pyramid levels, 8, 4 and 2 pixels; with 4, two); positions 16 a pixel
    along it, one across. ``kind``: the texture's kind and its options."""
    wave = (0.5 + 0.4 * np.sin(2 * np.pi * np.arange(64) / 16)).astype(np.float32)
    along = (np.arange(4096) + 0.5) * 16.0 / 4096
    across = np.full_like(along, 1.3)
    if axis == "x":
        texture = Texture(np.broadcast_to(wave, (across_px, 64)).copy(), 16.0, across_px / 2, **kind)
        return texture, along, across, along
    texture = Texture(np.broadcast_to(wave[:, None], (64, across_px)).copy(), across_px / 2, 16.0, **kind)
    return texture, across, along, along


def _gain(ratio: np.ndarray, along: np.ndarray) -> float:
    """The amplitude of the 4 mm sine in ``ratio`` over the texture's 0.4."""
    return 2 * abs(np.mean(ratio * np.exp(-2j * np.pi * along / 4.0))) / 0.4


@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("path", ["scalar step", "step per sample", "2-d step per sample", "live block"])
def test_a_step_between_pyramid_levels_blends_them_in_proportion(axis, path):
    texture, x, y, along = _sine_strip(axis)
    sampler = Sampler(texture)
    assert sampler.levels == 3
    for level, expected in BLENDS.items():
        step_mm = 0.5 * 2 ** level  # the level is log2 of the step over the larger pixel side, 0.5 mm
        if path == "scalar step":
            ratio = sampler.ratio(x, y, step_mm=step_mm)
        elif path == "step per sample":
            ratio = sampler.ratio(x, y, step_mm=np.full(x.shape, step_mm))
        elif path == "2-d step per sample":
            ratio = sampler.ratio(x.reshape(64, 64), y.reshape(64, 64), step_mm=np.full((64, 64), step_mm))
        else:
            ratio = sampler.ratio(x, y, step_mm=step_mm, out=np.empty(x.shape, dtype=np.float32))
        assert _gain(ratio.reshape(-1), along) == pytest.approx(expected, abs=2e-3), (level, path)
    unlimited = sampler.ratio(x, y) if path != "live block" else sampler.ratio(x, y, out=np.empty(x.shape, np.float32))
    assert _gain(unlimited, along) == pytest.approx(BLENDS[0.0], abs=2e-3)  # no step: full resolution


@pytest.mark.parametrize("outside", ["tile", "clamp", "fixed"])
def test_steps_within_a_pixel_read_the_full_resolution_level_to_the_bit(outside):
    texture, x, y, _ = _sine_strip("x")
    texture = Texture(texture.values, texture.width_mm, texture.height_mm, outside=outside)
    sampler = Sampler(texture)
    x = np.concatenate([x, x - 20.0, x + 40.0])  # on the texture and beyond its edges, both sides
    y = np.concatenate([y, y + 30.0, y - 50.0])
    steps = np.random.default_rng(2).uniform(0.0, sampler.base_pixel_mm, len(x))  # a slow finger's
    np.testing.assert_array_equal(sampler.ratio(x, y, step_mm=steps), sampler.ratio(x, y))


@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("levels", [(0.0, 0.75, 1.25, 5.0), (0.0, 1.25, 5.0)])  # the second: level 0 unblended
def test_one_query_with_steps_at_several_levels_blends_each_sample_by_its_own(axis, levels):
    texture, x, y, along = _sine_strip(axis)
    steps = 0.5 * 2 ** np.array(levels)[:, None]  # a row of 4096 samples for each level
    shape = (len(levels), 4096)
    ratio = Sampler(texture).ratio(np.broadcast_to(x, shape), np.broadcast_to(y, shape), np.broadcast_to(steps, shape))
    for row, level in zip(ratio, levels, strict=True):
        assert _gain(row, along) == pytest.approx(BLENDS[level], abs=2e-3), level


@pytest.mark.parametrize("path", ["scalar step", "live block"])
def test_a_strip_of_two_levels_blends_them_and_stops_at_the_second(path):
    texture, x, y, along = _sine_strip("x", across_px=4)
    sampler = Sampler(texture)
    assert sampler.levels == 2
    # level 0.75: a quarter of level 0 and three quarters of level 1; beyond, level 1 alone
    for level, expected in ((0.75, _blend(0.75, top=1)), (1.25, _blend(1.25, top=1)), (5.0, _level_gain(1))):
        out = np.empty(x.shape, dtype=np.float32) if path == "live block" else None
        assert _gain(sampler.ratio(x, y, step_mm=0.5 * 2 ** level, out=out), along) == pytest.approx(expected, abs=2e-3)


@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("path", ["scalar step", "live block", "direction per sample"])
@pytest.mark.parametrize("across_px", [8, 4])
def test_a_height_map_read_between_pyramid_levels_blends_its_slopes_in_proportion(axis, path, across_px):
    texture, x, y, along = _sine_strip(axis, across_px, kind="gradient", ratio_range=(0.2, 0.9), full_slope_per_mm=2.0)
    sampler = Sampler(texture)
    top = sampler.levels - 1
    assert top == {8: 2, 4: 1}[across_px]
    direction = (3.0, 0.0) if axis == "x" else (0.0, -3.0)  # any length: only the direction counts
    # the central difference of 0.4 sin(2 pi i / 16) over 0.25 mm pixels: 0.4 sin(2 pi / 16) / 0.25 per mm;
    # a slope of 2 per mm would reach the range's end, 0.35 from its middle (0.55): no clipping here
    slope_ratio = 0.35 / 2.0 * (0.4 * np.sin(2 * np.pi / 16) / 0.25)
    for level in (None, 0.0, 0.75, 1.25, 5.0):
        step_mm = None if level is None else 0.5 * 2 ** level
        expected = _blend(level or 0.0, top)
        if path == "scalar step":
            ratio = sampler.ratio(x, y, step_mm=step_mm, direction=direction)
        elif path == "live block":
            ratio = sampler.ratio(x, y, step_mm=step_mm, direction=direction, out=np.empty(x.shape, np.float32))
        else:
            ratio = sampler.ratio(x, y, step_mm=step_mm, direction=tuple(np.full(x.shape, d) for d in direction))
        assert np.mean(ratio) == pytest.approx(0.55, abs=1e-3)  # flat on average: the range's middle
        assert 2 * abs(np.mean(ratio * np.exp(-2j * np.pi * along / 4.0))) == pytest.approx(
            slope_ratio * expected, abs=1e-3), (level, path)


def test_each_pyramid_level_is_half_the_one_before_rounded_until_a_side_is_under_4_pixels():
    values = np.random.default_rng(3).random((11, 27)).astype(np.float32)
    sampler = Sampler(Texture(values, 27.0, 11.0))
    # 11 x 27 -> round(5.5) = 6 x round(13.5) = 14 -> 3 x 7, which is under 4 pixels tall: the top level
    assert [level.shape for level in sampler.pyramids[0]] == [(11, 27), (6, 14), (3, 7)]
    assert Sampler(Texture(values, 27.0, 11.0), band_limited=False).levels == 1
    assert [level.shape for level in Sampler(Texture(values, 27.0, 11.0), max_levels=2).pyramids[0]] == [(11, 27),
                                                                                                      (6, 14)]


@pytest.mark.parametrize("outside", ["tile", "clamp"])
@pytest.mark.parametrize("shape", [(11, 27), (64, 48), (5, 9), (33, 4)])
def test_each_pyramid_level_is_scipys_gaussian_blur_then_half_size_linear_zoom(outside, shape):
    """The levels, built without scipy, against scipy.ndimage's own blur and zoom (its edge modes named
    for a tile and for a clamped texture)."""
    from scipy import ndimage

    values = np.random.default_rng(5).random(shape).astype(np.float32)
    texture = Texture(values, 3.0 * shape[1], 3.0 * shape[0], outside=outside)
    mode, grid_mode = ("wrap", "grid-wrap") if outside == "tile" else ("nearest", "nearest")
    expected = values
    for level in Sampler(texture).pyramids[0][1:]:
        blurred = ndimage.gaussian_filter(expected, sigma=1.0, mode=mode)
        zoom = (level.shape[0] / expected.shape[0], level.shape[1] / expected.shape[1])
        expected = ndimage.zoom(blurred, zoom, order=1, mode=grid_mode, grid_mode=True)
        assert level.shape == expected.shape and level.dtype == np.float32
        assert level == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("kind", ["friction", "gradient"])
def test_a_fixed_outside_starts_exactly_at_the_edges(kind):
    # 10 x 5 mm of 0.75 (flat ground for a height map: the middle of 0.5..1), 0.25 beyond its edges:
    # the texture covers [0, 10) x [0, 5), so 0 is inside and 10 (or 5) outside, on each axis alone
    values = np.full((20, 40), 0.75, dtype=np.float32)
    extra = {"ratio_range": (0.5, 1.0)} if kind == "gradient" else {}
    texture = Texture(values, 10.0, 5.0, kind=kind, outside="fixed", outside_ratio=0.25, **extra)
    points = {(-0.001, 2.0): 0.25, (0.0, 2.0): 0.75, (0.5, 2.0): 0.75, (9.999, 2.0): 0.75, (10.0, 2.0): 0.25,
              (4.0, -0.001): 0.25, (4.0, 0.0): 0.75, (4.0, 0.5): 0.75, (4.0, 4.999): 0.75, (4.0, 5.0): 0.25}
    x, y = (np.array(axis) for axis in zip(*points, strict=True))
    direction = (np.ones_like(x), np.zeros_like(x))  # per sample: the general path, where the mask is applied
    for step_mm in (None, 1.0):
        ratio = Sampler(texture).ratio(x, y, step_mm=step_mm, direction=direction)
        np.testing.assert_allclose(ratio, list(points.values()), atol=1e-6)


def _two_way_slopes():
    """Heights 0.5 + 0.25 sin(2 pi i / 16) + 0.2 cos(2 pi j / 10), tiled, on 16 x 10 pixels of 0.5 x 2 mm,
    read at the pixel centres, where bilinear reads a pixel's own slope: the central differences
    d/dx = 0.25 cos(2 pi i / 16) sin(2 pi / 16) / 0.5 and d/dy = -0.2 sin(2 pi j / 10) sin(2 pi / 10) / 2
    per mm; ratios 0.2..0.9 with a slope of 1 per mm reaching an end (0.35 from flat ground, 0.55)."""
    i, j = np.meshgrid(np.arange(16), np.arange(10))
    values = (0.5 + 0.25 * np.sin(2 * np.pi * i / 16) + 0.2 * np.cos(2 * np.pi * j / 10)).astype(np.float32)
    texture = Texture(values, 8.0, 20.0, kind="gradient", ratio_range=(0.2, 0.9), full_slope_per_mm=1.0)
    x, y = (i.ravel() + 0.5) * 0.5, (j.ravel() + 0.5) * 2.0
    slope_x = 0.25 * np.cos(2 * np.pi * i.ravel() / 16) * np.sin(2 * np.pi / 16) / 0.5
    slope_y = -0.2 * np.sin(2 * np.pi * j.ravel() / 10) * np.sin(2 * np.pi / 10) / 2.0
    return Sampler(texture), x, y, slope_x, slope_y


HEIGHT_PATHS = ["live block", "one direction", "direction per sample", "grid, one direction"]


def _read_along(sampler, x, y, step_mm, direction, path):
    """A height map read by one of its paths: the live block's compiled pass (``out=``), one direction for
    the query (compiled at full resolution), a direction per sample (numpy), or positions in a grid (numpy)."""
    if path == "grid, one direction":
        return sampler.ratio(x.reshape(10, 16), y.reshape(10, 16), step_mm, direction).ravel()
    if path == "live block":
        return sampler.ratio(x, y, step_mm, direction, out=np.empty(x.shape, np.float32))
    if path == "direction per sample" and direction is not None:
        direction = tuple(np.full(x.shape, d) for d in direction)
    return sampler.ratio(x, y, step_mm, direction)


@pytest.mark.parametrize("path", HEIGHT_PATHS)
@pytest.mark.parametrize("direction", [None, (0.0, 0.0)], ids=["absent", "zero"])
def test_a_height_map_read_at_rest_is_flat_ground_by_every_path(path, direction):
    sampler, x, y, _, _ = _two_way_slopes()
    assert sampler.levels == 3  # 10 x 16, 5 x 8, 2 x 4 pixels; the larger side of a pixel is 2 mm
    for step_mm in (None, 1.0, 3.0, 5.0, 100.0):  # full resolution, blends of two levels, the top one
        np.testing.assert_allclose(_read_along(sampler, x, y, step_mm, direction, path), 0.55, atol=1e-6)


@pytest.mark.parametrize("path", HEIGHT_PATHS)
@pytest.mark.parametrize("direction", [(0.5, 0.0), (0.0, -0.25), (0.3, 0.4), (-3.0, 4.0)])
def test_a_height_map_reads_its_slope_along_the_motion_whatever_the_length_of_the_direction(path, direction):
    sampler, x, y, slope_x, slope_y = _two_way_slopes()
    length = np.hypot(*direction)  # under 1, 1 and over 1: only the direction counts
    expected = 0.55 + 0.35 * (slope_x * direction[0] + slope_y * direction[1]) / length
    np.testing.assert_allclose(_read_along(sampler, x, y, None, direction, path), expected, atol=2e-6)


@pytest.mark.parametrize(("kind", "path"), [("friction", "live block"), ("gradient", "live block"),
                                            ("friction", "step per sample")])
def test_a_fixed_outside_starts_exactly_at_the_edges_in_the_compiled_passes(kind, path):
    """As the general path above, through the live block's compiled pass (any kind, one step and one
    direction for the block) and the compiled per-sample pass (an export's, friction maps)."""
    values = np.full((20, 40), 0.75, dtype=np.float32)
    extra = {"ratio_range": (0.5, 1.0)} if kind == "gradient" else {}
    texture = Texture(values, 10.0, 5.0, kind=kind, outside="fixed", outside_ratio=0.25, **extra)
    points = {(-0.001, 2.0): 0.25, (0.0, 2.0): 0.75, (0.5, 2.0): 0.75, (9.999, 2.0): 0.75, (10.0, 2.0): 0.25,
              (4.0, -0.001): 0.25, (4.0, 0.0): 0.75, (4.0, 0.5): 0.75, (4.0, 4.999): 0.75, (4.0, 5.0): 0.25,
              (-30.0, -30.0): 0.25, (55.0, 2.0): 0.25}
    x, y = (np.array(axis, dtype=np.float64) for axis in zip(*points, strict=True))
    sampler = Sampler(texture)
    for step_mm in (None, 0.1, 1.0):
        if path == "live block":
            ratio = sampler.ratio(x, y, step_mm, (1.0, 0.0), out=np.empty(x.shape, np.float32))
        else:
            ratio = sampler.ratio(x, y, np.full(x.shape, 0.1 if step_mm is None else step_mm))
        np.testing.assert_allclose(ratio, list(points.values()), atol=1e-6)


def test_a_query_that_is_not_a_live_block_writes_its_ratios_into_out():
    """``out=`` with positions in a grid, in float32 or as lists, or a step per sample: not the live block's
    one compiled pass, but the same ratios, written into ``out``. Read at the pixel centres of a 4 x 5 map
    of 1 mm pixels, bilinear gives each pixel's own value."""
    values = (np.arange(20).reshape(4, 5) / 20).astype(np.float32)
    sampler = Sampler(Texture(values, 5.0, 4.0))
    x, y = np.meshgrid(np.arange(5) + 0.5, np.arange(4) + 0.5)
    queries = {"grid": (x, y, None), "float32": (x.ravel().astype(np.float32), y.ravel().astype(np.float32), None),
               "lists": (list(x.ravel()), list(y.ravel()), None), "step per sample": (x.ravel(), y.ravel(),
                                                                                    np.zeros(20))}
    for name, (qx, qy, step_mm) in queries.items():
        out = np.full(np.shape(qx), np.nan, dtype=np.float32)
        assert sampler.ratio(qx, qy, step_mm, out=out) is out
        np.testing.assert_allclose(out, values.reshape(out.shape), atol=1e-6, err_msg=name)


@pytest.mark.parametrize("kind", [{}, {"kind": "gradient", "ratio_range": (0.2, 0.9), "full_slope_per_mm": 2.0}],
                         ids=["friction", "gradient"])
def test_a_lookup_that_is_not_band_limited_reads_full_resolution_in_a_live_block_at_any_step(kind):
    texture, x, y, along = _sine_strip("x", **kind)
    sampler = Sampler(texture, band_limited=False)
    assert sampler.levels == 1
    plain = sampler.ratio(x, y, direction=(1.0, 0.0))
    for step_mm in (None, 0.25, 2.0):
        live = sampler.ratio(x, y, step_mm, (1.0, 0.0), out=np.empty(x.shape, np.float32))
        np.testing.assert_allclose(live, plain, atol=1e-6)
    if not kind:  # a friction map: the sine itself, its amplitude read bilinearly at 16 pixels a period
        assert _gain(plain, along) == pytest.approx(_level_gain(0), abs=2e-3)


def test_a_height_map_with_a_step_or_a_direction_per_sample_reads_its_slopes_also_into_out():
    sampler, x, y, slope_x, slope_y = _two_way_slopes()
    direction = (np.full(x.shape, 0.6), np.full(x.shape, -0.8))
    expected = 0.55 + 0.35 * (0.6 * slope_x - 0.8 * slope_y)
    steps = np.full(x.shape, 0.5)  # finer than the 2 mm pixels: full resolution
    np.testing.assert_allclose(sampler.ratio(x, y, steps, direction), expected, atol=2e-6)
    out = np.full(x.shape, np.nan, dtype=np.float32)
    assert sampler.ratio(x, y, None, direction, out=out) is out
    np.testing.assert_allclose(out, expected, atol=2e-6)


def _lookup_gain(step_px: float, per_sample: bool = False) -> float:
    """How much of a 16-pixel sine grating's swing the band-limited lookup keeps at this step,
    against the plain bilinear lookup at the same points (projection on the grating's frequency)."""
    texture = procedural.grating(2.0, size_mm=(64.0, 40.0), px_per_mm=8.0, ratio_range=(0.0, 1.0))
    pixel_mm = texture.pixel_mm[0]
    assert pixel_mm == pytest.approx(0.125)
    x = 0.37 * pixel_mm + np.arange(4000) * step_px * pixel_mm
    y = np.full_like(x, 20.0)
    step_mm = np.full_like(x, step_px * pixel_mm) if per_sample else step_px * pixel_mm
    limited = Sampler(texture).ratio(x, y, step_mm=step_mm)
    plain = Sampler(texture, band_limited=False).ratio(x, y)
    tone = np.exp(-2j * np.pi * x / 2.0)
    return abs(np.mean((limited - limited.mean()) * tone)) / abs(np.mean((plain - plain.mean()) * tone))


@pytest.mark.parametrize("per_sample", [False, True], ids=["one-step", "step-per-sample"])
@pytest.mark.parametrize("step_px", [0.25, 1.0])
def test_band_limited_lookup_reads_full_resolution_while_the_step_is_a_pixel_or_less(step_px, per_sample):
    assert _lookup_gain(step_px, per_sample) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("per_sample", [False, True], ids=["one-step", "step-per-sample"])
def test_band_limited_lookup_reads_the_level_the_step_asks_for(per_sample):
    # a step of two pixels reads pyramid level 1: a Gaussian of sigma 1 pixel keeps exp(-2 pi^2 / 16^2)
    # of a 16-pixel period, the 2:1 linear decimation cos(pi / 16), and linear interpolation between
    # level-1 pixels (8 a period) sinc^2(1/8) on average. One level coarser keeps about 0.5.
    expected = np.exp(-2 * np.pi ** 2 / 16 ** 2) * np.cos(np.pi / 16) * np.sinc(1 / 8) ** 2
    assert _lookup_gain(2.0, per_sample) == pytest.approx(expected, abs=0.03)
