"""A simulated participant for a design: a :class:`~ultraglide.experiment.observer.SimObserver` answering every task.

* Staircases, QUEST+ and constant stimuli: the trial is rendered offline through the real renderer (as the
  threshold sessions' dry runs are) and the observer answers from the nominal level, as there.
* Fixed A-vs-B forced choice: the observer detects the odd interval with F(d), d the difference between the two
  stimuli's delivered figures along the path (|Δ contrast| + |Δ mean ratio|, from the stimulus check).
* Same-different: "different" with P = false_alarm + (1 − false_alarm − lapse)·F(d), d as above (0 for a same pair).
* Rating on LOW..HIGH: LOW + (HIGH − LOW)·F(c) + noise·(HIGH − LOW)·N(0, 1), rounded and kept on the scale, c the
  stimulus's delivered contrast.
* Magnitude estimation: modulus·(c / c_modulus)^exponent·exp(noise·N(0, 1)).
* Adjustment: the reference's delivered contrast·exp(noise·N(0, 1)), kept within the condition's range.

Each trial draws from its own generator (seed, trial).
"""

from __future__ import annotations

import numpy as np

from ultraglide.experiment import psychometric as pf
from ultraglide.experiment.errors import ExperimentError
from ultraglide.experiment.observer import SimObserver
from ultraglide.experiment.responders import Answer


def difference(first, second) -> float:
    """|Δ delivered contrast| + |Δ delivered mean ratio| of two stimuli's check figures (0 if either is unknown)."""
    if first is None or second is None:
        return 0.0
    return abs(first.delivered_contrast - second.delivered_contrast) + abs(first.delivered_mean - second.delivered_mean)


class SimulatedParticipant:
    """The responder (:mod:`ultraglide.experiment.responders`) a dry run of a design uses."""

    def __init__(self, observer, rig, seed: int = 0):
        from ultraglide.experiment.dryrun import SimResponder

        if isinstance(observer, str):
            observer = SimObserver.parse(observer, seed)
        if not isinstance(observer, SimObserver):
            raise ExperimentError("observer must be a sim:... spec or a SimObserver")
        self.observer, self.rig = observer, rig
        self.renderer = SimResponder(observer, rig.model, rig.profile, rig.speed_mm_s, rig.force_n)
        self.breaks: list[int] = []

    def take_break(self, trial: int, message: str) -> bool:
        self.breaks.append(trial)
        return True

    def present(self, shown) -> Answer:
        trial, observer = shown.trial, self.observer
        if shown.stimulus_design is not None:
            return self.renderer.present(trial.number, shown.level, trial.target or 0, shown.stimulus_design)
        rng = np.random.default_rng([observer.seed, trial.number, 5])
        if trial.task == "afc":
            target = trial.target
            odd = shown.figures[target]
            other = next(f for z, f in enumerate(shown.figures) if z != target)
            response, rt_s = observer.respond(trial.number, difference(odd, other), shown.intervals, target)
            return Answer(response, rt_s)
        if trial.task == "same_different":
            response, rt_s = observer.respond(trial.number, difference(*shown.figures), 1, 0)
            return Answer(response, rt_s)
        _, rt_s = observer.respond(trial.number, observer.threshold, 2, 0)
        if trial.task == "rating":
            low, high = shown.scale
            contrast = shown.figures[0].delivered_contrast if shown.figures[0] else 0.0
            felt = float(pf.core(observer.function, contrast, observer.threshold, observer.slope))
            value = low + (high - low) * felt + observer.noise * (high - low) * rng.normal()
            return Answer(int(np.clip(round(value), low, high)), rt_s)
        if trial.task == "adjustment":  # a match to the reference's delivered contrast, off by log-normal noise
            reference = shown.figures[0].delivered_contrast if shown.figures[0] else 0.0
            low, high = shown.level_range
            match = reference * np.exp(observer.noise * rng.normal())
            return Answer(float(np.clip(match, low, high)), rt_s)
        modulus, stimulus = shown.figures
        reference = max(modulus.delivered_contrast, 1e-6) if modulus else 1.0
        contrast = stimulus.delivered_contrast if stimulus else 0.0
        estimate = shown.modulus * (contrast / reference) ** observer.exponent * np.exp(observer.noise * rng.normal())
        return Answer(float(round(estimate, 3)), rt_s)
