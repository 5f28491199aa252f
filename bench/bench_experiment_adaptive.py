"""Bias, spread and interval coverage of each adaptive design, over simulated sessions with known observers.

For each design (1-up-2-down, 1-up-3-down and weighted staircases, QUEST+; 2-interval forced choice, contrast
levels 0.005-0.6) and each simulated observer (Weibull threshold α and slope β, lapse 0.02), SESSIONS sessions of
TRIALS trials are run with the procedures and the observer ``ultraglide experiment run`` uses (the observer answers
from the nominal level, so the trials are not rendered here), and the threshold is estimated as a session's summary
does: the grid posterior's mean of log α with its 95 % credible interval (slope and lapse marginalised); QUEST+ also
by its own posterior. Printed: the median and mean relative error of the estimate (bias), the spread (the standard
deviation of log10 estimate, and the 5-95 % range of estimate / α), and the share of intervals holding α.

Run: .venv/bin/python bench/bench_experiment_adaptive.py [SESSIONS] [TRIALS]   (defaults 200 and 80)
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from ultraglide.experiment import psychometric as pf
from ultraglide.experiment.observer import SimObserver
from ultraglide.experiment.procedures import QuestParams, QuestPlus, Staircase, StaircaseParams, interval_positions

LOW, HIGH = 0.005, 0.6
OBSERVERS = ((0.08, 3.0), (0.2, 1.5))


def procedure(kind: str):
    if kind == "quest":
        return QuestPlus(QuestParams.log_grid(LOW, HIGH, guess=0.5))
    return Staircase(StaircaseParams(min(math.sqrt(LOW * HIGH) * 4, HIGH), kind, min_level=LOW, max_level=HIGH))


def session(kind: str, threshold: float, slope: float, seed: int, trials: int) -> tuple[dict, dict | None]:
    observer = SimObserver(threshold, slope, 0.02, seed=seed)
    chooser = procedure(kind)
    positions = interval_positions(seed, trials, 2)
    levels, outcomes = [], []
    for trial in range(1, trials + 1):
        level = chooser.next_level()
        response, _ = observer.respond(trial, level, 2, positions[trial - 1])
        outcome = int(response == positions[trial - 1])
        chooser.update(level, outcome)
        levels.append(level)
        outcomes.append(outcome)
    found = pf.posterior(levels, outcomes, "weibull", 0.5, (max(LOW, 1e-3 * HIGH), HIGH))
    own = chooser.estimate() if kind == "quest" else None
    return {"threshold": found.threshold, "ci": found.ci}, own


def describe(name: str, estimates: list[dict], truth: float) -> str:
    values = np.array([e["threshold"] for e in estimates])
    ratio = values / truth
    covered = np.mean([e["ci"][0] <= truth <= e["ci"][1] for e in estimates])
    low, high = np.percentile(ratio, [5, 95])
    return (f"| {name} | {100 * (np.median(ratio) - 1):+.1f} % | {100 * (np.mean(ratio) - 1):+.1f} % | "
            f"{np.std(np.log10(values)):.3f} | {low:.2f}-{high:.2f} | {100 * covered:.1f} % |")


def main() -> None:
    sessions = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    trials = int(sys.argv[2]) if len(sys.argv) > 2 else 80
    started = time.perf_counter()
    print(f"{sessions} sessions of {trials} trials each, 2AFC, lapse 0.02\n")
    print("| design, observer | bias (median) | bias (mean) | sd of log10 estimate | estimate / α, 5-95 % | "
          "95 % interval holds α |")
    print("|---|---|---|---|---|---|")
    for kind in ("1u2d", "1u3d", "weighted", "quest"):
        for threshold, slope in OBSERVERS:
            results = [session(kind, threshold, slope, seed, trials) for seed in range(sessions)]
            label = f"{kind}, α = {threshold:g}, β = {slope:g}"
            print(describe(label + " (grid posterior)", [r[0] for r in results], threshold), flush=True)
            if kind == "quest":
                print(describe(label + " (QUEST+ posterior)", [r[1] for r in results], threshold), flush=True)
    print(f"\n{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
