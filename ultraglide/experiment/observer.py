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
    """A simulated observer answering from a known psychometric function (see the module docstring).

    Parameters
    ----------
    threshold : float
        In the varied level's unit (friction contrast, mm, µm p-p).
    slope : float
        The psychometric function's slope (:mod:`ultraglide.experiment.psychometric`).
    lapse, false_alarm : float
        The lapse rate and the yes/no false-alarm rate, 0..0.5.
    function : {"weibull", "logistic"}
    exponent : float
        Stevens's exponent on the delivered contrast (magnitude estimation).
    noise : float
        The sd of ratings (in their scale's span) and of magnitude estimates (log units).
    seed : int
        With the trial's number, seeds each trial's generator.

    Examples
    --------
    >>> import math
    >>> observer = SimObserver(threshold=0.1, slope=3.0, lapse=0.02)
    >>> round(observer.probability(0.1, intervals=2), 6), round(0.5 + 0.48 * (1 - math.exp(-1)), 6)
    (0.803418, 0.803418)
    """
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
        """From ``sim:key=value,...``; ExperimentError (one line) for anything else.

        Parameters
        ----------
        spec : str
            ``sim:threshold=T[,slope=S,lapse=L,false_alarm=F,function=weibull|logistic,exponent=E,noise=N]``.
        seed : int

        Returns
        -------
        SimObserver

        Raises
        ------
        ExperimentError
            Not a ``sim:`` spec, an unknown or empty setting, a value that is not a number, no threshold, or a value out
            of range.

        Examples
        --------
        >>> SimObserver.parse("sim:threshold=0.1,lapse=0.01", seed=3)   # NORMALIZE_WHITESPACE
        SimObserver(threshold=0.1, slope=3.0, lapse=0.01, false_alarm=0.0, function='weibull', exponent=1.0,
                    noise=0.2, seed=3)
        >>> SimObserver.parse("sim:threshold=0.1,lapse=0.6")
        Traceback (most recent call last):
        ...
        ultraglide.experiment.errors.ExperimentError: --observer: lapse and false_alarm must lie in 0..0.5
        """
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
        """P(correct) in ``intervals``-interval forced choice, P(yes) in yes/no (``intervals`` 1), at ``level``.

        Parameters
        ----------
        level : float
            In the threshold's unit.
        intervals : int
            The trial's intervals; the guess rate is 1/intervals, or the false-alarm rate for 1.

        Returns
        -------
        float

        Examples
        --------
        >>> import math
        >>> observer = SimObserver(threshold=0.1, slope=3.0, lapse=0.02, false_alarm=0.05)
        >>> round(observer.probability(0.1, 1), 6), round(0.05 + 0.93 * (1 - math.exp(-1)), 6)     # yes/no
        (0.637872, 0.637872)
        """
        guess = 1.0 / intervals if intervals > 1 else self.false_alarm
        return float(pf.probability(self.function, level, self.threshold, self.slope, guess, self.lapse))

    def respond(self, trial: int, level: float, intervals: int, target: int) -> tuple[int, float]:
        """(response, reaction time s): the chosen interval (0-based) in forced choice, 1/0 for yes/no.

        Parameters
        ----------
        trial : int
            The trial's number (with the seed, it seeds the trial's generator).
        level : float
            The level presented, in the threshold's unit.
        intervals : int
            The trial's intervals (1: yes/no).
        target : int
            The interval holding the stimulus, 0-based.

        Returns
        -------
        (int, float)
            The response and the reaction time, s.

        Examples
        --------
        Without lapses, a level far above threshold is always found (P = 1 - exp(-1000 ** 3) = 1):

        >>> observer = SimObserver(threshold=0.1, slope=3.0, lapse=0.0)
        >>> [observer.respond(trial, 100.0, intervals=3, target=2)[0] for trial in range(1, 6)]
        [2, 2, 2, 2, 2]
        >>> observer.respond(7, 0.2, 2, 0) == observer.respond(7, 0.2, 2, 0)       # each trial its own generator
        True
        """
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
