"""EngineStatus.summary(): the engine's figures as strict JSON, whatever the engine has or has not said yet."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from ultraglide.render.engine import Engine, EngineConfig
from ultraglide.render.engine.shm import SharedBlock
from ultraglide.render.engine.status import status_from_shared


@pytest.fixture
def not_yet_reported():
    """The status of a segment no engine has written: its default force is not known (NaN in the status)."""
    block = SharedBlock.create()
    try:
        header, times, history, _ = block.read_fast()
        yield status_from_shared(header, times, history, {}, 0, "null", 10.0)
    finally:
        block.close()


def test_a_force_not_yet_reported_is_null_in_strict_json(not_yet_reported):
    assert math.isnan(not_yet_reported.force_n)  # the status itself keeps its float
    summary = not_yet_reported.summary()
    assert summary["force_n"] is None
    assert json.loads(json.dumps(summary, allow_nan=False)) == summary


def test_whatever_a_device_or_touch_reports_is_strict_json(not_yet_reported):
    status = replace(not_yet_reported, force_n=0.5, last_touch=(12.5, 3.0, math.nan, True),
                     block_p50_us=math.inf,
                     device_status={"measured_ratio": np.float32("nan"), "count": np.int64(3), "fine": np.float64(0.25),
                                    "spread": (1.0, -math.inf), "levels": np.array([0.5, np.nan]),
                                    "nested": {"bias": math.nan, 7: "seven"}, "ok": np.bool_(True)})
    summary = status.summary()
    assert json.loads(json.dumps(summary, allow_nan=False)) == summary
    assert summary["force_n"] == 0.5 and summary["last_touch"] == [12.5, 3.0, None, True]
    assert summary["block_p50_us"] is None
    assert summary["device_status"] == {"measured_ratio": None, "count": 3, "fine": 0.25, "spread": [1.0, None],
                                        "levels": [0.5, None], "nested": {"bias": None, "7": "seven"}, "ok": True}
    assert type(summary["device_status"]["count"]) is int and type(summary["device_status"]["ok"]) is bool


@pytest.mark.slow
def test_a_running_engines_summary_is_strict_json():
    with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        engine.wait_ready(60.0)
        running = engine.status().summary()
        final = engine.stop().summary()
    for summary in (running, final):
        assert json.loads(json.dumps(summary, allow_nan=False)) == summary
    assert running["state"] == "running" and running["device"] == "null"
    assert final["force_n"] == pytest.approx(EngineConfig().default_force_n)
