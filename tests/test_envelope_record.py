"""The envelope record (``play --envelope-csv``, and ``export``'s): the ratio the renderer asked its model for,
beside the target.

With a model that has friction dynamics the renderer plans: it asks the model's inverse for a static ratio that is
not the texture's, and only that ratio's response through the dynamics is the friction the plan means felt (issue
43: a lagging finger's closed loop is judged against it). A judge rebuilding the plan afterwards cannot know the
floor and the block timing the live planner had, so the record says what was asked.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import run_cli
from ultraglide.render.engine.envelope_record import EnvelopeRecord
from ultraglide.render.physics.calibration import load_model


def columns(path) -> dict[str, np.ndarray]:
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}


def test_a_block_without_a_plan_records_its_target_as_the_ratio_asked(tmp_path):
    record = EnvelopeRecord(tmp_path / "envelope.csv")
    ratio, asked = np.array([0.5, 0.6, 0.7]), np.array([0.4, 0.6, 1.0])
    record.add(np.arange(3.0), 0, np.zeros(3), np.zeros(3), True, ratio, np.ones(3), np.ones(3))
    record.add(np.arange(3.0, 6.0), 3, np.zeros(3), np.zeros(3), True, ratio, np.ones(3), np.ones(3), asked)
    assert record.close() is None
    table = columns(tmp_path / "envelope.csv")
    assert table["index"].tolist() == [0, 1, 2, 3, 4, 5]
    assert table["planned_ratio"].tolist() == [0.5, 0.6, 0.7, 0.4, 0.6, 1.0]
    assert table["target_ratio"].tolist() == [0.5, 0.6, 0.7, 0.5, 0.6, 0.7]


@pytest.mark.slow
@pytest.mark.parametrize("model", ["dynamic", "stretched"])
def test_play_records_the_ratio_its_model_was_asked_for(tmp_path, model):
    """Open loop on the simulated plate at the default force (0.5 N) and limit (6 µm p-p): each value's amplitude is
    the static model's inverse of the ratio recorded as asked, read back here through the model; with the dynamic
    model that ratio is the planner's (it holds friction up before a rise and lets it fall early: not the texture's),
    with the static one it is the texture's."""
    envelope_csv = tmp_path / "envelope.csv"
    result = run_cli("play", "grating-1mm", "--device", "sim", "--duration-s", "1.5", "--model", model,
                     "--envelope-csv", envelope_csv)
    assert result.returncode == 0, result.stderr
    table = columns(envelope_csv)
    down = table["down"] > 0
    assert down.sum() > 6000  # half a second and more of the swipe
    asked, target = table["planned_ratio"][down], table["target_ratio"][down]
    amplitude = load_model(model).amplitude_um_pp(asked, 0.5, 6.0).amplitude_um_pp
    np.testing.assert_allclose(amplitude, table["target_um_pp"][down], atol=2e-3)
    if model == "dynamic":
        assert np.mean(np.abs(asked - target) > 0.05) > 0.3
    else:
        np.testing.assert_array_equal(asked, target)


@pytest.mark.parametrize("model", ["dynamic", "stretched"])
def test_export_records_the_ratio_its_model_was_asked_for(tmp_path, model):
    """``export --envelope-csv`` has the same column: each sample's target amplitude is the static model's inverse
    of the ratio recorded as asked (read back through the model here), the planner's with the dynamic model and
    the texture's with the static one."""
    envelope_csv = tmp_path / "envelope.csv"
    result = run_cli("export", "grating-1mm", "-o", tmp_path / "out.wav", "--duration-s", "1", "--model", model,
                     "--envelope-csv", envelope_csv)
    assert result.returncode == 0, result.stderr
    table = columns(envelope_csv)
    down = table["down"] > 0
    assert down.sum() > 6000
    asked, target = table["planned_ratio"][down], table["target_ratio"][down]
    amplitude = load_model(model).amplitude_um_pp(asked, 0.5, 6.0).amplitude_um_pp
    np.testing.assert_allclose(amplitude, table["target_um_pp"][down], rtol=2e-3, atol=2e-3)
    if model == "dynamic":
        assert np.mean(np.abs(asked - target) > 0.05) > 0.3
    else:
        np.testing.assert_array_equal(asked, target)
