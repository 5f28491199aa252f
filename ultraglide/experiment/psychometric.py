"""Psychometric functions and their maximum-likelihood fit, with a parametric bootstrap.

P(response) = guess + (1 - guess - lapse) · F(level; threshold, slope), where F is

* ``weibull``: F = 1 - exp(-(level / threshold)^slope) (levels ≥ 0; F(threshold) = 1 - 1/e ≈ 0.632);
* ``logistic``: F = 1 / (1 + exp(-slope · (level - threshold))) (F(threshold) = 0.5).

In n-interval forced choice the guess rate is 1/n (fixed); in yes/no it is the false-alarm rate
(fitted within bounds). The threshold is in the units of the level (friction contrast, mm, µm p-p).
Pure functions: no state, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

FUNCTIONS = ("weibull", "logistic")
MAX_LAPSE = 0.06  # Wichmann & Hill (2001): a lapse rate fitted within [0, 0.06]
MAX_FALSE_ALARM = 0.5


def core(function: str, level, threshold, slope) -> np.ndarray:
    """F(level) in 0..1, the detection part of a psychometric function, broadcasting over arrays of levels and of
    parameters.

    Parameters
    ----------
    function : {"weibull", "logistic"}
        The function's form (see the module docstring).
    level : float or array_like
        The level(s), in the varied parameter's unit (friction contrast, mm, µm p-p).
    threshold : float or array_like
        Where F reaches 1 - 1/e (Weibull) or 0.5 (logistic), in the level's unit.
    slope : float or array_like
        The Weibull's exponent (dimensionless), or the logistic's rate (per unit of the level).

    Returns
    -------
    numpy.ndarray
        F at each level, 0..1.

    Raises
    ------
    ValueError
        An unknown ``function``.

    Examples
    --------
    >>> import math
    >>> values = core("weibull", [0.1, 0.2], threshold=0.1, slope=2.0)   # 1 - exp(-(x/t)^s): 1 - e^-1, 1 - e^-4
    >>> [round(float(v), 4) for v in values], round(1 - math.exp(-1), 4), round(1 - math.exp(-4), 4)
    ([0.6321, 0.9817], 0.6321, 0.9817)
    >>> float(core("logistic", 0.1, threshold=0.1, slope=3.0))            # the logistic's threshold: half way
    0.5
    """
    level = np.asarray(level, dtype=float)
    if function == "weibull":
        ratio = np.maximum(level, 0.0) / threshold
        return -np.expm1(-(ratio ** slope))
    if function == "logistic":
        return 0.5 * (1.0 + np.tanh(0.5 * slope * (level - threshold)))
    raise ValueError(f"psychometric function must be one of {', '.join(FUNCTIONS)}, got {function!r}")


def probability(function: str, level, threshold, slope, guess, lapse) -> np.ndarray:
    """P(correct) in forced choice, P(yes) in yes/no: guess + (1 - guess - lapse) · F(level).

    Parameters
    ----------
    function : {"weibull", "logistic"}
    level, threshold, slope : float or array_like
        As for :func:`core` (level and threshold in the varied parameter's unit).
    guess : float or array_like
        The guess rate: 1/n in n-interval forced choice, the false-alarm rate in yes/no (0..1).
    lapse : float or array_like
        The lapse rate (0..1): the answers missed however strong the stimulus.

    Returns
    -------
    numpy.ndarray
        The probability at each level, guess..1 - lapse.

    Examples
    --------
    >>> import math
    >>> p = probability("weibull", 0.1, threshold=0.1, slope=3.0, guess=0.5, lapse=0.02)
    >>> round(float(p), 6), round(0.5 + 0.48 * (1 - math.exp(-1)), 6)    # at the threshold F = 1 - 1/e
    (0.803418, 0.803418)
    """
    return guess + (1.0 - guess - lapse) * core(function, level, threshold, slope)


def level_at(function: str, p_core: float, threshold: float, slope: float) -> float:
    """The level where F reaches ``p_core`` (the inverse of :func:`core`).

    Parameters
    ----------
    function : {"weibull", "logistic"}
    p_core : float
        The value of F wanted, strictly between 0 and 1.
    threshold : float
        In the level's unit.
    slope : float
        As for :func:`core`.

    Returns
    -------
    float
        The level, in the threshold's unit.

    Examples
    --------
    >>> import math
    >>> round(level_at("weibull", 0.5, threshold=0.1, slope=2.0), 6), round(0.1 * math.sqrt(math.log(2)), 6)
    (0.083255, 0.083255)
    >>> level_at("logistic", 0.5, threshold=0.1, slope=3.0)               # the logistic's midpoint
    0.1
    """
    if function == "weibull":
        return float(threshold * (-np.log1p(-p_core)) ** (1.0 / slope))
    return float(threshold + np.log(p_core / (1.0 - p_core)) / slope)


@dataclass(frozen=True)
class Fit:
    """A fitted psychometric function. ``ci``: the threshold's 95 % interval (bootstrap).

    Parameters
    ----------
    function : {"weibull", "logistic"}
    threshold : float
        In the level's unit (friction contrast, mm, µm p-p).
    slope : float
        The Weibull's exponent, or the logistic's rate per unit of the level.
    guess, lapse : float
        The guess and lapse rates, 0..1.
    log_likelihood : float
        The fit's log-likelihood (natural log) of the trials.
    ci : (float, float), optional
        The threshold's 95 % percentile interval from :func:`bootstrap`, in the level's unit.
    bootstrap_samples : int
        How many simulated data sets made ``ci``.

    Examples
    --------
    >>> fitted = Fit("weibull", threshold=0.1, slope=3.0, guess=0.5, lapse=0.0, log_likelihood=-20.0)
    >>> round(float(fitted.probability(0.0)), 3), round(float(fitted.probability(10.0)), 3)    # guess .. 1 - lapse
    (0.5, 1.0)
    """

    function: str
    threshold: float
    slope: float
    guess: float
    lapse: float
    log_likelihood: float
    ci: tuple[float, float] | None = None
    bootstrap_samples: int = 0

    def probability(self, level) -> np.ndarray:
        """P(correct) or P(yes) of this fit at ``level`` (:func:`probability` with its parameters).

        Parameters
        ----------
        level : float or array_like
            In the threshold's unit.

        Returns
        -------
        numpy.ndarray
            guess..1 - lapse.

        Examples
        --------
        >>> import math
        >>> fitted = Fit("weibull", threshold=0.1, slope=3.0, guess=0.5, lapse=0.02, log_likelihood=0.0)
        >>> round(float(fitted.probability(0.1)), 6), round(0.5 + 0.48 * (1 - math.exp(-1)), 6)
        (0.803418, 0.803418)
        """
        return probability(self.function, level, self.threshold, self.slope, self.guess, self.lapse)

    def as_dict(self) -> dict:
        """The fit as plain data (JSON-ready: the interval a list, or None).

        Returns
        -------
        dict
            ``function``, ``threshold``, ``slope``, ``guess``, ``lapse``, ``log_likelihood``, ``ci``,
            ``bootstrap_samples``.

        Examples
        --------
        >>> Fit("logistic", 0.2, 30.0, 0.5, 0.01, -12.5, (0.15, 0.25), 100).as_dict()["ci"]
        [0.15, 0.25]
        """
        return {"function": self.function, "threshold": self.threshold, "slope": self.slope,
                "guess": self.guess, "lapse": self.lapse, "log_likelihood": self.log_likelihood,
                "ci": list(self.ci) if self.ci else None, "bootstrap_samples": self.bootstrap_samples}


def aggregate(levels, outcomes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct levels, trials at each and positive outcomes at each.

    Parameters
    ----------
    levels : array_like
        One level per trial.
    outcomes : array_like
        One outcome per trial (1 = correct / yes, 0 otherwise).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The distinct levels in increasing order, the trials at each and the sum of outcomes at each.

    Examples
    --------
    >>> levels, n, k = aggregate([0.1, 0.2, 0.1, 0.1], [1, 0, 0, 1])
    >>> levels.tolist(), n.tolist(), k.tolist()
    ([0.1, 0.2], [3.0, 1.0], [2.0, 0.0])
    """
    levels = np.asarray(levels, dtype=float)
    outcomes = np.asarray(outcomes, dtype=float)
    distinct, index = np.unique(levels, return_inverse=True)
    n = np.bincount(index, minlength=len(distinct)).astype(float)
    k = np.bincount(index, weights=outcomes, minlength=len(distinct))
    return distinct, n, k


def _negative_log_likelihood(params, function, x, n, k, guess_fixed):
    threshold, log_slope, guess, lapse = params
    guess = guess_fixed if guess_fixed is not None else guess
    p = probability(function, x, threshold, np.exp(log_slope), guess, lapse)
    p = np.clip(p, 1e-9, 1 - 1e-9)
    return -float(np.sum(k * np.log(p) + (n - k) * np.log1p(-p)))


def _bounds(function: str, low: float, high: float):
    span = max(high - low, 1e-6)
    if function == "weibull":
        return (max(1e-6, 1e-3 * high), 3.0 * high + 1e-6), (np.log(0.3), np.log(30.0))
    return (low - span, high + span), (np.log(0.1 / span), np.log(200.0 / span))


def _grid(function: str, bounds_t, bounds_s, guess: float | None, max_lapse: float):
    """Candidate parameter sets (threshold, log slope, guess, lapse), one per column."""
    if function == "weibull":
        thresholds = np.geomspace(*bounds_t, 160)
    else:
        thresholds = np.linspace(*bounds_t, 160)
    log_slopes = np.linspace(*bounds_s, 32)
    guesses = np.array([guess]) if guess is not None else np.linspace(0.0, MAX_FALSE_ALARM, 11)
    lapses = np.linspace(0.0, max_lapse, 4)
    return np.array(np.meshgrid(thresholds, log_slopes, guesses, lapses, indexing="ij")).reshape(4, -1)


def _grid_log_probabilities(function, grid, x) -> tuple[np.ndarray, np.ndarray]:
    """log P and log (1 - P) at each level (rows) for each parameter set (columns of ``grid``)."""
    p = probability(function, x[:, None], grid[0][None, :], np.exp(grid[1])[None, :], grid[2][None, :],
                    grid[3][None, :])
    return np.log(np.clip(p, 1e-9, 1)), np.log(np.clip(1 - p, 1e-9, 1))


def _grid_log_likelihood(function, grid, x, n, k, log_probabilities=None) -> np.ndarray:
    """Log-likelihood of each parameter set (columns of ``grid``) for each data set (rows of ``k``);
    ``log_probabilities``: :func:`_grid_log_probabilities` of the same grid and levels, if computed."""
    log_p, log_q = log_probabilities or _grid_log_probabilities(function, grid, x)
    k = np.atleast_2d(k)
    return k @ log_p + (n[None, :] - k) @ log_q


def fit(levels, outcomes, function: str = "weibull", guess: float | None = 0.5,
        level_range: tuple[float, float] | None = None, max_lapse: float = MAX_LAPSE) -> Fit:
    """Maximum-likelihood fit to per-trial ``outcomes`` (1 = correct / yes) at ``levels``.

    ``guess``: fixed (forced choice: 1/n) or None to fit it (yes/no: the false-alarm rate in
    0..0.5). The threshold is searched within ``level_range`` (default: the levels' span), widened;
    the slope on a log scale. A grid search finds the start, L-BFGS-B refines it.

    Parameters
    ----------
    levels : array_like
        One level per trial, in the varied parameter's unit.
    outcomes : array_like
        One outcome per trial, 1 or 0.
    function : {"weibull", "logistic"}
    guess : float or None
        The guess rate held fixed, or None to fit it.
    level_range : (float, float), optional
        Where to look for the threshold, in the level's unit.
    max_lapse : float
        The largest lapse rate fitted.

    Returns
    -------
    Fit
        Without an interval (:func:`bootstrap` adds one).

    Raises
    ------
    ValueError
        An unknown ``function``, or no trials.

    Examples
    --------
    Trials made exactly as a 2AFC observer of threshold 0.1 and slope 3 answers on average (40 at each level, the
    correct counts rounded from :func:`probability`: 20, 22, 33, 40) give the threshold back:

    >>> import numpy as np
    >>> levels = np.repeat([0.02, 0.05, 0.1, 0.2], 40)
    >>> outcomes = np.concatenate([np.r_[np.ones(k), np.zeros(40 - k)] for k in (20, 22, 33, 40)])
    >>> fitted = fit(levels, outcomes, "weibull", guess=0.5)
    >>> round(fitted.threshold, 2), fitted.guess
    (0.1, 0.5)
    """
    if function not in FUNCTIONS:
        raise ValueError(f"psychometric function must be one of {', '.join(FUNCTIONS)}, got {function!r}")
    x, n, k = aggregate(levels, outcomes)
    if len(x) == 0:
        raise ValueError("no trials to fit")
    low, high = level_range if level_range else (float(x.min()), float(x.max()))
    bounds_t, bounds_s = _bounds(function, low, high)
    grid = _grid(function, bounds_t, bounds_s, guess, max_lapse)
    start = grid[:, int(np.argmax(_grid_log_likelihood(function, grid, x, n, k)[0]))]
    guess_bounds = (0.0, MAX_FALSE_ALARM) if guess is None else (guess, guess)
    result = optimize.minimize(_negative_log_likelihood, start, args=(function, x, n, k, guess), method="L-BFGS-B",
                               bounds=[bounds_t, bounds_s, guess_bounds, (0.0, max_lapse)])
    best = result.x if result.fun <= _negative_log_likelihood(start, function, x, n, k, guess) else start
    threshold, log_slope, fitted_guess, lapse = best
    return Fit(function, float(threshold), float(np.exp(log_slope)),
               float(guess if guess is not None else fitted_guess), float(lapse),
               -_negative_log_likelihood(best, function, x, n, k, guess))


def bootstrap(fitted: Fit, levels, samples: int = 200, seed: int = 0, fit_guess: bool = False,
              level_range: tuple[float, float] | None = None, max_lapse: float = MAX_LAPSE) -> Fit:
    """The fit with a 95 % percentile interval on its threshold: ``samples`` data sets simulated from
    the fit at the same levels (a parametric bootstrap, Wichmann & Hill 2001b), each refitted by
    maximum likelihood on a fine grid (160 thresholds × 32 slopes × 4 lapse rates, all data sets at once).

    Parameters
    ----------
    fitted : Fit
        The fit to simulate from.
    levels : array_like
        The trials' levels (one per trial), in the threshold's unit.
    samples : int
        Simulated data sets.
    seed : int
        The generator's seed: the same seed gives the same interval.
    fit_guess : bool
        Refit the guess rate too (yes/no).
    level_range : (float, float), optional
        Where to look for the threshold.
    max_lapse : float
        The largest lapse rate fitted.

    Returns
    -------
    Fit
        ``fitted`` with ``ci`` and ``bootstrap_samples`` set.

    Examples
    --------
    >>> import numpy as np
    >>> levels = np.repeat([0.02, 0.05, 0.1, 0.2], 40)
    >>> known = Fit("weibull", threshold=0.1, slope=3.0, guess=0.5, lapse=0.0, log_likelihood=0.0)
    >>> with_ci = bootstrap(known, levels, samples=100, seed=1)
    >>> low, high = with_ci.ci
    >>> low < 0.1 < high, with_ci.bootstrap_samples, with_ci.threshold
    (True, 100, 0.1)
    """
    levels = np.asarray(levels, dtype=float)
    x, n, _ = aggregate(levels, np.zeros(len(levels)))
    rng = np.random.default_rng(seed)
    k = rng.binomial(n.astype(int)[None, :], fitted.probability(x)[None, :], size=(samples, len(x))).astype(float)
    low, high = level_range if level_range else (float(x.min()), float(x.max()))
    grid = _grid(fitted.function, *_bounds(fitted.function, low, high), None if fit_guess else fitted.guess,
                 max_lapse)
    thresholds = np.empty(samples)
    log_probabilities = _grid_log_probabilities(fitted.function, grid, x)  # the same for every data set
    for chunk in range(0, samples, 50):  # bounded memory: 50 data sets at a time
        best = np.argmax(_grid_log_likelihood(fitted.function, grid, x, n, k[chunk:chunk + 50], log_probabilities),
                         axis=1)
        thresholds[chunk:chunk + 50] = grid[0][best]
    low_ci, high_ci = np.percentile(thresholds, [2.5, 97.5])
    return Fit(fitted.function, fitted.threshold, fitted.slope, fitted.guess, fitted.lapse, fitted.log_likelihood,
               (float(low_ci), float(high_ci)), samples)


@dataclass(frozen=True)
class Posterior:
    """The threshold's posterior on a grid: its mean on the log scale and 95 % credible interval.

    Parameters
    ----------
    threshold : float
        The posterior mean (on the log scale for the Weibull), in the level's unit.
    ci : (float, float)
        The 95 % credible interval, in the level's unit.
    slope, lapse, guess : float
        Their posterior means.

    Examples
    --------
    >>> found = Posterior(threshold=0.1, ci=(0.08, 0.12), slope=3.0, lapse=0.02, guess=0.5)
    >>> found.ci[0] < found.threshold < found.ci[1]
    True
    """

    threshold: float
    ci: tuple[float, float]
    slope: float
    lapse: float
    guess: float


def posterior(levels, outcomes, function: str = "weibull", guess: float | None = 0.5,
              level_range: tuple[float, float] = (1e-3, 1.0), max_lapse: float = MAX_LAPSE) -> Posterior:
    """Bayes on a grid: 200 thresholds over ``level_range`` (log-spaced for the Weibull), 24 slopes
    (log-spaced), lapse rates 0..``max_lapse``, and the false-alarm rate 0..0.5 when ``guess`` is None;
    uniform priors on log threshold and log slope. Slope, lapse and guess are marginalised out, so the
    interval carries their uncertainty (the likelihood is that of the trials as run, whatever chose
    their levels, so it holds for staircase data too).

    Parameters
    ----------
    levels, outcomes : array_like
        One level (in the varied parameter's unit) and one outcome (1 or 0) per trial.
    function : {"weibull", "logistic"}
    guess : float or None
        The guess rate held fixed, or None to marginalise the false-alarm rate.
    level_range : (float, float)
        The thresholds considered, in the level's unit.
    max_lapse : float
        The largest lapse rate considered.

    Returns
    -------
    Posterior

    Examples
    --------
    The trials of :func:`fit`'s example (a 2AFC observer of threshold 0.1):

    >>> import numpy as np
    >>> levels = np.repeat([0.02, 0.05, 0.1, 0.2], 40)
    >>> outcomes = np.concatenate([np.r_[np.ones(k), np.zeros(40 - k)] for k in (20, 22, 33, 40)])
    >>> found = posterior(levels, outcomes)
    >>> round(found.threshold, 2), found.ci[0] < 0.1 < found.ci[1], round(found.guess, 6)
    (0.1, True, 0.5)
    """
    x, n, k = aggregate(levels, outcomes)
    low, high = level_range
    if function == "weibull":
        thresholds, slopes = np.geomspace(max(low, 1e-6), high, 200), np.geomspace(0.7, 12.0, 24)
    else:
        span = max(high - low, 1e-6)
        thresholds, slopes = np.linspace(low, high, 200), np.geomspace(0.5 / span, 60.0 / span, 24)
    guesses = np.array([guess]) if guess is not None else np.linspace(0.0, MAX_FALSE_ALARM, 11)
    lapses = np.linspace(0.0, max_lapse, 4)
    grid = np.array(np.meshgrid(thresholds, np.log(slopes), guesses, lapses, indexing="ij")).reshape(4, -1)
    log_likelihood = _grid_log_likelihood(function, grid, x, n, k)[0]
    weights = np.exp(log_likelihood - log_likelihood.max())
    weights /= weights.sum()
    marginal = weights.reshape(len(thresholds), -1).sum(axis=1)
    scale = np.log(thresholds) if function == "weibull" else thresholds
    cumulative = np.cumsum(marginal)
    low_ci, high_ci = np.interp([0.025, 0.975], cumulative, scale)
    mean = float(np.sum(marginal * scale))
    back = np.exp if function == "weibull" else (lambda value: value)
    return Posterior(float(back(mean)), (float(back(low_ci)), float(back(high_ci))),
                     float(np.exp(np.sum(weights * grid[1]))), float(np.sum(weights * grid[3])),
                     float(np.sum(weights * grid[2])))
