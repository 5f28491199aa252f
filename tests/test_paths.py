"""Synthetic finger paths (export's --path): positions against hand-computed geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ultraglide.render.errors import RenderError
from ultraglide.render.paths import SwipePath


def test_a_zigzag_goes_back_and_forth_and_steps_sideways_at_each_end():
    path = SwipePath("zigzag", speed_mm_s=100.0, duration_s=2.0, start_mm=(5.0, 10.0), width_mm=40.0, pitch_mm=3.0)
    # 0.25 s: 25 mm out; 0.5 s: 50 mm = out 40 and back 10 (pass 2); 0.9 s: 90 mm, out 10 on pass 3;
    # 2 s (and after): 200 mm, the end of pass 5, 40 mm out and 4 steps over
    state = path.state(np.array([0.0, 0.25, 0.5, 0.9, 2.0, 2.5, -0.1]))
    np.testing.assert_allclose(state.x_mm, [5.0, 30.0, 35.0, 15.0, 45.0, 45.0, 5.0], atol=1e-12)
    np.testing.assert_allclose(state.y_mm, [10.0, 10.0, 13.0, 16.0, 25.0, 25.0, 10.0], atol=1e-12)
    assert state.down.tolist() == [True, True, True, True, True, False, False]
    assert math.isnan(state.force_n)


def test_a_straight_swipe_follows_its_heading():
    path = SwipePath("straight", speed_mm_s=50.0, duration_s=1.0, start_mm=(20.0, 30.0), direction_deg=90.0,
                     force_n=0.8)
    state = path.state(np.array([[0.2, 0.4], [1.0, 3.0]]))  # any shape of times
    np.testing.assert_allclose(state.x_mm, 20.0, atol=1e-12)
    np.testing.assert_allclose(state.y_mm, [[40.0, 50.0], [80.0, 80.0]], atol=1e-12)
    assert state.down.tolist() == [[True, True], [True, False]] and state.force_n == 0.8


def test_a_circle_starts_on_its_left_and_turns_counter_clockwise_on_screen():
    radius = 15.0
    path = SwipePath("circle", speed_mm_s=math.pi * radius, duration_s=2.0, start_mm=(10.0, 40.0), radius_mm=radius)
    # a quarter turn a half second: bottom of the circle on screen (y down) is up on the plate's y
    state = path.state(np.array([0.0, 0.5, 1.0, 1.5]))
    np.testing.assert_allclose(state.x_mm, [10.0, 25.0, 40.0, 25.0], atol=1e-12)
    np.testing.assert_allclose(state.y_mm, [40.0, 25.0, 40.0, 55.0], atol=1e-12)
    distance = np.hypot(state.x_mm - 25.0, state.y_mm - 40.0)
    np.testing.assert_allclose(distance, radius, atol=1e-12)


def test_a_path_with_nonsense_parameters_is_refused():
    with pytest.raises(RenderError, match="speed_mm_s"):
        SwipePath("straight", speed_mm_s=-1.0, duration_s=1.0, start_mm=(0.0, 0.0))
    with pytest.raises(RenderError, match="path must be one of"):
        SwipePath("spiral", speed_mm_s=1.0, duration_s=1.0, start_mm=(0.0, 0.0))


def test_the_default_swipe_over_a_texture_is_one_rule_for_the_api_and_the_commands():
    from ultraglide.render.paths import SwipePath

    straight = SwipePath.across(80.0, 50.0)
    assert straight.start_mm == (8.0, 25.0) and straight.kind == "straight" and straight.speed_mm_s == 100.0
    circle = SwipePath.across(80.0, 50.0, "circle", radius_mm=10.0)
    assert circle.start_mm == (30.0, 25.0)  # the circle's leftmost point, so it is centred on the texture
    zigzag = SwipePath.across(80.0, 50.0, "zigzag", width_of_pass_mm=40.0)
    assert zigzag.start_mm == (20.0, 10.0)
    assert SwipePath.across(80.0, 50.0, start_mm=(1.0, 2.0)).start_mm == (1.0, 2.0)
