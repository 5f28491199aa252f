"""Running a design: its stimuli checked, its trials presented through a responder, its files written.

:func:`run` is the whole session: the stimulus check (:mod:`ultraglide.experiment.check`; a failing design is
refused unless ``accept_check``, and then the warning is recorded), the trial plan
(:func:`ultraglide.experiment.design.plan`), each trial presented through the responder (the participant-interface
seam, :mod:`ultraglide.experiment.responders`) with a procedure per adaptive condition choosing its level, and, with
``out``, ``trials.csv`` (a row per trial, fsync'd as it goes), ``session.json`` and ``summary.json``.
"""

from __future__ import annotations

import csv
import datetime
import json
import math
import os
import platform
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ultraglide.experiment.check import CheckReport, Rig, ZoneSource, check_stimuli, refuse, refuse_unfit
from ultraglide.experiment.columns import DESIGN_COLUMNS
from ultraglide.experiment.design import ADAPTIVE, Block, Design, Trial, plan, response_labels, to_toml
from ultraglide.experiment.errors import ExperimentError
from ultraglide.experiment.procedures import QuestParams, QuestPlus, Staircase, StaircaseParams
from ultraglide.experiment.responders import Answer

TRIALS, SESSION, SUMMARY = "trials.csv", "session.json", "summary.json"


@dataclass(frozen=True)
class Presentation:
    """What a responder presents: the planned trial, its level (chosen now for adaptive blocks), the question and
    answer labels in the participant's language, the zones' layout and a function building the trial's texture
    (every zone in place, plain glass between), and the trial's stimulus figures for a simulated observer.

    Parameters
    ----------
    trial : Trial
    level : float or None
        In the condition's unit.
    question : str
    labels : tuple of str
    intervals : int
    layout : Layout
    texture : callable
        Returns the trial's Texture.
    stimulus_design : StimulusDesign or None
        Adaptive and constant blocks: the condition's.
    figures : tuple
        StimulusFigures of each zone's stimulus (None for plain glass or a varied zone).
    modulus : float, optional
    scale : (int, int), optional
        A rating's (low, high).
    texture_at : callable, optional
        Adjustment: the trial's Texture with the adjusted zone at a level.
    level_range : (float, float), optional
        Adjustment: the levels it may be set to.

    Examples
    --------
    A responder sees one per trial; this one keeps them:

    >>> from ultraglide.experiment import Answer, design_from_dict, run
    >>> class Keeper:
    ...     shown = []
    ...     def present(self, presentation):
    ...         self.shown.append(presentation)
    ...         return Answer(3, 0.5)
    ...     def take_break(self, trial, message):
    ...         return True
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
    ...     "conditions": [{"name": "g", "stimulus": "g"}],
    ...     "blocks": [{"task": "rating", "conditions": ["g"], "repeats": 2, "scale": [1, 5]}]})
    >>> session = run(design, responder=Keeper(), check=False)
    >>> [(p.trial.number, p.question, p.scale, p.layout.zones) for p in Keeper.shown]
    [(1, 'How rough did it feel?', (1, 5), 1), (2, 'How rough did it feel?', (1, 5), 1)]
    >>> Keeper.shown[0].texture().width_mm               # one 40 mm zone and 10 mm of glass either side
    60.0
    """

    trial: Trial
    level: float | None
    question: str
    labels: tuple[str, ...]
    intervals: int
    layout: object  # ultraglide.experiment.stimuli.Layout
    texture: object  # a callable returning the trial's Texture
    stimulus_design: object | None  # adaptive and constant blocks: the StimulusDesign of the condition
    figures: tuple  # StimulusFigures of each zone's stimulus (None for plain glass or a varied zone)
    modulus: float | None = None
    scale: tuple[int, int] | None = None  # a rating's (low, high)
    texture_at: object = None  # adjustment: a callable returning the trial's Texture with the adjusted zone at a level
    level_range: tuple[float, float] | None = None  # adjustment: the levels it may be set to


@dataclass
class Session:
    """A session's outcome. ``trials``: one dict per trial (the columns of trials.csv, numbers as numbers);
    ``summary``: the fits per block and condition; ``check``: the stimulus check; ``directory``: where its files
    went (None without ``out``); ``complete``: False if the participant stopped it.

    Parameters
    ----------
    design : Design
    trials : list of dict
    summary : dict
    check : CheckReport or None
    directory : pathlib.Path or None
    complete : bool
    warnings : list of str
        What was accepted despite the check, one sentence each.

    Examples
    --------
    Written with ``out``, its trials.csv read back by ``csv`` holds the same rows:

    >>> import csv, pathlib, tempfile
    >>> from ultraglide.experiment import design_from_dict, run
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
    ...     "conditions": [{"name": "g", "stimulus": "g", "levels": [0.1, 0.3]}],
    ...     "blocks": [{"task": "constant", "conditions": ["g"], "repeats": 2}]})
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "s01"
    >>> session = run(design, observer="sim:threshold=0.1", out=out, check=False)
    >>> with open(out / "trials.csv", newline="") as handle:
    ...     logged = list(csv.DictReader(handle))
    >>> session.complete, session.directory == out, [float(row["level"]) for row in logged] == [
    ...     row["level"] for row in session.trials]
    (True, True, True)
    """

    design: Design
    trials: list[dict]
    summary: dict
    check: CheckReport | None
    directory: Path | None = None
    complete: bool = True
    warnings: list[str] = field(default_factory=list)

    def table(self):
        """The trials as a pandas DataFrame (pandas installed), else the list of dicts (a DataFrame's records).

        Returns
        -------
        pandas.DataFrame or list of dict

        Examples
        --------
        >>> from ultraglide.experiment import design_from_dict, run
        >>> from ultraglide.experiment.analysis import records
        >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
        ...     "conditions": [{"name": "g", "stimulus": "g", "levels": [0.1, 0.3]}],
        ...     "blocks": [{"task": "constant", "conditions": ["g"], "repeats": 2}]})
        >>> session = run(design, observer="sim:threshold=0.1", check=False)
        >>> len(records(session.table())), sorted(records(session.table())[0])[:3]
        (4, ['block', 'break_before', 'commanded_um_pp'])
        """
        from ultraglide.experiment.analysis import as_frame

        return as_frame(self.trials)


class _Stimuli:
    """Zone textures of the design's stimuli: each stimulus's texture loaded and sampled over its zone once (its
    :class:`~ultraglide.experiment.check.ZoneSource`), at its own contrast built once, at a level (a varied
    stimulus) from the sampled zone with the arithmetic alone."""

    def __init__(self, design: Design, rig: Rig):
        self.design, self.rig = design, rig
        self._sources: dict = {}
        self._zones: dict = {}
        self._designs: dict = {}

    def zone_source(self, name: str) -> ZoneSource:
        if name not in self._sources:
            self._sources[name] = ZoneSource(self.design.stimuli[name], self.rig.zone_mm)
        return self._sources[name]

    def zone(self, name: str):
        if not name:
            return None
        if name not in self._zones:
            self._zones[name] = self.zone_source(name).texture()
        return self._zones[name]

    def stimulus_design(self, condition_name: str, intervals: int):
        """The condition's StimulusDesign (the threshold sessions' stimuli: the varied zone and the reference)."""
        key = (condition_name, intervals)
        if key not in self._designs:
            from ultraglide.experiment.stimuli import Layout, StimulusDesign

            condition = self.design.conditions[condition_name]
            stimulus = self.design.stimuli[condition.stimulus]
            zone_at = None
            if condition.vary == "wavelength" or stimulus_is_plain_library(stimulus):
                from ultraglide.textures.library import resolve_texture

                base = resolve_texture(stimulus.texture)  # as the threshold command loads it (a grating's authoring)
            elif condition.vary == "contrast":  # its zone at each level as the check renders it (its mean kept)
                zone_at = self.zone_source(condition.stimulus).texture
                base = zone_at(0.0)  # its name and size (no contrast fits any mean; the levels are checked)
            else:
                base = self.zone(condition.stimulus)
            reference = self.zone(condition.reference) if condition.reference else None
            layout = Layout(intervals, self.rig.zone_mm, self.rig.gap_mm)
            self._designs[key] = StimulusDesign(base, condition.vary, layout, reference, self.rig.model,
                                                self.rig.force_n, zone_at)
        return self._designs[key]


def stimulus_is_plain_library(stimulus) -> bool:
    """A stimulus with no transform: the texture exactly as ``experiment threshold TEXTURE`` would use it.

    Parameters
    ----------
    stimulus : Stimulus

    Returns
    -------
    bool

    Examples
    --------
    >>> from ultraglide.experiment import Stimulus
    >>> stimulus_is_plain_library(Stimulus("g", "grating-1mm")), stimulus_is_plain_library(
    ...     Stimulus("g", "grating-1mm", scale=2.0))
    (True, False)
    """
    return (stimulus.contrast is None and stimulus.mean is None and stimulus.scale == 1.0 and not stimulus.rotation_deg
            and stimulus.effects is None)


def _procedures(design: Design) -> dict:
    """A procedure for each adaptive (block, condition)."""
    made = {}
    for block in design.blocks:
        if block.task not in ADAPTIVE:
            continue
        guess = 1.0 / block.intervals
        for name in block.conditions:
            condition = design.conditions[name]
            low, high = condition.range
            if block.task == "quest":
                made[(block.name, name)] = QuestPlus(QuestParams.log_grid(low, high, function=block.function,
                                                                          guess=guess))
            else:
                start = condition.start_level if condition.start_level is not None else math.sqrt(low * high) * 4
                made[(block.name, name)] = Staircase(StaircaseParams(min(start, high), block.rule, min_level=low,
                                                                     max_level=high))
    return made


def now_utc() -> str:
    """The time now, ISO 8601 in UTC to the millisecond (trials.csv's ``time_utc``).

    Returns
    -------
    str

    Examples
    --------
    >>> import datetime
    >>> stamp = now_utc()
    >>> parsed = datetime.datetime.fromisoformat(stamp)
    >>> parsed.utcoffset(), len(stamp.split(".")[1])           # "+00:00" after three digits of milliseconds
    (datetime.timedelta(0), 9)
    """
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="milliseconds")


def versions() -> dict:
    """The versions a session ran with (written in session.json): ultraglide's, Python's, numpy's and scipy's.

    Returns
    -------
    dict

    Examples
    --------
    >>> import platform, numpy, scipy
    >>> found = versions()
    >>> found["python"] == platform.python_version(), found["numpy"] == numpy.__version__
    (True, True)
    >>> found["scipy"] == scipy.__version__
    True
    """
    import sys

    import scipy

    root = sys.modules.get("ultraglide")  # the package root, imported before any of its modules (not imported here:
    version = getattr(root, "__version__", None)  # it re-exports every layer)
    return {"ultraglide": version, "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__}


def run(design: Design, participant: str = "P01", session: str = "1", out=None, observer=None, responder=None,
        accept_check: bool = False, check: bool = True, resume: bool = False) -> Session:
    """Run ``design`` for one participant, with a simulated observer or a responder (a window, a remote interface).

    Parameters
    ----------
    design : Design
    participant, session : str
        Written in every row; the participant's number picks a counterbalanced block order.
    out : str or os.PathLike, optional
        A new directory for trials.csv, session.json and summary.json (None: nothing written).
    observer : str or SimObserver, optional
        A simulated observer (``"sim:threshold=0.1,slope=3"``); its threshold is in the varied level's units for
        adaptive and constant blocks, in delivered friction-contrast difference for A-vs-B and same-different.
    responder : Responder, optional
        The participant's interface (:mod:`ultraglide.experiment.responders`), instead of ``observer``.
    accept_check : bool
        Run a design whose stimuli fail the check, with the failures recorded as warnings.
    check : bool or CheckReport
        False skips the stimulus check (tests of the plan alone; never for a participant); a CheckReport of this
        design, already made, is used as it is.
    resume : bool
        Continue the stopped session in ``out`` (same design, participant and session): its logged trials are
        replayed into the procedures (each logged level must be the one asked for) and the plan goes on from the
        next trial; a half-written last row is dropped. A simulated observer answers as an uninterrupted session.

    Returns
    -------
    Session

    Raises
    ------
    StimulusCheckError
        A stimulus does not deliver what the design asks (one line naming it and the figure).
    ExperimentError
        An unusable design, observer or output directory.

    Examples
    --------
    >>> from ultraglide.experiment import design_from_dict, run
    >>> design = design_from_dict({"experiment": {"seed": 1},
    ...     "stimuli": {"g": {"texture": "grating-1mm"}},
    ...     "conditions": [{"name": "g", "stimulus": "g", "levels": [0.05, 0.4]}],
    ...     "blocks": [{"task": "constant", "conditions": ["g"], "repeats": 3}]})
    >>> session = run(design, observer="sim:threshold=0.1,slope=3")
    >>> len(session.trials), sorted({row["level"] for row in session.trials})
    (6, [0.05, 0.4])
    """
    rig = Rig(design)
    if responder is None and observer is None:
        raise ExperimentError("give a simulated observer (observer='sim:...') or a responder (a window)")
    warnings_: list[str] = []
    report = check if isinstance(check, CheckReport) else check_stimuli(design, rig) if check else None
    if report is not None and not report.passed:
        if not accept_check:
            refuse(report)
        warnings_ += [f"stimulus check accepted despite: {failure}" for failure in report.failures]
    if responder is None:
        from ultraglide.experiment.simulated import SimulatedParticipant

        responder = SimulatedParticipant(observer, rig, design.seed)
    stimuli = _Stimuli(design, rig)
    refuse_unfit(design, stimuli.zone_source)  # a level no trial could build: refused before any is presented
    directory = _prepare(out) if not resume else Path(out)
    procedures = _procedures(design)
    factors = sorted({key for c in design.conditions.values() for key in c.factors})
    columns = [*DESIGN_COLUMNS]
    at = columns.index("condition") + 1
    columns[at:at] = factors
    trials = plan(design, participant)
    rows: list[dict] = _resumed_rows(design, directory, participant, session, trials, procedures, columns) if resume \
        else []
    log = _Log(directory / TRIALS, columns, append=resume) if directory else None
    started = now_utc()
    if directory:
        _write_json(directory / SESSION, _metadata(design, participant, session, report, warnings_, started, "running",
                                                   len(rows)))
    complete = True
    blocks = {block.name: block for block in design.blocks}
    try:
        for trial in trials[len(rows):]:
            block = blocks[trial.block]
            if trial.break_before and not responder.take_break(trial.number, design.break_message):
                complete = False
                break
            procedure = procedures.get((block.name, trial.condition))
            level = trial.level
            if procedure is not None and not trial.practice:
                level = procedure.next_level()
            shown = _presentation(design, block, trial, level, stimuli, report)
            answer = responder.present(shown)
            if answer.quit:
                complete = False
                break
            row = _row(design, block, trial, level, answer, participant, session, factors, shown)
            if procedure is not None and not trial.practice:
                procedure.update(level, int(row["correct"]))
                row["reversal"] = int(getattr(procedure, "last_was_reversal", False))
            rows.append(row)
            if log:
                log.write(row)
    finally:
        if log:
            log.close()
    from ultraglide.experiment.analysis import summarise

    summary = summarise(design, rows, procedures)
    summary["complete"] = complete
    if directory:
        _write_json(directory / SUMMARY, summary)
        _write_json(directory / SESSION, _metadata(design, participant, session, report, warnings_, started,
                                                   "complete" if complete else "stopped", len(rows)))
    return Session(design, rows, summary, report, directory, complete, warnings_)


def _resumed_rows(design: Design, directory: Path, participant: str, session: str, trials: list[Trial],
                  procedures: dict, columns: list[str]) -> list[dict]:
    """The logged rows of the session in ``directory``, replayed into ``procedures``; ExperimentError if they are not
    this design's, participant's and session's."""
    from ultraglide.experiment.analysis import read_trials

    if directory is None:
        raise ExperimentError("resuming needs the session's directory (out)")
    saved_path = directory / SESSION
    try:
        saved = json.loads(saved_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ExperimentError(f"{saved_path}: no session to resume there ({error})") from None
    if not isinstance(saved, dict) or saved.get("design_toml") != to_toml(design) or (
            saved.get("participant"), saved.get("session")) != (participant, session):
        raise ExperimentError(f"{directory}: its session ran another design, participant or session; resume it with "
                              "the same ones")
    path = directory / TRIALS
    if os.path.lexists(path) and (path.is_symlink() or not path.is_file()):
        raise ExperimentError(f"{path}: is not a regular file; a session's trials are logged to one")
    data = path.read_bytes() if path.is_file() else b""
    if data and not data.endswith(b"\n"):  # a row cut short when the session stopped
        with open(path, "r+b") as handle:
            handle.truncate(data.rfind(b"\n") + 1)
    rows = read_trials(path) if data else []
    if rows and list(rows[0]) != columns:
        raise ExperimentError(f"{path}: its columns are not this design's")
    if len(rows) > len(trials):
        raise ExperimentError(f"{path}: more trials than the design plans")
    for row, trial in zip(rows, trials, strict=False):
        if (row["trial"], row["block"], row["condition"]) != (trial.number, trial.block, trial.condition):
            raise ExperimentError(f"{path}: trial {trial.number} of the log is not the plan's; it is another session")
        procedure = procedures.get((trial.block, trial.condition))
        if procedure is not None and not trial.practice:
            wanted = procedure.next_level()
            if not math.isclose(wanted, row["level"], rel_tol=1e-9):
                raise ExperimentError(f"{path}: trial {trial.number} was at level {row['level']:g} but the procedure "
                                      f"asks for {wanted:g}: the log was written by another design or seed")
            procedure.update(row["level"], int(row["correct"]))
    return rows


def _prepare(out) -> Path | None:
    if out is None:
        return None
    directory = Path(out)
    if directory.exists() and not directory.is_dir():
        raise ExperimentError(f"{directory}: is a file, not a directory")
    if (directory / TRIALS).exists() or os.path.lexists(directory / TRIALS):
        raise ExperimentError(f"{directory} already holds a session; choose another output directory")
    directory.mkdir(parents=True, exist_ok=True)
    return directory


def _presentation(design: Design, block: Block, trial: Trial, level, stimuli: _Stimuli,
                  report: CheckReport | None) -> Presentation:
    from ultraglide.experiment.stimuli import Layout
    from ultraglide.textures.compose import Placement, compose

    figures_of = report.figures if report else {}
    if block.task in ADAPTIVE + ("constant",):
        intervals = max(block.intervals, 1)
        stimulus_design = stimuli.stimulus_design(trial.condition, intervals)
        target = trial.target or 0
        layout = stimulus_design.layout
        reference_name = design.conditions[trial.condition].reference
        figures = tuple(None if z == target else figures_of.get(reference_name) for z in range(intervals))
        return Presentation(trial, level, block.shown_question, response_labels(block), block.intervals, layout,
                            lambda: stimulus_design.trial_texture(level, target), stimulus_design, figures)
    layout = Layout(len(trial.zones), stimuli.rig.zone_mm, stimuli.rig.gap_mm)

    def texture():
        placements = [Placement(stimuli.zone(name), layout.zone_left_mm(z), layout.gap_mm)
                      for z, name in enumerate(trial.zones) if name]
        px = max(10.0, max((1.0 / min(p.texture.pixel_mm) for p in placements), default=10.0))
        return compose(layout.size_mm, placements, 1.0, px_per_mm=min(px, 40.0), name=f"trial-{trial.number}")

    figures = tuple(figures_of.get(name) for name in trial.zones)
    intervals = block.intervals if block.task == "afc" else 1
    if block.task == "adjustment":
        condition = design.conditions[trial.condition]
        reference = stimuli.zone(condition.reference)
        adjusted_at = stimuli.zone_source(condition.stimulus).texture  # loaded and sampled once, for every level

        def texture_at(value: float):
            adjusted = adjusted_at(float(value))
            placements = [Placement(reference, layout.zone_left_mm(0), layout.gap_mm),
                          Placement(adjusted, layout.zone_left_mm(1), layout.gap_mm)]
            px = max(10.0, max(1.0 / min(p.texture.pixel_mm) for p in placements))
            return compose(layout.size_mm, placements, 1.0, px_per_mm=min(px, 40.0), name=f"trial-{trial.number}")

        return Presentation(trial, level, block.shown_question, response_labels(block), 1, layout,
                            lambda: texture_at(level), None, figures, texture_at=texture_at,
                            level_range=condition.range)
    return Presentation(trial, level, block.shown_question, response_labels(block), intervals, layout, texture, None,
                        figures, block.modulus if block.task == "magnitude" else None,
                        block.scale if block.task == "rating" else None)


def _number(value, digits: int = 4):
    return None if value is None or not math.isfinite(value) else round(float(value), digits)


def _row(design: Design, block: Block, trial: Trial, level, answer: Answer, participant: str, session: str,
         factors: list[str], shown: Presentation) -> dict:
    condition = design.conditions[trial.condition]
    labels = shown.labels
    correct = None
    if block.task in ADAPTIVE + ("afc",) or (block.task == "constant" and block.intervals > 1):
        response = int(answer.response) + 1
        correct = int(int(answer.response) == trial.target)
        label = labels[int(answer.response)] if labels else str(response)
        target = trial.target + 1
    elif block.task == "constant":  # yes/no
        response = "yes" if answer.response else "no"
        correct = int(bool(answer.response) == (level > 0))
        label, target = labels[0 if answer.response else 1], None
    elif block.task == "same_different":
        response = "different" if answer.response else "same"
        correct = int(int(answer.response) == trial.target)
        label, target = labels[1 if answer.response else 0], ("different" if trial.target else "same")
    elif block.task == "rating":
        response = int(answer.response)
        label, target = labels[response - block.scale[0]], None
    elif block.task == "adjustment":
        response = float(answer.response)
        label, target = f"{response:.4g}", None
    else:
        response = float(answer.response)
        label, target = f"{response:g}", None
    varied = shown.figures[trial.target or 0] if shown.stimulus_design is None else None
    first = varied or next((f for f in shown.figures if f is not None), None)
    delivered = (answer.rendered_contrast, None, answer.rendered_um_pp) if shown.stimulus_design is not None else (
        (first.delivered_contrast, first.delivered_mean, first.delivered_um_pp) if first else (None, None, None))
    friction = answer.friction or {}
    row = {"participant": participant, "session": session, "trial": trial.number, "block": block.name,
           "task": block.task, "practice": int(trial.practice), "condition": condition.name,
           **{key: condition.factors.get(key) for key in factors},
           "stimuli": " | ".join(name or "plain glass" for name in trial.zones),
           "level": None if level is None else float(level), "target": target, "response": response,
           "response_label": label, "correct": correct, "rt_s": _number(answer.rt_s), "reversal": 0,
           "break_before": int(trial.break_before), "delivered_contrast": _number(delivered[0]),
           "delivered_mean_ratio": _number(delivered[1]), "delivered_um_pp": _number(delivered[2]),
           "time_utc": now_utc(), "target_ratio": _number(friction.get("target_ratio")),
           "measured_ratio": _number(friction.get("measured_ratio")),
           "commanded_um_pp": _number(friction.get("commanded_um_pp")), "loop": friction.get("loop")}
    return row


class _Log:
    """trials.csv: a header, then a row per trial, flushed and fsync'd before the next trial."""

    def __init__(self, path: Path, columns: list[str], append: bool = False):
        flags = os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC | (os.O_APPEND if append else os.O_EXCL)
        descriptor = os.open(path, flags, 0o666)
        new = os.fstat(descriptor).st_size == 0
        self._file = open(descriptor, "a" if append else "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._writer = csv.DictWriter(self._file, fieldnames=columns, lineterminator="\n")
        if new:
            self._writer.writeheader()
        self._sync()

    def _sync(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())

    def write(self, row: dict) -> None:
        self._writer.writerow({key: _cell(row.get(key)) for key in self._writer.fieldnames})
        self._sync()

    def close(self) -> None:
        self._file.close()


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _write_json(path: Path, document: dict) -> None:
    from ultraglide.atomic import AtomicFile

    with AtomicFile(path) as target:
        Path(target.temporary).write_text(json.dumps(document, indent=2, allow_nan=False, default=str) + "\n",
                                          encoding="utf-8")


def _metadata(design: Design, participant: str, session: str, report: CheckReport | None, warnings_: list[str],
              started: str, status: str, trials: int = 0) -> dict:
    rig = Rig(design)
    calibration = None
    if design.model.endswith(".toml"):
        calibration = {"file": str(Path(design.model).resolve()),
                       "text": Path(design.model).read_text(encoding="utf-8", errors="replace")}
    return {"status": status, "started_utc": started, "updated_utc": now_utc(), "participant": participant,
            "session": session, "trials_logged": trials, "design": design.as_dict(), "design_toml": to_toml(design),
            "versions": versions(),
            "rig": {"profile": {"name": design.profile, "resonance_hz": rig.profile.resonance_hz, "q": rig.profile.q,
                                "max_amplitude_um_pp": rig.profile.max_amplitude_um_pp},
                    "model": {"spec": design.model, "description": rig.model.describe(),
                              "parameters": rig.model.parameters()},
                    "speed_mm_s": design.speed_mm_s, "force_n": design.force_n, "zone_mm": list(design.zone_mm),
                    "gap_mm": design.gap_mm},
            "calibration": calibration, "stimulus_check": report.as_dict() if report else None,
            "warnings": warnings_}
