"""The drive limiter's bookkeeping, pinned where scripts/mutation.sh found the quick tests silent: what
counts as limited (more than 0.1 % of the limit), how counts add up over blocks, and the words and
figures people read (status and summary), all against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.devices.output.limiter import DriveLimiter
from ultraglide.devices.profiles import PlateProfile

PLATE = PlateProfile("p", 25000.0, 200.0, 8.0, 2.0)  # full scale 8 µm, limit 2 µm, no overdrive


def _limiter() -> DriveLimiter:
    return DriveLimiter(PLATE, control_rate_hz=12000)


def test_a_sample_counts_as_limited_only_when_lowered_by_more_than_a_thousandth_of_the_limit():
    limiter = _limiter()
    out = limiter.process(np.array([2.0015, 2.0025, 1.9]))  # lowered by 0.075 %, 0.125 % and not at all
    np.testing.assert_array_equal(out, [2.0, 2.0, 1.9])
    assert limiter.limited_samples == 1
    assert limiter.worst_excess_um_pp == pytest.approx(0.0025, abs=1e-12)


def test_counts_and_the_worst_excess_add_up_over_blocks():
    limiter = _limiter()
    assert limiter.limited_fraction == 0.0  # nothing seen yet
    limiter.process(np.array([1.0, 5.0, 1.0, 1.0]))  # one limited, by 3 µm
    limiter.process(np.array([3.0, 3.0, 1.0, 0.5]))  # two more, by 1 µm: the worst stays 3
    assert (limiter.samples, limiter.limited_samples) == (8, 3)
    assert limiter.limited_fraction == pytest.approx(3 / 8)
    assert limiter.worst_excess_um_pp == pytest.approx(3.0)
    limiter.process(np.zeros(8))
    assert limiter.limited_fraction == pytest.approx(3 / 16)


def test_status_and_summary_say_what_the_limiter_did():
    limiter = _limiter()
    assert limiter.summary() == "the limiter never acted (limit 2 µm p-p)"
    limiter.process(np.array([1.0, 4.0, 8.0]))
    assert limiter.status() == {"limited_fraction": pytest.approx(0.666667, abs=1e-9),
                                "worst_excess_um_pp": pytest.approx(6.0), "limit_um_pp": 2.0,
                                "max_drive_um_pp": 2.0}
    assert limiter.summary() == ("the limiter lowered the drive 66.7 % of the time, by at most 6.00 µm p-p "
                                 "(limit 2 µm p-p, drive at most 2 µm p-p)")
