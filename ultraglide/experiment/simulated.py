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
    """|Δ delivered contrast| + |Δ delivered mean ratio| of two stimuli's check figures (0 if either is unknown).

    Parameters
    ----------
    first, second : StimulusFigures or None

    Returns
    -------
    float
        In friction ratio.

    Examples
    --------
    >>> from ultraglide.experiment.check import StimulusFigures
    >>> a = StimulusFigures("a", None, 0.3, 0.3, 0.28, 0.85, 0.86, 1.5, 0.4)
    >>> b = StimulusFigures("b", None, 0.3, 0.3, 0.20, 0.85, 0.90, 1.1, 0.3)
    >>> round(difference(a, b), 6), difference(a, None)            # |0.28 - 0.20| + |0.86 - 0.90|
    (0.12, 0.0)
    """
    if first is None or second is None:
        return 0.0
    return abs(first.delivered_contrast - second.delivered_contrast) + abs(first.delivered_mean - second.delivered_mean)


class SimulatedParticipant:
    """The responder (:mod:`ultraglide.experiment.responders`) a dry run of a design uses.

    Parameters
    ----------
    observer : str or SimObserver
        ``"sim:threshold=..."`` or an observer.
    rig : Rig
        The design's model, profile, speed and force.
    seed : int

    Raises
    ------
    ExperimentError
        An observer that is neither.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> rig = SimpleNamespace(model=None, profile=None, speed_mm_s=100.0, force_n=0.5)
    >>> SimulatedParticipant("sim:threshold=0.2,slope=2", rig, seed=9).observer.slope
    2.0
    >>> SimulatedParticipant(0.2, rig)
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: observer must be a sim:... spec or a SimObserver
    """

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
        """No pause for a simulated participant; the break is noted in ``breaks``.

        Parameters
        ----------
        trial : int
        message : str

        Returns
        -------
        bool
            Always True.

        Examples
        --------
        >>> from types import SimpleNamespace
        >>> participant = SimulatedParticipant("sim:threshold=0.2", SimpleNamespace(model=None, profile=None,
        ...                                    speed_mm_s=100.0, force_n=0.5))
        >>> participant.take_break(5, "Take a break."), participant.breaks
        (True, [5])
        """
        self.breaks.append(trial)
        return True

    def present(self, shown) -> Answer:
        """Answer a trial as the module docstring says for its task.

        Parameters
        ----------
        shown : Presentation

        Returns
        -------
        Answer

        Examples
        --------
        A rating of a stimulus far above threshold without noise: the scale's top (LOW + (HIGH - LOW) · F, F = 1):

        >>> from types import SimpleNamespace
        >>> from ultraglide.experiment.check import StimulusFigures
        >>> from ultraglide.experiment.design import Trial
        >>> from ultraglide.experiment.runner import Presentation
        >>> participant = SimulatedParticipant("sim:threshold=0.001,noise=0", SimpleNamespace(model=None, profile=None,
        ...                                    speed_mm_s=100.0, force_n=0.5))
        >>> strong = StimulusFigures("g", None, 0.3, 0.3, 0.3, 0.85, 0.85, 1.5, 0.4)
        >>> shown = Presentation(Trial(1, "rate", "rating", "g", False, None, None, ("g",)), None, "How rough?",
        ...                      ("1", "2", "3", "4", "5"), 1, None, None, None, (strong,), scale=(1, 5))
        >>> participant.present(shown).response
        5
        """
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
