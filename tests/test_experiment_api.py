"""The Python API of experiments: sessions in code, analyses of the trials table.

Its docstring examples run in tests/test_doctests.py, with every documented module's.
"""

import numpy as np
import pandas as pd
import pytest

from ultraglide.experiment import (
    Block,
    Condition,
    Design,
    Stimulus,
    fit_psychometric,
    mean_response,
    proportions,
    read_trials,
    run,
    threshold_posterior,
)
from ultraglide.experiment import psychometric as pf


def simulated_constant_rows(threshold=0.08, slope=3.0, guess=0.5, trials=60, seed=0):
    """Trials drawn by hand from P = γ + (1 − γ)·(1 − exp(−(x/α)^β)), independent of the package's observer."""
    rng = np.random.default_rng(seed)
    rows = []
    for level in (0.02, 0.04, 0.08, 0.16, 0.32):
        p = guess + (1 - guess) * (1 - np.exp(-((level / threshold) ** slope)))
        rows += [{"condition": "c", "level": level, "correct": int(rng.random() < p), "practice": 0}
                 for _ in range(trials)]
    return rows


def test_fits_recover_a_known_threshold_from_a_list_or_a_dataframe():
    # 20 data sets of 300 trials: the intervals hold the true threshold in most (a 95 % interval misses 1 in 20; the
    # ML fit's bootstrap a little more often, when the slope runs to its bound), the estimates centre on it
    fits, posteriors = [], []
    for seed in range(20):
        rows = simulated_constant_rows(seed=seed)
        fits += fit_psychometric(rows, bootstrap=100, seed=seed)
        posteriors += threshold_posterior(rows, level_range=(0.005, 0.6))
    assert np.median([fit["threshold"] for fit in fits]) == pytest.approx(0.08, rel=0.05)
    assert sum(fit["ci"][0] < 0.08 < fit["ci"][1] for fit in fits) >= 16
    assert sum(found["ci"][0] < 0.08 < found["ci"][1] for found in posteriors) >= 17
    rows = simulated_constant_rows()
    fits = fit_psychometric(rows, bootstrap=200)
    assert fit_psychometric(pd.DataFrame(rows), bootstrap=200) == fits
    # practice trials are left out unless asked for
    practice = [{**row, "practice": 1, "correct": 0} for row in rows[:50]]
    assert fit_psychometric(practice + rows, bootstrap=0)[0]["trials"] == len(rows)
    counted = proportions(rows, by="level")
    assert [entry["trials"] for entry in counted] == [60] * 5
    assert all(entry["ci"][0] <= entry["p"] <= entry["ci"][1] for entry in counted)


def test_a_group_too_small_to_fit_says_why_once():
    found = fit_psychometric([{"condition": "c", "level": 0.1, "correct": 1}] * 3)
    assert found == [{"condition": "c", "trials": 3, "threshold": None, "ci": None,
                      "note": "3 trials with a level and an outcome, and a fit needs at least 5"}]


def test_a_rating_and_magnitude_study_in_code_follows_the_delivered_contrast(tmp_path):
    stimuli = {name: Stimulus(name, "grating-2mm", contrast=c) for name, c in (("low", 0.1), ("mid", 0.2),
                                                                               ("high", 0.4))}
    conditions = {name: Condition(name, name, factors={"contrast": s.contrast}) for name, s in stimuli.items()}
    design = Design("ratings", stimuli, conditions,
                    (Block("rate", "rating", tuple(conditions), repeats=6, scale=(1, 7)),
                     Block("estimate", "magnitude", tuple(conditions), repeats=4, modulus=10.0,
                           modulus_stimulus="mid")), seed=3)
    session = run(design, "P09", out=tmp_path / "s", observer="sim:threshold=0.15,slope=2,noise=0.0001,exponent=0.7")
    table = session.table()
    assert isinstance(table, pd.DataFrame) and len(table) == 30
    assert table.equals(pd.DataFrame(read_trials(tmp_path / "s")).astype(table.dtypes.to_dict())) or len(
        read_trials(tmp_path / "s")) == 30
    figures = {name: f.delivered_contrast for name, f in session.check.figures.items()}
    # the observer's ratings, by hand: 1 + 6·F(c), F the Weibull at α = 0.15, β = 2 (noise 1e-4: none)
    ratings = table[table.task == "rating"].groupby("condition")["response"].mean()
    for name in conditions:
        felt = pf.core("weibull", figures[name], 0.15, 2.0)
        assert ratings[name] == round(1 + 6 * felt)
    # magnitude estimates, by hand: 10·(c / c_mid)^0.7
    estimates = mean_response(table[table.task == "magnitude"], by="condition", log=True)
    for entry in estimates:
        expected = 10 * (figures[entry["condition"]] / figures["mid"]) ** 0.7
        assert entry["mean"] == pytest.approx(expected, rel=2e-3)
    assert session.summary["blocks"][1]["conditions"][1]["mean"] == pytest.approx(10.0, rel=2e-3)


def test_interleaved_staircases_in_code_estimate_each_conditions_threshold():
    design = Design("two", {"a": Stimulus("a", "grating-1mm"), "b": Stimulus("b", "grating-4mm")},
                    {"a": Condition("a", "a", factors={"period_mm": 1}), "b": Condition("b", "b",
                                                                                       factors={"period_mm": 4})},
                    (Block("s", "staircase", ("a", "b"), trials=50, rule="1u2d"),), seed=1)
    session = run(design, observer="sim:threshold=0.08,slope=3,lapse=0.02")
    for item in session.summary["blocks"][0]["conditions"]:
        assert item["ci"][0] < 0.08 < item["ci"][1]
        own = [r for r in session.trials if r["condition"] == item["condition"]]
        assert len(own) == 50 and item["reversals"] == sum(r["reversal"] for r in own)


def test_an_adjustment_block_matches_the_references_delivered_contrast():
    stimuli = {"ref": Stimulus("ref", "grating-2mm", contrast=0.2), "adj": Stimulus("adj", "grating-1mm")}
    design = Design("match", stimuli,
                    {"m": Condition("m", "adj", "ref", level_range=(0.02, 0.6))},
                    (Block("a", "adjustment", ("m",), repeats=8),), seed=4)
    session = run(design, observer="sim:threshold=0.1,noise=0.0001")
    reference = session.check.figures["ref"].delivered_contrast
    assert reference == pytest.approx(0.2, rel=0.05)
    starts = [row["level"] for row in session.trials]
    assert len(set(starts)) == 8 and all(0.02 <= level <= 0.6 for level in starts)
    assert all(row["response"] == pytest.approx(reference, rel=1e-3) for row in session.trials)
    assert session.summary["blocks"][0]["conditions"][0]["mean"] == pytest.approx(reference, rel=1e-3)
