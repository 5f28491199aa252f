"""Analyses as functions of the trials table: a list of dicts (trials.csv's rows) or a pandas DataFrame.

Each function takes the table as a session returns it (:attr:`ultraglide.experiment.Session.trials`), as
:func:`read_trials` reads it back from ``trials.csv``, or as a DataFrame of either, and leaves practice trials out
(``practice`` = 1) unless asked. Groups are given by column names (``by="condition"``).

Examples
--------
>>> from ultraglide.experiment.analysis import fit_psychometric
>>> rows = [{"condition": "c", "level": level, "correct": int(k < hits)}
...         for level, hits in ((0.02, 5), (0.05, 6), (0.1, 9), (0.2, 10)) for k in range(10)]
>>> fits = fit_psychometric(rows, by="condition", bootstrap=100)
>>> fits[0]["condition"], fits[0]["trials"], fits[0]["ci"][0] < fits[0]["threshold"] < fits[0]["ci"][1]
('c', 40, True)
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ultraglide.experiment import psychometric as pf
from ultraglide.experiment.errors import ExperimentError

MIN_FIT_TRIALS = 5


def records(table) -> list[dict]:
    """The table's rows as dicts: a list of dicts as it is, a DataFrame's records.

    Parameters
    ----------
    table : list of dict, pandas.DataFrame or any iterable of dicts

    Returns
    -------
    list of dict

    Examples
    --------
    >>> records(iter([{"level": 0.1}, {"level": 0.2}]))
    [{'level': 0.1}, {'level': 0.2}]
    """
    if hasattr(table, "to_dict"):
        return table.to_dict("records")
    return list(table)


def as_frame(rows: list[dict]):
    """A pandas DataFrame of ``rows`` if pandas is installed, else ``rows`` (pandas is not a dependency).

    Parameters
    ----------
    rows : list of dict
        A trials table (one dict per trial).

    Returns
    -------
    pandas.DataFrame or list of dict

    Examples
    --------
    >>> table = as_frame([{"level": 0.1, "correct": 1}, {"level": 0.2, "correct": 0}])
    >>> records(table)                       # back to dicts, whichever it is
    [{'level': 0.1, 'correct': 1}, {'level': 0.2, 'correct': 0}]
    """
    try:
        import pandas
    except ImportError:
        return rows
    return pandas.DataFrame(rows)


def _float(value) -> float | None:
    if value is None or value == "":
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def read_trials(path) -> list[dict]:
    """trials.csv (or a session directory holding one) as a list of dicts, numbers as numbers, empty cells as None.

    ``pandas.DataFrame(read_trials("s01/"))`` gives a DataFrame, or ``pandas.read_csv("s01/trials.csv")`` directly.

    Parameters
    ----------
    path : str or os.PathLike
        A trials.csv, or the session's directory.

    Returns
    -------
    list of dict
        One dict per row, keyed by the header's columns; whole numbers as int, other numbers as float.

    Raises
    ------
    ExperimentError
        The file cannot be read (one line naming it).

    Examples
    --------
    A file written by the ``csv`` module, read back:

    >>> import csv, tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with open(folder / "trials.csv", "w", newline="") as handle:
    ...     csv.writer(handle).writerows([["trial", "level", "rt_s", "response_label"], [1, 0.05, "", "Yes"]])
    >>> read_trials(folder)
    [{'trial': 1, 'level': 0.05, 'rt_s': None, 'response_label': 'Yes'}]
    """
    path = Path(path)
    if path.is_dir():
        path = path / "trials.csv"
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ExperimentError(f"{path}: cannot read the trials ({error})") from None

    def typed(text: str):
        if text == "":
            return None
        try:
            return int(text)
        except ValueError:
            pass
        try:
            return float(text)
        except ValueError:
            return text

    return [{key: typed(value) for key, value in row.items()} for row in rows]


def _groups(rows: list[dict], by) -> dict[tuple, list[dict]]:
    keys = [by] if isinstance(by, str) else list(by or [])
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        groups.setdefault(tuple(row.get(key) for key in keys), []).append(row)
    return groups


def _main(rows, practice: bool) -> list[dict]:
    return [r for r in records(rows) if practice or not _float(r.get("practice"))]


def reaction_time_summary(table) -> dict:
    """``rt_s_median`` and ``rt_s_count``: the median (s) of the reaction times that are numbers, and how many;
    the median is None when none is.

    Parameters
    ----------
    table : list of dict or pandas.DataFrame
        Rows with an ``rt_s`` column (s).

    Returns
    -------
    dict
        ``rt_s_median`` (s, or None) and ``rt_s_count``.

    Examples
    --------
    >>> reaction_time_summary([{"rt_s": 0.5}, {"rt_s": 0.7}, {"rt_s": None}, {"rt_s": ""}])
    {'rt_s_median': 0.6, 'rt_s_count': 2}
    """
    times = [t for t in (_float(r.get("rt_s")) for r in records(table)) if t is not None]
    return {"rt_s_median": float(np.median(times)) if times else None, "rt_s_count": len(times)}


def fit_psychometric(table, by="condition", level: str = "level", outcome: str = "correct", guess: float | None = 0.5,
                     function: str = "weibull", bootstrap: int = 200, seed: int = 0,
                     practice: bool = False) -> list[dict]:
    """A maximum-likelihood psychometric fit per group, with a parametric-bootstrap 95 % interval on the threshold.

    Parameters
    ----------
    table : list of dict or pandas.DataFrame
        One row per trial with ``level`` and ``outcome`` columns (1 = correct / yes).
    by : str or list of str
        The grouping columns (one fit each); None: one fit of all rows.
    level, outcome : str
        The columns holding the level (in the varied parameter's unit) and the outcome.
    guess : float or None
        The guess rate: 1/n in n-interval forced choice; None fits it (yes/no: the false-alarm rate).
    function : "weibull" or "logistic"
    bootstrap : int
        Simulated data sets for the interval (0: no interval).
    seed : int
    practice : bool
        Include practice trials.

    Returns
    -------
    list of dict
        Per group: the grouping columns, ``trials``, ``threshold`` (the level where the detection function reaches
        63.2 % for the Weibull, 50 % for the logistic; in the level's unit), ``slope``, ``lapse``, ``guess``,
        ``ci`` ([low, high], or None), or ``threshold`` None and a ``note`` for a group of fewer than 5 trials.

    Examples
    --------
    Trials made exactly as a 2AFC observer of threshold 0.1 and slope 3 answers on average (40 at each level; 20,
    22, 33 and 40 correct: :func:`ultraglide.experiment.psychometric.probability` rounded), and a group too small:

    >>> rows = [{"condition": "c", "level": level, "correct": int(k < hits)}
    ...         for level, hits in ((0.02, 20), (0.05, 22), (0.1, 33), (0.2, 40)) for k in range(40)]
    >>> rows += [{"condition": "d", "level": 0.1, "correct": 1}]
    >>> fits = fit_psychometric(rows, bootstrap=100)
    >>> [(fit["condition"], fit["trials"], fit["threshold"] and round(fit["threshold"], 2)) for fit in fits]
    [('c', 160, 0.1), ('d', 1, None)]
    """
    keys = [by] if isinstance(by, str) else list(by or [])
    out = []
    for group, rows in _groups(_main(table, practice), keys).items():
        pairs = [(_float(r.get(level)), _float(r.get(outcome))) for r in rows]
        pairs = [(x, y) for x, y in pairs if x is not None and y is not None]
        entry = {**dict(zip(keys, group, strict=True)), "trials": len(pairs)}
        if len(pairs) < MIN_FIT_TRIALS:
            out.append({**entry, "threshold": None, "ci": None,
                        "note": f"{len(pairs)} trials with a level and an outcome, and a fit needs at least "
                                f"{MIN_FIT_TRIALS}"})
            continue
        levels, outcomes = np.array(pairs).T
        fitted = pf.fit(levels, outcomes, function, guess, (0.0, 1.5 * float(levels.max())) if function == "weibull"
                        else None)
        if bootstrap:
            fitted = pf.bootstrap(fitted, levels, bootstrap, seed, fit_guess=guess is None,
                                  level_range=(0.0, 1.5 * float(levels.max())) if function == "weibull" else None)
        out.append({**entry, **fitted.as_dict(), "ci": list(fitted.ci) if fitted.ci else None})
    return out


def threshold_posterior(table, by="condition", level: str = "level", outcome: str = "correct",
                        guess: float | None = 0.5, function: str = "weibull",
                        level_range: tuple[float, float] = (1e-3, 1.0), practice: bool = False) -> list[dict]:
    """The threshold's posterior mean and 95 % credible interval per group (grid posterior, slope and lapse
    marginalised; valid for staircase data): ``threshold``, ``ci``, ``slope``, ``lapse``, ``trials``.

    Parameters
    ----------
    table : list of dict or pandas.DataFrame
        One row per trial with ``level`` and ``outcome`` columns.
    by : str or list of str
        The grouping columns (one posterior each); None: one of all rows.
    level, outcome : str
        The columns holding the level (in the varied parameter's unit) and the outcome (1 = correct / yes).
    guess : float or None
        The guess rate (1/n in forced choice); None marginalises the false-alarm rate (yes/no).
    function : {"weibull", "logistic"}
    level_range : (float, float)
        The thresholds considered, in the level's unit.
    practice : bool
        Include practice trials.

    Returns
    -------
    list of dict
        Per group: the grouping columns, ``trials``, ``threshold`` (level's unit), ``ci`` ([low, high]), ``slope``,
        ``lapse``; or ``threshold`` None and a ``note`` for a group of fewer than 5 trials.

    Examples
    --------
    Trials made exactly as a 2AFC observer of threshold 0.1 and slope 3 answers on average (40 at each level; 20,
    22, 33 and 40 correct: :func:`ultraglide.experiment.psychometric.probability` rounded):

    >>> rows = [{"condition": "c", "level": level, "correct": int(k < hits)}
    ...         for level, hits in ((0.02, 20), (0.05, 22), (0.1, 33), (0.2, 40)) for k in range(40)]
    >>> found = threshold_posterior(rows)[0]
    >>> found["trials"], round(found["threshold"], 2), found["ci"][0] < 0.1 < found["ci"][1]
    (160, 0.1, True)
    """
    keys = [by] if isinstance(by, str) else list(by or [])
    out = []
    for group, rows in _groups(_main(table, practice), keys).items():
        pairs = [(_float(r.get(level)), _float(r.get(outcome))) for r in rows]
        pairs = [(x, y) for x, y in pairs if x is not None and y is not None]
        entry = {**dict(zip(keys, group, strict=True)), "trials": len(pairs)}
        if len(pairs) < MIN_FIT_TRIALS:
            out.append({**entry, "threshold": None, "ci": None,
                        "note": f"{len(pairs)} trials, and a fit needs at least {MIN_FIT_TRIALS}"})
            continue
        levels, outcomes = np.array(pairs).T
        found = pf.posterior(levels, outcomes, function, guess, level_range)
        out.append({**entry, "threshold": found.threshold, "ci": list(found.ci), "slope": found.slope,
                    "lapse": found.lapse})
    return out


def proportions(table, by="condition", outcome: str = "correct", practice: bool = False) -> list[dict]:
    """Per group: ``trials``, ``positive`` (outcome = 1) and ``p`` with its 95 % Wilson interval ``ci``.

    Parameters
    ----------
    table : list of dict or pandas.DataFrame
    by : str or list of str
        The grouping columns; None: all rows together.
    outcome : str
        The column holding 1 (positive) or 0.
    practice : bool
        Include practice trials.

    Returns
    -------
    list of dict
        Per group with an outcome: the grouping columns, ``trials``, ``positive``, ``p`` and ``ci`` ([low, high]).

    Examples
    --------
    8 of 10 correct; the Wilson interval by hand (z = 1.959964):

    >>> import math
    >>> found = proportions([{"condition": "c", "correct": int(k < 8)} for k in range(10)])[0]
    >>> z, n, p = 1.959964, 10, 0.8
    >>> centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    >>> half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    >>> found["p"], [round(v, 4) for v in found["ci"]], [round(centre - half, 4), round(centre + half, 4)]
    (0.8, [0.4902, 0.9433], [0.4902, 0.9433])
    """
    keys = [by] if isinstance(by, str) else list(by or [])
    out = []
    for group, rows in _groups(_main(table, practice), keys).items():
        values = [v for v in (_float(r.get(outcome)) for r in rows) if v is not None]
        n, k = len(values), float(sum(values))
        if not n:
            continue
        p, z = k / n, 1.959964
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        out.append({**dict(zip(keys, group, strict=True)), "trials": n, "positive": int(k), "p": p,
                    "ci": [centre - half, centre + half]})
    return out


def mean_response(table, by="condition", response: str = "response", log: bool = False, bootstrap: int = 2000,
                  seed: int = 0, practice: bool = False) -> list[dict]:
    """Per group: the mean response (ratings), or with ``log`` the geometric mean (magnitude estimates), with a 95 %
    bootstrap interval (``bootstrap`` resamples of the trials), ``median`` and ``trials``.

    Parameters
    ----------
    table : list of dict or pandas.DataFrame
    by : str or list of str
        The grouping columns; None: all rows together.
    response : str
        The column holding the number given.
    log : bool
        The geometric mean (positive responses only).
    bootstrap : int
        Resamples for the interval (0: the interval is the mean itself).
    seed : int
    practice : bool
        Include practice trials.

    Returns
    -------
    list of dict
        Per group with a response: the grouping columns, ``trials``, ``mean``, ``ci`` ([low, high]) and ``median``,
        in the response's unit.

    Examples
    --------
    Magnitude estimates 2, 4 and 8: their geometric mean is (2 × 4 × 8) ** (1/3) = 4:

    >>> found = mean_response([{"condition": "c", "response": v} for v in (2, 4, 8)], log=True, bootstrap=0)[0]
    >>> round(found["mean"], 9), found["median"], found["trials"]
    (4.0, 4.0, 3)
    """
    keys = [by] if isinstance(by, str) else list(by or [])
    rng = np.random.default_rng(seed)
    out = []
    for group, rows in _groups(_main(table, practice), keys).items():
        values = np.array([v for v in (_float(r.get(response)) for r in rows) if v is not None and (v > 0 or not log)])
        if not len(values):
            continue
        data = np.log(values) if log else values
        means = rng.choice(data, (bootstrap, len(data))).mean(axis=1) if bootstrap else np.array([data.mean()])
        low, high = np.percentile(means, [2.5, 97.5])
        back = np.exp if log else (lambda v: v)
        out.append({**dict(zip(keys, group, strict=True)), "trials": len(values), "mean": float(back(data.mean())),
                    "ci": [float(back(low)), float(back(high))], "median": float(np.median(values))})
    return out


def summarise(design, rows: list[dict], procedures: dict) -> dict:
    """A session's summary: per block and condition the fit (thresholds with their 95 % intervals), proportions,
    mean ratings or estimates; reaction times when there are any.

    Parameters
    ----------
    design : Design
        The session's design.
    rows : list of dict
        The session's trials (trials.csv's rows, as :attr:`Session.trials` holds them).
    procedures : dict
        The adaptive procedures by (block, condition), for their own estimates (empty: none).

    Returns
    -------
    dict
        ``design`` (its name), ``trials``, ``rt_s_median``, ``rt_s_count`` and ``blocks``: per block its
        ``conditions``, each with its figures.

    Examples
    --------
    An A-vs-B block of four trials, three correct (the practice trial left out of the proportion):

    >>> from ultraglide.experiment import design_from_dict
    >>> design = design_from_dict({"stimuli": {"a": {"texture": "grating-1mm"}, "b": {"texture": "grating-2mm"}},
    ...     "conditions": [{"name": "ab", "a": "a", "b": "b"}],
    ...     "blocks": [{"name": "main", "task": "afc", "conditions": ["ab"], "repeats": 4}]})
    >>> rows = [{"block": "main", "task": "afc", "condition": "ab", "practice": int(k == 4), "correct": int(k != 1),
    ...          "rt_s": 0.5 + 0.1 * k} for k in range(5)]
    >>> condition = summarise(design, rows, {})["blocks"][0]["conditions"][0]
    >>> condition["trials"], condition["positive"], condition["p"]
    (4, 3, 0.75)
    """
    from ultraglide.experiment.design import ADAPTIVE

    blocks = []
    for block in design.blocks:
        own = [r for r in rows if r["block"] == block.name]
        entry = {"block": block.name, "task": block.task, "trials": len(own),
                 "practice_trials": sum(1 for r in own if r["practice"]), **reaction_time_summary(own)}
        conditions = []
        for name in block.conditions:
            mine = [r for r in own if r["condition"] == name]
            item = {"condition": name, "factors": dict(design.conditions[name].factors)}
            if block.task in ADAPTIVE + ("constant",):
                guess = 1.0 / block.intervals if block.intervals > 1 else None
                outcome_rows = [{**r, "positive": _positive(r)} for r in mine]
                found = threshold_posterior(outcome_rows, None, outcome="positive", guess=guess,
                                            function=block.function, level_range=_range(design, name, block))
                item.update({key: value for key, value in found[0].items() if key != "trials"} if found else
                            {"threshold": None, "ci": None, "note": "no trials"})
                item["ci_kind"] = ("95 % credible interval of the grid posterior (slope and lapse marginalised; "
                                   "uniform prior on log threshold)")
                procedure = procedures.get((block.name, name))
                if block.task == "quest" and procedure is not None and procedure.trials:
                    item["quest"] = procedure.estimate()
                if block.task == "staircase" and procedure is not None:
                    item["reversals"] = len(procedure.reversals)
                    item["reversal_mean"] = procedure.reversal_mean()
                    item["target_p"] = procedure.target_p
                if block.task == "constant":
                    item["proportions"] = proportions(outcome_rows, "level", outcome="positive")
            elif block.task in ("afc", "same_different"):
                found = proportions(mine, None)
                item.update(found[0] if found else {"trials": 0})
            else:
                found = mean_response(mine, None, log=block.task in ("magnitude", "adjustment"))
                item.update(found[0] if found else {"trials": 0})
            conditions.append(item)
        entry["conditions"] = conditions
        blocks.append(entry)
    return {"design": design.name, "trials": len(rows), **reaction_time_summary(rows), "blocks": blocks}


def _positive(row: dict) -> int:
    if row["task"] == "constant" and row["target"] is None:
        return int(row["response"] == "yes")
    return int(row["correct"])


def _range(design, condition: str, block) -> tuple[float, float]:
    found = design.conditions[condition]
    if block.task == "constant":
        return (max(1e-3 * max(found.levels), 1e-6), 1.5 * max(found.levels)) if max(found.levels) > 0 else (1e-3, 1)
    low, high = found.range
    return (max(low, 1e-3 * high), high)
