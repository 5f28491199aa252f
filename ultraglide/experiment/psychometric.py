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
    """F(level) in 0..1, broadcasting over arrays of levels and of parameters."""
    level = np.asarray(level, dtype=float)
    if function == "weibull":
        ratio = np.maximum(level, 0.0) / threshold
        return -np.expm1(-(ratio ** slope))
    if function == "logistic":
        return 0.5 * (1.0 + np.tanh(0.5 * slope * (level - threshold)))
    raise ValueError(f"psychometric function must be one of {', '.join(FUNCTIONS)}, got {function!r}")


def probability(function: str, level, threshold, slope, guess, lapse) -> np.ndarray:
    """P(correct) in forced choice, P(yes) in yes/no."""
    return guess + (1.0 - guess - lapse) * core(function, level, threshold, slope)


def level_at(function: str, p_core: float, threshold: float, slope: float) -> float:
    """The level where F reaches ``p_core`` (the inverse of :func:`core`)."""
    if function == "weibull":
        return float(threshold * (-np.log1p(-p_core)) ** (1.0 / slope))
    return float(threshold + np.log(p_core / (1.0 - p_core)) / slope)


@dataclass(frozen=True)
class Fit:
    """A fitted psychometric function. ``ci``: the threshold's 95 % interval (bootstrap)."""

    function: str
    threshold: float
    slope: float
    guess: float
    lapse: float
    log_likelihood: float
    ci: tuple[float, float] | None = None
    bootstrap_samples: int = 0

    def probability(self, level) -> np.ndarray:
        return probability(self.function, level, self.threshold, self.slope, self.guess, self.lapse)

    def as_dict(self) -> dict:
        return {"function": self.function, "threshold": self.threshold, "slope": self.slope,
                "guess": self.guess, "lapse": self.lapse, "log_likelihood": self.log_likelihood,
                "ci": list(self.ci) if self.ci else None, "bootstrap_samples": self.bootstrap_samples}


def aggregate(levels, outcomes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct levels, trials at each and positive outcomes at each."""
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
    maximum likelihood on a fine grid (160 thresholds × 32 slopes × 4 lapse rates, all data sets at once)."""
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
    """The threshold's posterior on a grid: its mean on the log scale and 95 % credible interval."""

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
    their levels, so it holds for staircase data too)."""
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
