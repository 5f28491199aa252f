"""The rig's touch panel in the demo: SDL finger events (posted as the panel's driver posts them) are turned,
flipped and placed on the panel's active area, their pressure scaled by the panel's full scale, and the touch
that drives is the rig's choice; checked at the engine, which says what touch it rendered."""

from __future__ import annotations

import numpy as np
import pytest
from test_demo import engine, halves, post, run_until  # noqa: F401  (halves: a fixture)
from ultraglide.devices.rig import TouchPanel

AREA_MM = (10.0, 20.0, 200.0, 100.0)  # the panel's active area on the display: left, top, width, height


def start(halves, monkeypatch, panel):  # noqa: F811
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    demo = DemoApp([halves], windowed=True, screen_width_mm=338.7, touch_panel=panel)  # 1280 px: 0.2646 mm/px
    demo.wait_ready()
    demo.act("texture")
    return demo


def on_texture_mm(app, display_mm):
    """Where a point of the display (mm from its top-left corner) lies on the texture, mm: by hand, from the
    texture area's corner in pixels."""
    return display_mm[0] - app.area.left * app.mm_per_px, display_mm[1] - app.area.top * app.mm_per_px


def touch(pg, kind, u, v, finger_id=1, pressure=1.0):
    post(pg, kind, x=u, y=v, dx=0.0, dy=0.0, finger_id=finger_id, touch_id=1, pressure=pressure)


@pytest.fixture
def turned(halves, monkeypatch):  # noqa: F811
    app = start(halves, monkeypatch, TouchPanel(AREA_MM, rotation_deg=90, pressure_full_scale_n=4.0))
    yield app
    app.close()


def test_a_turned_panel_maps_onto_its_area_and_scales_its_pressure(turned):
    app, pg = turned, turned.pg
    # a quarter turn clockwise: the panel's (0.25, 0.5) is the area's (0.5, 0.25): 10 + 100, 20 + 25 mm
    touch(pg, pg.FINGERDOWN, 0.25, 0.5, pressure=0.5)
    assert run_until(app, lambda: engine(app).touches >= 1)
    x_mm, y_mm, force_n, down = engine(app).last_touch
    expected = on_texture_mm(app, (110.0, 45.0))
    assert expected[0] > 0 and expected[1] > 0  # on the texture, not the toolbar
    assert (x_mm, y_mm) == pytest.approx(expected, abs=0.3) and down
    assert force_n == pytest.approx(0.5 * 4.0)  # the panel's 4 N full scale, not the demo's 2 N
    touch(pg, pg.FINGERMOTION, 0.5, 0.75, pressure=0.25)  # -> the area's (0.25, 0.5): 60, 70 mm
    assert run_until(app, lambda: engine(app).touches >= 2)
    x_mm, y_mm, force_n, _ = engine(app).last_touch
    assert (x_mm, y_mm) == pytest.approx(on_texture_mm(app, (60.0, 70.0)), abs=0.3)
    assert force_n == pytest.approx(1.0)


@pytest.mark.parametrize("drives", ["first", "latest", "none"])
def test_which_touch_drives_when_two_are_down(halves, monkeypatch, drives):  # noqa: F811
    app = start(halves, monkeypatch, TouchPanel(AREA_MM, drives=drives))
    pg = app.pg
    try:
        touch(pg, pg.FINGERDOWN, 0.2, 0.5, finger_id=1)  # at 50, 70 mm
        assert run_until(app, lambda: engine(app).touches >= 1)
        first = on_texture_mm(app, (50.0, 70.0))
        assert engine(app).last_touch[:2] == pytest.approx(first, abs=0.3)
        touch(pg, pg.FINGERDOWN, 0.6, 0.5, finger_id=2)  # at 130, 70 mm
        touch(pg, pg.FINGERMOTION, 0.65, 0.5, finger_id=2)  # at 140, 70 mm
        touch(pg, pg.FINGERMOTION, 0.25, 0.5, finger_id=1)  # at 60, 70 mm
        second = on_texture_mm(app, (140.0, 70.0))
        moved_first = on_texture_mm(app, (60.0, 70.0))
        if drives == "first":
            assert run_until(app, lambda: engine(app).last_touch[:2] == pytest.approx(moved_first, abs=0.3))
            assert app.driving == 1
        elif drives == "latest":
            assert run_until(app, lambda: engine(app).last_touch[:2] == pytest.approx(second, abs=0.3))
            assert app.driving == 2 and engine(app).last_touch[3]
        else:  # none: the plate rests while two are down
            assert run_until(app, lambda: not engine(app).last_touch[3])
            assert app.driving is None
        assert set(app.fingers) == {1, 2}
        touch(pg, pg.FINGERUP, 0.65, 0.5, finger_id=2)
        if drives == "none":  # one left: it drives again
            assert run_until(app, lambda: engine(app).last_touch[3]
                             and engine(app).last_touch[:2] == pytest.approx(moved_first, abs=0.3))
            assert app.driving == 1
        elif drives == "latest":  # the one still down takes over
            assert run_until(app, lambda: engine(app).last_touch[3] and app.driving == 1)
        assert not np.isnan(engine(app).last_touch[0])
    finally:
        app.close()
