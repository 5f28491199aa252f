"""Texture sampling, pinned where scripts/mutation.sh found the quick tests silent: a thin strip (a 1-D
grating a few pixels tall) is band-limited like any other texture, down to a pyramid level 2 pixels tall."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.textures import procedural
from ultraglide.textures.sampling import Sampler


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
