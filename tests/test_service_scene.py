"""Views and sprites composed into the one texture the engine renders: the topmost sprite under each point,
rotation, stretching, the background; against values worked by hand."""

import math

import numpy as np
import pytest
from ultraglide.apps.service.scene import MAX_COMPOSED_PIXELS, Sprite, View, compose_view, grid_density, sprite_at
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture


def flat(ratio: float, size_mm=(10.0, 10.0), pixels=(20, 20)) -> Texture:
    return Texture(np.full(pixels[::-1], ratio, dtype=np.float32), *size_mm, name=f"flat {ratio}")


def ratio_at(texture: Texture, x_mm: float, y_mm: float) -> float:
    value = Sampler(texture, band_limited=False).ratio(np.array([x_mm]), np.array([y_mm]),
                                                       direction=(np.ones(1), np.zeros(1)))
    return float(value[0])


VIEW_MM = View("main", 100.0, 50.0, "mm", 100.0, 50.0, background_ratio=0.9)


def test_the_topmost_sprite_is_felt_and_the_background_elsewhere():
    textures = {"a": flat(0.3), "b": flat(0.6)}
    sprites = [Sprite("low", "main", "a", 10, 10, 30, 20, z=0, order=1),
               Sprite("high", "main", "b", 30, 10, 30, 20, z=1, order=2)]
    composed = compose_view(VIEW_MM, sprites, textures)
    assert ratio_at(composed, 15, 20) == pytest.approx(0.3, abs=1e-6)  # only the low one
    assert ratio_at(composed, 35, 20) == pytest.approx(0.6, abs=1e-6)  # both: the higher z
    assert ratio_at(composed, 55, 20) == pytest.approx(0.6, abs=1e-6)
    assert ratio_at(composed, 80, 40) == pytest.approx(0.9, abs=1e-6)  # none: the background
    assert composed.outside == "fixed" and composed.outside_ratio == 0.9  # beyond the view too
    assert sprite_at(VIEW_MM, sprites, 35, 20).name == "high"
    # reordered: z lowered below the other
    sprites[1] = sprites[1].with_(z=-1)
    assert ratio_at(compose_view(VIEW_MM, sprites, textures), 35, 20) == pytest.approx(0.3, abs=1e-6)
    assert sprite_at(VIEW_MM, sprites, 35, 20).name == "low"


def test_equal_z_the_later_placed_is_on_top_and_hidden_sprites_are_not_felt():
    textures = {"a": flat(0.3), "b": flat(0.6)}
    sprites = [Sprite("first", "main", "a", 0, 0, 50, 50, order=1),
               Sprite("second", "main", "b", 0, 0, 50, 50, order=2)]
    assert ratio_at(compose_view(VIEW_MM, sprites, textures), 25, 25) == pytest.approx(0.6, abs=1e-6)
    sprites[1] = sprites[1].with_(visible=False)
    assert ratio_at(compose_view(VIEW_MM, sprites, textures), 25, 25) == pytest.approx(0.3, abs=1e-6)
    assert sprite_at(VIEW_MM, sprites, 25, 25).name == "first"


def test_a_rotated_sprite_covers_its_turned_rectangle():
    # 40 × 10 mm centred at (50, 25), turned 90°: it covers x 45..55, y 5..45
    sprites = [Sprite("bar", "main", "a", 30, 20, 40, 10, rotation_deg=90, order=1)]
    composed = compose_view(VIEW_MM, sprites, {"a": flat(0.2)})
    assert ratio_at(composed, 50, 8) == pytest.approx(0.2, abs=1e-6)
    assert ratio_at(composed, 50, 42) == pytest.approx(0.2, abs=1e-6)
    assert ratio_at(composed, 35, 25) == pytest.approx(0.9, abs=1e-6)  # where it lay before turning
    assert sprite_at(VIEW_MM, sprites, 50, 8) is not None and sprite_at(VIEW_MM, sprites, 35, 25) is None


def test_rotation_is_clockwise_on_the_screen_and_the_texture_turns_with_it():
    # a texture dark on its left half, light on its right; turned 90° clockwise (y down), its left goes to the top
    values = np.ones((10, 20), dtype=np.float32)
    values[:, :10] = 0.2
    texture = Texture(values, 20.0, 10.0)
    sprite = Sprite("s", "main", "t", 40, 20, 20, 10, rotation_deg=90, order=1)  # centre (50, 25): covers y 15..35
    composed = compose_view(VIEW_MM, [sprite], {"t": texture})
    assert ratio_at(composed, 50, 18) == pytest.approx(0.2, abs=1e-6)  # its left half, now at the top
    assert ratio_at(composed, 50, 32) == pytest.approx(1.0, abs=1e-6)
    u, v = sprite.local_mm(VIEW_MM, 50.0, 18.0)
    assert (u, v) == pytest.approx((3.0, 5.0))  # 7 mm above the centre: 7 mm left of it before turning


def test_a_sprite_stretches_its_texture_over_its_rectangle_in_px_views():
    # 400 × 200 px at 0.25 mm a px: 100 × 50 mm. A 10 mm texture with a step at its middle, stretched to 200 px
    view = View("main", 400, 200, "px", 100.0, 50.0)
    values = np.ones((10, 20), dtype=np.float32)
    values[:, 10:] = 0.5
    texture = Texture(values, 10.0, 5.0)
    sprite = Sprite("s", "main", "t", 0, 0, 200, 100, order=1)  # 50 × 25 mm
    composed = compose_view(view, [sprite], {"t": texture})
    assert ratio_at(composed, 22.0, 10) == pytest.approx(1.0, abs=1e-6)  # texture pixels 2.5 mm wide now
    assert ratio_at(composed, 28.0, 10) == pytest.approx(0.5, abs=1e-6)  # the step at 25 mm, not at 5 mm
    assert ratio_at(composed, 60.0, 10) == pytest.approx(1.0, abs=1e-6)
    assert view.to_mm(100, 40) == (25.0, 10.0)


def test_the_grid_follows_the_finest_sprite_within_the_budget():
    view = View("main", 1000.0, 1000.0, "mm", 1000.0, 1000.0)
    fine = Sprite("s", "main", "t", 0, 0, 10, 10, order=1)
    texture = flat(0.5, (10.0, 10.0), (200, 200))  # 20 px per mm as stretched over 10 mm
    density = grid_density(view, [fine], {"t": texture})
    assert density == pytest.approx(math.sqrt(MAX_COMPOSED_PIXELS / 1e6))  # held by the budget: 2 px per mm
    small = View("main", 50.0, 50.0, "mm", 50.0, 50.0)
    assert grid_density(small, [fine], {"t": texture}) == pytest.approx(20.0)
