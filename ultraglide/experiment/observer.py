"""A simulated observer: answers trials from a known psychometric function, for dry runs and tests.

``sim:threshold=0.1,slope=3,lapse=0.02[,false_alarm=0.05][,function=weibull]``: the observer detects
the target with P = F(level) (see :mod:`ultraglide.experiment.psychometric`); in forced choice it is correct
with P = 1/n + (1 − 1/n − lapse)·F and otherwise picks one of the other intervals at random; in yes/no
it says "yes" with P = false_alarm + (1 − false_alarm − lapse)·F. Reaction times are log-normal,
slower near threshold. Each trial draws from its own generator (seed, trial), so a resumed session
answers as an uninterrupted one would. For a design's ratings and magnitude estimates
(:mod:`ultraglide.experiment.simulated`): ``exponent`` (Stevens's, default 1) and ``noise`` (default 0.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ultraglide.experiment import psychometric as pf
from ultraglide.experiment.errors import ExperimentError

KEYS = {"threshold": float, "slope": float, "lapse": float, "false_alarm": float, "function": str, "exponent": float,
        "noise": float}


@dataclass(frozen=True)
class SimObserver:
    threshold: float
    slope: float = 3.0
    lapse: float = 0.02
    false_alarm: float = 0.0
    function: str = "weibull"
    exponent: float = 1.0  # magnitude estimation: Stevens's exponent on the delivered contrast
    noise: float = 0.2  # ratings (in scale points / their span) and magnitude estimates (log units): the sd
    seed: int = 0

    @staticmethod
    def parse(spec: str, seed: int = 0) -> SimObserver:
        """From ``sim:key=value,...``; ExperimentError (one line) for anything else."""
        kind, _, body = spec.partition(":")
        if kind != "sim" or not body:
            raise ExperimentError(f"--observer must be sim:threshold=T[,slope=S,lapse=L,false_alarm=F], got {spec!r}")
        values: dict = {}
        for item in body.split(","):
            key, _, text = item.partition("=")
            key = key.strip()
            if key not in KEYS or not text:
                raise ExperimentError(f"--observer: unknown or empty setting {item!r}; use {', '.join(KEYS)}")
            try:
                values[key] = KEYS[key](text)
            except ValueError:
                raise ExperimentError(f"--observer: {key} must be a number, got {text!r}") from None
        if "threshold" not in values:
            raise ExperimentError("--observer needs threshold=T (in the varied parameter's units)")
        observer = SimObserver(**values, seed=seed)
        if not observer.threshold > 0 or not observer.slope > 0:
            raise ExperimentError("--observer: threshold and slope must be positive")
        if not 0 <= observer.lapse < 0.5 or not 0 <= observer.false_alarm < 0.5:
            raise ExperimentError("--observer: lapse and false_alarm must lie in 0..0.5")
        if observer.function not in pf.FUNCTIONS:
            raise ExperimentError(f"--observer: function must be one of {', '.join(pf.FUNCTIONS)}")
        return observer

    def probability(self, level: float, intervals: int) -> float:
        guess = 1.0 / intervals if intervals > 1 else self.false_alarm
        return float(pf.probability(self.function, level, self.threshold, self.slope, guess, self.lapse))

    def respond(self, trial: int, level: float, intervals: int, target: int) -> tuple[int, float]:
        """(response, reaction time s): the chosen interval (0-based) in forced choice, 1/0 for yes/no."""
        rng = np.random.default_rng([self.seed, trial, 3])
        p = self.probability(level, intervals)
        hit = rng.random() < p
        if intervals > 1:
            response = target if hit else int(rng.choice([i for i in range(intervals) if i != target]))
        else:
            response = int(hit)
        detect = float(pf.core(self.function, level, self.threshold, self.slope))
        rt_s = float(np.exp(rng.normal(np.log(0.9 + 0.8 * (1.0 - abs(2 * detect - 1))), 0.25)))
        return response, rt_s
