"""Texture sampling, pinned where scripts/mutation.sh found the quick tests silent: a thin strip (a 1-D
grating a few pixels tall) is band-limited like any other texture, down to a pyramid level 2 pixels tall."""

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
