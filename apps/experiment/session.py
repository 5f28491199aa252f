"""A threshold session: the procedure, the schedule, the responder, the log; then the analysis.

The responder presents a trial and returns the answer: :class:`SimResponder` renders the trial
offline through the real renderer and lets a simulated observer answer; the window
(:mod:`apps.experiment.window`) shows it on the touch panel through the live engine. Everything that
defines the procedure lives in :class:`SessionConfig`, saved in ``session.json``, so ``--resume``
rebuilds the same procedure and replays the log into it.
"""

from __future__ import annotations

import datetime
import math
import platform
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.experiment.log import RESULT, SESSION, TrialLog, read_trials, write_json
from ultraglide.render.physics.default_model import EXPERIMENT_MODEL

from ultraglide import __version__
from ultraglide.experiment import psychometric as pf
from ultraglide.experiment.procedures import (
    ConstantParams,
    ConstantStimuli,
    QuestParams,
    QuestPlus,
    Staircase,
    StaircaseParams,
    interval_positions,
    replay,
)
from ultraglide.experiment.responders import Answer  # noqa: F401 - the window and tests take it from here too
from ultraglide.experiment.stimuli import StimulusDesign
from ultraglide.inputs import decode_text, read_input

MIN_FIT_TRIALS = 5  # fewer trials fit no psychometric function
DEFAULT_RANGES = {"contrast": (0.005, 0.6), "wavelength": (0.01, 2.0), "amplitude": (0.05, 6.0)}


@dataclass(frozen=True)
class SessionConfig:
    """Plain values only: it is written to and read back from session.json."""

    texture: str
    method: str = "staircase"  # staircase, quest, constant
    parameter: str = "contrast"
    intervals: int = 2  # 1: yes/no; 2 or 3: forced choice
    rule: str = "1u2d"
    trials: int = 60
    seed: int = 0
    start_level: float | None = None
    level_range: tuple[float, float] | None = None
    levels: tuple[float, ...] = ()  # constant stimuli
    repeats: int = 10
    function: str = "weibull"
    reference: str | None = None
    zone_mm: tuple[float, float] = (40.0, 40.0)
    gap_mm: float = 10.0
    speed_mm_s: float = 100.0
    force_n: float = 0.5
    model: str = EXPERIMENT_MODEL
    profile: str = "sim-plate"
    device: str = "null"
    observer: str | None = None
    participant: str = "P01"
    session: str = "1"
    break_every: int = 0
    preset: str | None = None
    question: str = "Which zone felt different?"
    bootstrap: int = 200
    interval: str = "posterior"  # posterior or bootstrap (staircases and constant stimuli)
    closed_loop: bool = False  # the friction loop on the plate's force sensors (a device with them)

    @property
    def range(self) -> tuple[float, float]:
        return tuple(self.level_range) if self.level_range else DEFAULT_RANGES[self.parameter]

    @property
    def total_trials(self) -> int:
        return len(self.levels) * self.repeats if self.method == "constant" else self.trials

    @property
    def condition(self) -> str:
        task = "yes/no" if self.intervals == 1 else f"{self.intervals}AFC"
        how = self.rule if self.method == "staircase" else self.method
        return f"{self.parameter} {task} {how}"

    def as_dict(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_dict(values: dict, where: str = "session.json") -> SessionConfig:
        """The config a session.json holds; each value is checked against its field's type and, for numbers
        the command line bounds, the same range (:data:`RESUMED_RANGES`): UsageError naming the field."""
        known = {key: values[key] for key in SessionConfig.__dataclass_fields__ if key in values}
        if "texture" not in known:
            raise UsageError(f"{where}: the session's texture is missing")
        for key, value in known.items():
            known[key] = _typed(key, value, SessionConfig.__dataclass_fields__[key].type, where)
        try:
            return SessionConfig(**known)
        except (TypeError, ValueError) as error:
            raise UsageError(f"{where}: {str(error).splitlines()[0]}") from None


CHOICES = {"method": ("staircase", "quest", "constant"), "parameter": tuple(DEFAULT_RANGES),
           "rule": ("1u2d", "1u3d", "weighted"), "function": ("weibull", "logistic"),
           "interval": ("posterior", "bootstrap"), "intervals": (1, 2, 3)}
RESUMED_RANGES = {  # the command line's ranges (apps.cli.types) for what session.json can hold
    "trials": (1, 100_000), "repeats": (1, 100_000), "seed": (0, 2**32 - 1), "bootstrap": (10, 100_000),
    "break_every": (0, 100_000), "zone_mm": (1.0, 1_000.0), "gap_mm": (0.0, 1_000.0), "speed_mm_s": (1e-6, 10_000.0),
    "force_n": (1e-6, 50.0), "start_level": (0.0, 10_000.0), "level_range": (0.0, 10_000.0), "levels": (0.0, 10_000.0)}
MAX_RESUMED_LEVELS = 1_000


def _typed(key: str, value, annotation: str, where: str):
    """``value`` as field ``key`` of the annotated type takes it (lists become tuples), or UsageError."""
    def bad(what: str):
        return UsageError(f"{where}: config {key} must be {what}, got {str(value)[:40]!r}")

    def number(item, integer: bool):
        if isinstance(item, bool) or not isinstance(item, int if integer else int | float):
            raise bad("a whole number" if integer else "a number")
        low, high = RESUMED_RANGES.get(key, (-math.inf, math.inf))
        if not (math.isfinite(item) and low <= item <= high):
            raise bad(f"from {low:g} to {high:g}")
        return item if integer else float(item)

    if value is None and "None" in annotation:
        return None
    base = annotation.replace(" | None", "")
    if base == "str":  # shown in the window, printed, drawn on the figures: no control characters
        if not isinstance(value, str) or len(value) > 10_000 or not value.isprintable():
            raise bad("printable text")
    elif base in ("int", "float"):
        value = number(value, base == "int")
    elif base.startswith("tuple["):
        pair = base == "tuple[float, float]"
        if not isinstance(value, list | tuple) or (pair and len(value) != 2) or len(value) > MAX_RESUMED_LEVELS:
            raise bad("a pair of numbers" if pair else "a list of numbers")
        value = tuple(number(item, False) for item in value)
    if key in CHOICES and value not in CHOICES[key]:
        raise bad(f"one of {', '.join(map(str, CHOICES[key]))}")
    return value


def check_levels(config: SessionConfig, where: str) -> None:
    """Refuse, before any file is written, levels the procedure cannot take: a range that is not 0 < LOW < HIGH, a
    staircase's start outside it (UsageError naming ``where``: the options, or the session.json resumed)."""
    if config.method == "constant":
        return
    low, high = config.range
    if not 0 < low < high:
        raise UsageError(f"{where}: the levels' range needs 0 < LOW < HIGH, got {low:g} {high:g}")
    start = config.start_level
    if config.method == "staircase" and start is not None and not low <= start <= high:
        raise UsageError(f"{where}: the start level {start:g} lies outside the levels' range {low:g}..{high:g}; "
                         "start within it (or widen --range)")


def make_procedure(config: SessionConfig):
    low, high = config.range
    if config.method == "constant":
        return ConstantStimuli(ConstantParams(tuple(config.levels), config.repeats, config.seed))
    guess = 1.0 / config.intervals if config.intervals > 1 else 0.0
    if config.method == "quest":
        return QuestPlus(QuestParams.log_grid(low, high, function=config.function, guess=guess))
    start = config.start_level if config.start_level is not None else math.sqrt(low * high) * 4
    return Staircase(StaircaseParams(min(start, high), config.rule, min_level=low, max_level=high))


@dataclass
class SessionResult:
    directory: Path
    rows: list[dict]
    result: dict
    figures: list[Path] = field(default_factory=list)
    complete: bool = True


def versions() -> dict:
    import matplotlib
    import scipy

    return {"ultraglide": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "matplotlib": matplotlib.__version__}


def metadata(config: SessionConfig, design: StimulusDesign, status: str, started_utc: str, extra: dict) -> dict:
    from ultraglide.devices.rig import load_plate
    from ultraglide.render.physics.calibration import load_model

    profile = load_plate(config.profile)
    model = load_model(config.model)
    calibration = None
    if config.model.endswith(".toml"):
        text = decode_text(read_input(config.model, "calibration file", UsageError), config.model, "calibration file",
                           UsageError)
        calibration = {"file": str(Path(config.model).resolve()), "text": text}
    return {
        "status": status, "started_utc": started_utc, "updated_utc": now_utc(),
        "config": config.as_dict(), "unit": design.unit, "condition": config.condition,
        "question": config.question,
        "profile": {"name": config.profile, "resonance_hz": profile.resonance_hz, "q": profile.q,
                    "max_amplitude_um_pp": profile.max_amplitude_um_pp},
        "model": {"spec": config.model, "description": model.describe(), "parameters": model.parameters()},
        "calibration": calibration,
        "device": config.device, "observer": config.observer or "participant",
        "layout": {"zones": design.layout.zones, "zone_mm": list(design.layout.zone_mm),
                   "gap_mm": design.layout.gap_mm, "canvas_mm": list(design.layout.size_mm)},
        "versions": versions(), "seed": config.seed, **extra,
    }


def now_utc() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="milliseconds")


def run_session(config: SessionConfig, design: StimulusDesign, responder, directory: Path,
                resume: bool = False, figures: bool = True, recorded: dict | None = None) -> SessionResult:
    """Run (or continue) a session into ``directory``: trials.csv as it goes, session.json at the start
    and the end, result.json and (unless ``figures`` is False, as for a batch of simulated sessions
    that only their results serve; then a resumed session's earlier figures are removed) the figures when it
    ends. ``recorded``: more for session.json (the stimulus check, its accepted warnings)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    rows = read_trials(directory) if resume else []
    procedure = make_procedure(config)
    try:
        replay(procedure, [float(r["level"]) for r in rows], [outcome(config, r) for r in rows])
    except ValueError as error:
        raise UsageError(f"--resume {directory}: {error}") from None
    total = config.total_trials
    positions = interval_positions(config.seed, total, max(config.intervals, 1))
    started = now_utc()
    extra = {"resumed_at_trial": len(rows) + 1} if resume else {}
    extra.update(recorded or {})
    write_json(directory / SESSION, metadata(config, design, "running", started, extra))
    log = TrialLog(directory)
    complete = True
    try:
        for trial in range(len(rows) + 1, total + 1):
            if getattr(procedure, "finished", False):
                break
            pause = bool(config.break_every and trial > 1 and (trial - 1) % config.break_every == 0)
            if pause and not responder.take_break(trial):
                complete = False
                break
            level = procedure.next_level()
            target = positions[trial - 1] if config.intervals > 1 else 0
            answer = responder.present(trial, level, target, design)
            if answer.quit:
                complete = False
                break
            row = make_row(config, design, trial, level, target, answer, pause)
            procedure.update(level, outcome(config, row))
            row["reversal"] = int(getattr(procedure, "last_was_reversal", False))
            log.write(row)
            rows.append(row)
    finally:
        log.close()
    result = analyse(config, design, rows, procedure, complete)
    write_json(directory / RESULT, result)
    from ultraglide.apps.experiment.figures import draw_figures

    drawn = draw_figures(directory, config, design, rows, result) if rows and figures else []
    if not figures:
        _remove_earlier_figures(directory)
    write_json(directory / SESSION, metadata(config, design, "complete" if complete else "stopped", started,
                                             {**extra, "trials_logged": len(rows)}))
    return SessionResult(directory, rows, result, drawn, complete)


def _remove_earlier_figures(directory: Path) -> None:
    """The figures an earlier run of a resumed session drew (regular files only): they show fewer trials than the
    log now holds, and a session not drawn leaves none that disagree with it."""
    from ultraglide.apps.figures import SESSION_FIGURES, both_formats

    for name in both_formats(SESSION_FIGURES):
        path = directory / name
        if path.is_file() and not path.is_symlink():
            path.unlink()


def make_row(config: SessionConfig, design: StimulusDesign, trial: int, level: float, target: int, answer: Answer,
             pause: bool) -> dict:
    correct = answer.response == target if config.intervals > 1 else answer.response == int(level > 0)
    return {"participant": config.participant, "session": config.session, "trial": trial,
            "condition": config.condition, "level": repr(float(level)),
            "stimulus": design.describe(level, target),
            "target": target + 1 if config.intervals > 1 else "",
            "response": answer.response + 1 if config.intervals > 1 else ("yes" if answer.response else "no"),
            "correct": int(correct), "rt_s": f"{answer.rt_s:.4f}", "reversal": 0, "break_before": int(pause),
            "rendered_um_pp": "" if answer.rendered_um_pp is None else f"{answer.rendered_um_pp:.4f}",
            "rendered_contrast": "" if answer.rendered_contrast is None else f"{answer.rendered_contrast:.4f}",
            "time_utc": now_utc(), **_friction_columns(answer.friction)}


def _friction_columns(friction: dict | None) -> dict:
    """The trial's played friction as the log's columns (empty where unknown: a dry run, open loop)."""
    friction = friction or {}

    def number(key: str) -> str:
        value = friction.get(key)
        return "" if value is None or not math.isfinite(value) else f"{value:.4f}"

    return {"target_ratio": number("target_ratio"), "measured_ratio": number("measured_ratio"),
            "commanded_um_pp": number("commanded_um_pp"), "loop": friction.get("loop", "")}


def outcome(config: SessionConfig, row: dict) -> int:
    """What the procedure and the fit count: correct in forced choice, "yes" in yes/no."""
    if config.intervals > 1:
        return int(row["correct"])
    return int(row["response"] == "yes")


def analyse(config: SessionConfig, design: StimulusDesign, rows: list[dict], procedure, complete: bool) -> dict:
    """The threshold with its 95 % interval, the fit, and how they were obtained."""
    levels = np.array([float(r["level"]) for r in rows])
    outcomes = np.array([outcome(config, r) for r in rows])
    result = {"threshold": None, "ci": None, "unit": design.unit, "parameter": config.parameter,
              "method": config.method, "condition": config.condition, "trials": len(rows),
              "complete": complete, "function": config.function,
              "threshold_definition": ("the level where the detection function F reaches 1 - 1/e = 63.2 % "
                                       "(Weibull alpha)" if config.function == "weibull" else
                                       "the level where the detection function F reaches 50 % (logistic)"),
              "guess": (1.0 / config.intervals) if config.intervals > 1 else "fitted false-alarm rate"}
    result.update(reaction_times(rows))
    if len(rows) < MIN_FIT_TRIALS:
        result["note"] = f"{len(rows)} trials logged, and a fit needs at least {MIN_FIT_TRIALS}"
        return result
    guess = 1.0 / config.intervals if config.intervals > 1 else None
    # constant stimuli: the threshold may lie up to half as far again as the largest level
    low, high = config.range if config.method != "constant" else (0.0, 1.5 * max(config.levels))
    fitted = pf.fit(levels, outcomes, config.function, guess, (low, high))
    if config.method == "quest":
        estimate = procedure.estimate()
        result.update(threshold=estimate["threshold"], ci=estimate["ci"],
                      ci_kind="95 % credible interval of the QUEST+ posterior (grid, uniform prior on log threshold)",
                      posterior=estimate)
    elif config.interval == "bootstrap":
        fitted = pf.bootstrap(fitted, levels, config.bootstrap, config.seed, fit_guess=guess is None,
                              level_range=(low, high))
        result.update(threshold=fitted.threshold, ci=list(fitted.ci),
                      ci_kind=f"95 % parametric bootstrap ({fitted.bootstrap_samples} samples) of the ML fit")
    else:
        bayes = pf.posterior(levels, outcomes, config.function, guess, (max(low, 1e-3 * high), high))
        result.update(threshold=bayes.threshold, ci=list(bayes.ci),
                      ci_kind="95 % credible interval of the posterior on a grid (slope, lapse"
                              + (", false alarms" if guess is None else "") + " marginalised; uniform prior on "
                              "log threshold and log slope); threshold: its posterior mean",
                      posterior={"slope": bayes.slope, "lapse": bayes.lapse, "guess": bayes.guess})
    result["fit"] = fitted.as_dict()
    if isinstance(procedure, Staircase):
        result.update(rule=config.rule, target_p=procedure.target_p, reversals=len(procedure.reversals),
                      reversal_mean=procedure.reversal_mean())
    if config.method == "constant":
        x, n, k = pf.aggregate(levels, outcomes)
        result["proportions"] = [{"level": float(a), "n": int(b), "positive": int(c), "p": float(c / b)}
                                 for a, b, c in zip(x, n, k, strict=True)]
    return result


def reaction_times(rows: list[dict]) -> dict:
    """The median and count of the logged reaction times (s) that are numbers; None without any."""
    from ultraglide.experiment.analysis import reaction_time_summary

    return reaction_time_summary(rows)


def resumed_config(saved: dict, trials: int | None, where: str = "session.json") -> SessionConfig:
    config = SessionConfig.from_dict(saved.get("config", {}), where)
    return replace(config, trials=trials) if trials else config
