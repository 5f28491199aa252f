"""The live trajectory: its speed cap and how near-simultaneous touch reports merge."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.render.trajectory import LiveTrajectory


@pytest.mark.parametrize("predictor", ["linear", "lsq"])
def test_a_glitch_faster_than_any_finger_is_capped_at_3_m_per_s(predictor):
    track = LiveTrajectory(predictor)
    track.push(0.0, 10.0, 20.0)
    track.push(0.010, 60.0, 20.0 + 50.0 * np.tan(np.radians(30)))  # 5.8 m/s at 30° below the x axis
    vx, vy = track.state(np.array([0.010, 0.011])).velocity_mm_s
    assert np.hypot(vx, vy) == pytest.approx(3000.0, rel=1e-9)
    assert np.degrees(np.arctan2(vy, vx)) == pytest.approx(30.0, abs=1e-9)  # capped, not turned


def test_reports_within_2_ms_are_one_instant_and_the_newest_stands():
    track = LiveTrajectory("linear")
    track.push(0.0, 0.0, 0.0)
    track.push(0.010, 1.0, 0.0)
    track.push(0.0115, 5.0, 0.0)  # 1.5 ms later: queued with the one before, read in one go
    vx, _ = track.state(np.array([0.0115, 0.012])).velocity_mm_s
    assert vx == pytest.approx(5.0 / 0.0115, rel=1e-9)  # through the first report and the newest
