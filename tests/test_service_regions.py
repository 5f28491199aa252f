"""Where a sprite is felt, as the rectangles its attached effects play over (``scene.sprite_regions``): exact where
every sprite concerned is turned by a right angle, against rectangles worked by hand; a staircase within its pitch
where one is turned otherwise, against the sprite's own geometry."""

import math

import numpy as np
import pytest
from ultraglide.apps.service.scene import Sprite, View, sprite_regions

VIEW = View("main", 100.0, 50.0, "mm", 100.0, 50.0)


def as_set(rectangles):
    return {tuple(round(v, 9) for v in r) for r in rectangles}


def test_a_sprite_alone_is_its_rectangle_clipped_to_the_view():
    sprites = [Sprite("a", "main", "t", 10, 5, 30, 20, order=1)]
    assert as_set(sprite_regions(VIEW, sprites, "a", 32)) == {(10, 5, 30, 20)}
    # half beyond the right edge: the part on the view
    sprites = [Sprite("a", "main", "t", 80, 5, 40, 20, order=1)]
    assert as_set(sprite_regions(VIEW, sprites, "a", 32)) == {(80, 5, 20, 20)}


def test_the_part_under_a_sprite_on_top_is_left_out():
    a = Sprite("a", "main", "t", 0, 0, 40, 20, order=1)
    b = Sprite("b", "main", "t", 30, 10, 20, 20, z=1, order=2)  # covers a's 30..40 × 10..20
    # by hand: the top half whole, the bottom half up to x = 30
    assert as_set(sprite_regions(VIEW, [a, b], "a", 32)) == {(0, 0, 40, 10), (0, 10, 30, 10)}
    # b below a instead: a is whole again, and b is what a leaves of it
    b = b.with_(z=-1)
    assert as_set(sprite_regions(VIEW, [a, b], "a", 32)) == {(0, 0, 40, 20)}
    assert as_set(sprite_regions(VIEW, [a, b], "b", 32)) == {(40, 10, 10, 10), (30, 20, 20, 10)}
    # hidden, or wholly covered: nowhere
    assert sprite_regions(VIEW, [a.with_(visible=False), b], "a", 32) == []
    big = Sprite("c", "main", "t", 0, 0, 100, 50, z=5, order=3)
    assert sprite_regions(VIEW, [a, b, big], "a", 32) == []
    # not enough rectangles allowed: None, not a wrong shape
    assert sprite_regions(VIEW, [a, b.with_(z=1)], "a", 1) is None


def test_a_right_angle_turn_is_exact():
    # 40 × 10 mm about its centre (30, 15), turned 90°: upright, 25..35 × -5..35, clipped at the top
    bar = Sprite("bar", "main", "t", 10, 10, 40, 10, rotation_deg=90, order=1)
    (x, y, w, h), = sprite_regions(VIEW, [bar], "bar", 32)
    assert (x, y, w, h) == pytest.approx((25, 0, 10, 35))


def test_a_turned_sprite_is_a_staircase_close_to_its_shape():
    # a 30 mm square about (45, 20) turned 45°: the diamond |x - 45| + |y - 20| <= 30 / √2
    diamond = Sprite("d", "main", "t", 30, 5, 30, 30, rotation_deg=45, order=1)
    rectangles = sprite_regions(VIEW, [diamond], "d", 32)
    assert rectangles is not None and 4 < len(rectangles) <= 32
    xs, ys = np.meshgrid(np.linspace(20, 70, 501), np.linspace(0, 50, 501))
    in_rectangles = np.zeros(xs.shape, bool)
    for x, y, w, h in rectangles:
        in_rectangles |= (xs >= x) & (xs < x + w) & (ys >= y) & (ys < y + h)
    on_diamond = np.abs(xs - 45) + np.abs(ys - 20) <= 30 / math.sqrt(2)
    # the staircase's area misjudged: a tenth of the sprite's at most (its steps over 32 rectangles)
    assert np.mean(in_rectangles != on_diamond) * 50 * 50 < 0.1 * 30 * 30
    # no rectangle strays far from it: each one's centre within the diamond grown by a few mm
    for x, y, w, h in rectangles:
        assert abs(x + w / 2 - 45) + abs(y + h / 2 - 20) <= 30 / math.sqrt(2) + 3
    # the same sprite allowed more rectangles follows it closer
    finer = sprite_regions(VIEW, [diamond], "d", 400)
    in_finer = np.zeros(xs.shape, bool)
    for x, y, w, h in finer:
        in_finer |= (xs >= x) & (xs < x + w) & (ys >= y) & (ys < y + h)
    assert np.mean(in_finer != on_diamond) < np.mean(in_rectangles != on_diamond) / 2
