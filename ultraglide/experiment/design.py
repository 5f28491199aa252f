"""An experiment's design: stimuli, conditions, blocks, order; from TOML or built in code; and its trial plan.

A design names its **stimuli** (a texture by library name or file, with transforms: friction contrast, mean
friction, scale, rotation), its **conditions** (named, with factors, each saying which stimuli it shows) and its
**blocks** (one task each: constant stimuli, staircases interleaved across conditions, QUEST+, fixed A-vs-B
n-AFC, same-different, rating scales, magnitude estimation with a modulus), with the question and response
labels in the participant's language, practice trials and breaks. :func:`load_design` reads one from TOML
(every value checked: :class:`~ultraglide.experiment.errors.ExperimentError`, one line naming the key);
:func:`plan` lays out its trials for a participant, as a function of the design's seed only.

Examples
--------
>>> from ultraglide.experiment import design_from_dict, plan
>>> design = design_from_dict({
...     "experiment": {"name": "two gratings", "seed": 3},
...     "stimuli": {"fine": {"texture": "grating-1mm", "contrast": 0.3},
...                 "coarse": {"texture": "grating-2mm", "contrast": 0.3}},
...     "conditions": [{"name": "fine-vs-coarse", "a": "fine", "b": "coarse"}],
...     "blocks": [{"name": "main", "task": "afc", "conditions": ["fine-vs-coarse"], "repeats": 4}]})
>>> [trial.target for trial in plan(design)]
[1, 0, 1, 0]
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field

import numpy as np

from ultraglide.experiment.errors import ExperimentError
from ultraglide.experiment.procedures import RULES, ConstantParams, ConstantStimuli, interval_positions
from ultraglide.render.physics.default_model import EXPERIMENT_MODEL

TASKS = ("constant", "staircase", "quest", "afc", "same_different", "rating", "magnitude", "adjustment")
ADAPTIVE = ("staircase", "quest")
ORDERS = ("random", "blocked", "counterbalanced")
VARY = ("contrast", "wavelength", "amplitude")
DEFAULT_RANGES = {"contrast": (0.005, 0.6), "wavelength": (0.01, 2.0), "amplitude": (0.05, 6.0)}
DEFAULT_QUESTIONS = {
    "constant": "Which zone felt different?", "staircase": "Which zone felt different?",
    "quest": "Which zone felt different?", "afc": "Which zone felt different?",
    "same_different": "Did the two zones feel the same or different?",
    "rating": "How rough did it feel?", "magnitude": "How intense was it, against the first zone's number?",
    "adjustment": "Make the second zone feel like the first, then press OK."}
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
MAX_TRIALS = 100_000
LANGUAGE = re.compile(r"^[A-Za-z]{2,3}(-[A-Za-z0-9]{2,8}){0,4}$")  # a BCP 47 tag's shape: the page's lang
# the words a participant reads that are not a block's question or labels: ``[words]`` in the design, English by
# default; each with the placeholders it may use ({trial} of {total}, the last key {last}, the {modulus})
WORDS = {
    "progress": "Trial {trial} of {total}",
    "keys_choice": "Keys: 1–{last} (or ← / →) answer.",
    "keys_yes_no": "Keys: Y for yes, N for no.",
    "keys_pair": "Keys: S for same, D for different.",
    "keys_rating": "Keys: 1–{last} for the scale's points, from its low end.",
    "keys_magnitude": "Keys: type the number, Enter gives it.",
    "keys_adjustment": "Keys: ← or − down, → or + up (1 dB a step), Enter gives it.",
    "keys_break": "Space or Enter goes on.",
    "keys_stop": "Esc stops the session.",
    "ok": "OK",
    "modulus": "(zone 1 = {modulus})",
    "end": "The session is over. Thank you.",
    "connection_lost": "Connection lost; trying again.",
}
WORD_FIELDS = {"progress": ("trial", "total"), "keys_choice": ("last",), "keys_rating": ("last",),
               "modulus": ("modulus",)}


@dataclass(frozen=True)
class Stimulus:
    """A texture and its transforms. ``texture``: a library name or a texture/image file. ``contrast``: the
    friction contrast (1 - ratio at its most slippery point, the stickiest at 1) it is rescaled to (None: as it
    is); ``mean``: the mean friction ratio it is shifted to (None: as it is); ``scale``: its size × this;
    ``rotation_deg``: turned anticlockwise by this; ``effects``: a file of temporal effects played on the zone
    (ours, JSON, or a designer's ``.ahap``, ``.haptic``, ``.hjif``; positions in mm from the zone's top-left corner,
    an effect without a region plays over the whole zone).

    Parameters
    ----------
    name : str
        The stimulus's name in the design.
    texture : str
        A library name or a file.
    contrast : float, optional
        Friction contrast, 0..1.
    mean : float, optional
        Mean friction ratio, 0..1.
    scale : float
        Size factor (0.05..20).
    rotation_deg : float
        Degrees, anticlockwise.
    effects : str, optional
        A file of temporal effects.

    Examples
    --------
    >>> from ultraglide.experiment.check import zone_texture
    >>> fine = Stimulus("fine", "grating-1mm", contrast=0.3)
    >>> zone = zone_texture(fine, (20.0, 10.0))                  # a 20 × 10 mm zone of it
    >>> round(float(zone.values.max()), 6), round(float(zone.values.min()), 6)     # spans 1 - 0.3 .. 1
    (1.0, 0.7)
    """

    name: str
    texture: str
    contrast: float | None = None
    mean: float | None = None
    scale: float = 1.0
    rotation_deg: float = 0.0
    effects: str | None = None


@dataclass(frozen=True)
class Condition:
    """A named condition. ``factors``: its level of each factor (a column each in trials.csv). ``stimulus``: the
    stimulus varied (staircases, QUEST+, constant stimuli), rated or estimated, or A of an A-vs-B task;
    ``reference``: what the other zones show (None: plain glass), or B. ``vary``: what the level is (contrast,
    wavelength in mm, amplitude in µm p-p); ``levels``: constant stimuli's; ``level_range``: an adaptive
    procedure's (default by ``vary``); ``start_level``: a staircase's first.

    Parameters
    ----------
    name, stimulus : str
    reference : str, optional
    factors : dict
    vary : {"contrast", "wavelength", "amplitude"}
    levels : tuple of float
        In the unit of ``vary``.
    level_range : (float, float), optional
        In the unit of ``vary``.
    start_level : float, optional
        In the unit of ``vary``.

    Examples
    --------
    >>> Condition("fine", "fine", factors={"spacing_mm": 1.0}, levels=(0.05, 0.1)).levels
    (0.05, 0.1)
    """

    name: str
    stimulus: str
    reference: str | None = None
    factors: dict = field(default_factory=dict)
    vary: str = "contrast"
    levels: tuple[float, ...] = ()
    level_range: tuple[float, float] | None = None
    start_level: float | None = None

    @property
    def range(self) -> tuple[float, float]:
        """The levels an adaptive procedure may present, (low, high) in the unit of ``vary``: ``level_range``, else the
        default for what varies.

        Examples
        --------
        >>> Condition("c", "s").range, Condition("c", "s", vary="amplitude").range
        ((0.005, 0.6), (0.05, 6.0))
        >>> Condition("c", "s", level_range=(0.01, 0.2)).range
        (0.01, 0.2)
        """
        return tuple(self.level_range) if self.level_range else DEFAULT_RANGES[self.vary]


@dataclass(frozen=True)
class Block:
    """One task over some conditions. ``trials``: per condition (staircase, QUEST+); ``repeats``: presentations
    of each level (constant) or of each condition (afc, same_different: of each pair order; rating, magnitude).
    ``intervals``: zones in forced choice (1: yes/no for constant stimuli). ``question``/``labels``: in the
    participant's language (labels: one per answer button; a rating's from its low end). ``scale``: a rating's
    (low, high) whole numbers; ``modulus``: magnitude estimation's number for ``modulus_stimulus`` (shown first in
    every trial). ``adjustment``: the participant sets the condition's stimulus's contrast (from a random start in
    its range, 1 dB a step) until it feels like the reference (shown first). ``practice``: trials before the
    block's own, not analysed; ``break_every``: a pause every N.

    Parameters
    ----------
    name, task : str
        The block's name; its task, one of ``constant``, ``staircase``, ``quest``, ``afc``, ``same_different``,
        ``rating``, ``magnitude``, ``adjustment``.
    conditions : tuple of str
    trials, repeats, intervals : int
    rule : {"1u2d", "1u3d", "weighted"}
    function : {"weibull", "logistic"}
    question : str
    labels : tuple of str
    scale : (int, int)
    modulus : float
    modulus_stimulus : str, optional
    practice, break_every : int

    Examples
    --------
    >>> block = Block("rate", "rating", ("fine",), repeats=3, scale=(1, 5))
    >>> block.shown_question, response_labels(block)
    ('How rough did it feel?', ('1', '2', '3', '4', '5'))
    """

    name: str
    task: str
    conditions: tuple[str, ...]
    trials: int = 40
    repeats: int = 10
    intervals: int = 2
    rule: str = "1u2d"
    function: str = "weibull"
    question: str = ""
    labels: tuple[str, ...] = ()
    scale: tuple[int, int] = (1, 7)
    modulus: float = 10.0
    modulus_stimulus: str | None = None
    practice: int = 0
    break_every: int = 0

    @property
    def shown_question(self) -> str:
        """The question the participant reads: the block's own, else the task's default (in English).

        Examples
        --------
        >>> Block("m", "afc", ("c",)).shown_question, Block("m", "afc", ("c",), question="Welche?").shown_question
        ('Which zone felt different?', 'Welche?')
        """
        return self.question or DEFAULT_QUESTIONS[self.task]

    @property
    def zones(self) -> int:
        """The zones a trial of this block shows: 2 for same-different, magnitude and adjustment (a reference first), 1
        for a rating, else ``intervals``.

        Examples
        --------
        >>> [Block("b", task, ("c",), intervals=3).zones for task in ("afc", "same_different", "rating")]
        [3, 2, 1]
        """
        if self.task in ("same_different", "magnitude", "adjustment"):
            return 2
        if self.task == "rating":
            return 1
        return self.intervals


@dataclass(frozen=True)
class Design:
    """A whole experiment (see the module docstring). ``order``: within each block, ``random`` interleaves its
    conditions' trials, ``blocked`` runs them one condition after another; ``counterbalanced`` also interleaves
    them and orders the blocks by a balanced Latin square row chosen by the participant's number (the digits in
    the ID). Sizes in mm, speed in mm/s, force in N: the swipe participants (and the stimulus check) use.

    Parameters
    ----------
    name : str
    stimuli : dict of str to Stimulus
    conditions : dict of str to Condition
    blocks : tuple of Block
    seed : int
        Every random order of the plan comes from it.
    order : {"random", "blocked", "counterbalanced"}
    language, break_message : str
    zone_mm : (float, float)
        A zone's width and height, mm.
    gap_mm : float
        Plain glass around each zone, mm.
    speed_mm_s : float
        The swipe's speed, mm/s.
    force_n : float
        The finger's force, N.
    model, profile : str
        The friction model and the plate profile, by name or file.
    check_paths : tuple of str
        Touch logs the stimulus check also renders along.

    Raises
    ------
    ExperimentError
        Whatever :func:`validate` refuses.

    Examples
    --------
    >>> design = Design("one", {"g": Stimulus("g", "grating-1mm")}, {"g": Condition("g", "g", levels=(0.1, 0.2))},
    ...                 (Block("main", "constant", ("g",), repeats=3),))
    >>> len(plan(design))                                  # 2 levels × 3 repeats
    6
    >>> Design("none", {}, {}, ())
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: blocks: a design needs at least one block
    """

    name: str
    stimuli: dict[str, Stimulus]
    conditions: dict[str, Condition]
    blocks: tuple[Block, ...]
    seed: int = 0
    order: str = "random"
    language: str = "en"
    break_message: str = "Take a break. Tap or press space to go on."
    zone_mm: tuple[float, float] = (40.0, 40.0)
    gap_mm: float = 10.0
    speed_mm_s: float = 100.0
    force_n: float = 0.5
    model: str = EXPERIMENT_MODEL
    profile: str = "sim-plate"
    check_paths: tuple[str, ...] = ()  # touch logs (mm from a zone's top-left corner) the check also renders along
    words: dict = field(default_factory=dict)  # the participant's words the design sets (WORDS' keys), else English

    def __post_init__(self) -> None:
        validate(self)

    def as_dict(self) -> dict:
        """The design as the TOML's tables (what :func:`design_from_dict` takes back).

        Returns
        -------
        dict
            ``experiment``, ``rig``, ``stimuli``, ``conditions`` and ``blocks``.

        Examples
        --------
        >>> design = Design("one", {"g": Stimulus("g", "grating-1mm")}, {"g": Condition("g", "g")},
        ...                 (Block("main", "rating", ("g",)),), seed=5)
        >>> design_from_dict(design.as_dict()) == design
        True
        """
        return design_to_dict(self)

    def word(self, key: str, **fields) -> str:
        """The participant's words for ``key``: the design's ``[words]``, else English, placeholders filled.

        Parameters
        ----------
        key : str
            One of :data:`WORDS`.
        **fields
            The placeholders' values (``trial``, ``total``, ``last``, ``modulus``); those the words do not use are
            left aside.

        Returns
        -------
        str

        Examples
        --------
        >>> from ultraglide.experiment import design_from_dict
        >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
        ...     "conditions": [{"name": "c", "stimulus": "g"}], "blocks": [{"task": "rating", "conditions": ["c"]}],
        ...     "words": {"progress": "Essai {trial} sur {total}"}})
        >>> design.word("progress", trial=2, total=9), design.word("keys_pair")
        ('Essai 2 sur 9', 'Keys: S for same, D for different.')
        """
        return self.words.get(key, WORDS[key]).format(**fields)


@dataclass(frozen=True)
class Trial:
    """One planned trial. ``number`` from 1; ``target``: the odd interval (0-based) in forced choice, 1/0 for a
    different/same pair; ``level``: the level (constant stimuli), or None where a procedure chooses it as the
    session goes (staircase, QUEST+) or none is varied; ``zones``: the stimulus name in each zone ("" for
    plain glass, the varied stimulus's name for the varied zone).

    Parameters
    ----------
    number : int
    block, task, condition : str
    practice : bool
    target : int or None
    level : float or None
        In the condition's unit.
    zones : tuple of str
    break_before : bool
        A pause comes before it.

    Examples
    --------
    >>> design = Design("one", {"g": Stimulus("g", "grating-1mm")}, {"g": Condition("g", "g", levels=(0.1,))},
    ...                 (Block("main", "constant", ("g",), repeats=1, intervals=2),))
    >>> trial = plan(design)[0]
    >>> trial.level, trial.zones[trial.target], trial.zones[1 - trial.target]       # plain glass elsewhere
    (0.1, 'g', '')
    """

    number: int
    block: str
    task: str
    condition: str
    practice: bool
    target: int | None
    level: float | None
    zones: tuple[str, ...]
    break_before: bool = False

    def as_dict(self) -> dict:
        """The trial as plain data (JSON-ready).

        Returns
        -------
        dict
            ``trial`` (its number), ``block``, ``task``, ``condition``, ``practice``, ``target``, ``level``, ``zones``
            (a list), ``break_before``.

        Examples
        --------
        >>> Trial(1, "main", "rating", "g", False, None, None, ("g",)).as_dict()["zones"]
        ['g']
        """
        return {"trial": self.number, "block": self.block, "task": self.task, "condition": self.condition,
                "practice": self.practice, "target": self.target, "level": self.level, "zones": list(self.zones),
                "break_before": self.break_before}


# ---- validation ------------------------------------------------------------------------------------------------


def _refuse(where: str, what: str) -> ExperimentError:
    return ExperimentError(f"{where}: {what}")


def validate(design: Design) -> None:
    """Refuse what cannot run: unknown names, tasks without what they need, counts out of range.

    Parameters
    ----------
    design : Design

    Raises
    ------
    ExperimentError
        One line naming the key (``blocks[0].task``, ``conditions.NAME.range`` ...) and what it must be.

    Examples
    --------
    A design is validated as it is made:

    >>> Design("x", {"g": Stimulus("g", "grating-1mm")}, {"g": Condition("g", "g")}, (Block("b", "afc", ("g",)),))
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: conditions.g: block 'b' (afc) compares two stimuli: give the ...
    """
    if not design.blocks:
        raise _refuse("blocks", "a design needs at least one block")
    if design.order not in ORDERS:
        raise _refuse("experiment.order", f"must be one of {', '.join(ORDERS)}, got {design.order!r}")
    if not LANGUAGE.match(design.language):
        raise _refuse("experiment.language", f"must be a language tag such as en, fr or pt-BR, got "
                      f"{design.language[:40]!r}")
    for key, text in design.words.items():
        _check_word(key, text)
    for name, stimulus in design.stimuli.items():
        where = f"stimuli.{name}"
        if stimulus.contrast is not None and not 0 <= stimulus.contrast <= 1:
            raise _refuse(where + ".contrast", f"a friction contrast lies in 0..1, got {stimulus.contrast:g}")
        if stimulus.mean is not None and not 0 < stimulus.mean <= 1:
            raise _refuse(where + ".mean", f"a mean friction ratio lies in 0..1, got {stimulus.mean:g}")
        if not 0.05 <= stimulus.scale <= 20:
            raise _refuse(where + ".scale", f"must lie in 0.05..20, got {stimulus.scale:g}")
    for name, condition in design.conditions.items():
        where = f"conditions.{name}"
        for role in ("stimulus", "reference"):
            wanted = getattr(condition, role)
            if wanted is not None and wanted not in design.stimuli:
                raise _refuse(f"{where}.{role}", f"no stimulus named {wanted!r}; the design's stimuli: "
                              f"{', '.join(design.stimuli) or 'none'}")
        if condition.vary not in VARY:
            raise _refuse(where + ".vary", f"must be one of {', '.join(VARY)}, got {condition.vary!r}")
        low, high = condition.range
        if not 0 < low < high:
            raise _refuse(where + ".range", f"needs 0 < LOW < HIGH, got {low:g} {high:g}")
        if condition.vary == "contrast" and high > 1:
            raise _refuse(where + ".range", "a friction contrast is at most 1")
        if condition.start_level is not None and not low <= condition.start_level <= high:
            raise _refuse(where + ".start_level", f"{condition.start_level:g} lies outside the range {low:g}..{high:g}")
    names = set()
    for index, block in enumerate(design.blocks):
        where = f"blocks[{index}]"
        if block.name in names:
            raise _refuse(where + ".name", f"{block.name!r} names two blocks")
        names.add(block.name)
        if block.task not in TASKS:
            raise _refuse(where + ".task", f"must be one of {', '.join(TASKS)}, got {block.task!r}")
        if not block.conditions:
            raise _refuse(where + ".conditions", "a block needs at least one condition")
        for name in block.conditions:
            if name not in design.conditions:
                raise _refuse(where + ".conditions", f"no condition named {name!r}")
            condition = design.conditions[name]
            if block.task in ("afc", "same_different", "adjustment") and condition.reference is None:
                raise _refuse(f"conditions.{name}", f"block {block.name!r} ({block.task}) compares two stimuli: "
                              "give the condition both a and b")
            if block.task == "adjustment" and condition.vary != "contrast":
                raise _refuse(f"conditions.{name}.vary", f"block {block.name!r} (adjustment) adjusts a friction "
                              "contrast")
            if block.task == "constant" and not condition.levels:
                raise _refuse(f"conditions.{name}.levels", f"block {block.name!r} (constant stimuli) needs the "
                              "condition's levels")
            if block.task in ADAPTIVE + ("constant",) and condition.vary == "contrast" and any(
                    level > 1 for level in condition.levels):
                raise _refuse(f"conditions.{name}.levels", "a friction contrast is at most 1")
        allowed_intervals = (1, 2, 3) if block.task == "constant" else (2, 3, 4)
        if block.task in ADAPTIVE + ("constant", "afc") and block.intervals not in allowed_intervals:
            raise _refuse(where + ".intervals", f"must be one of {', '.join(map(str, allowed_intervals))} for "
                          f"{block.task}, got {block.intervals}")
        if block.rule not in (*RULES, "weighted"):
            raise _refuse(where + ".rule", f"must be 1u2d, 1u3d or weighted, got {block.rule!r}")
        if block.function not in ("weibull", "logistic"):
            raise _refuse(where + ".function", f"must be weibull or logistic, got {block.function!r}")
        for key, value, low in (("trials", block.trials, 1), ("repeats", block.repeats, 1),
                                ("practice", block.practice, 0), ("break_every", block.break_every, 0)):
            if not low <= value <= MAX_TRIALS:
                raise _refuse(f"{where}.{key}", f"must be a whole number from {low} to {MAX_TRIALS}, got {value}")
        if block.task == "rating":
            low, high = block.scale
            if not (isinstance(low, int) and isinstance(high, int) and low < high and high - low <= 100):
                raise _refuse(where + ".scale", f"needs whole numbers LOW < HIGH (at most 101 points), got {low} "
                              f"{high}")
        if block.task == "magnitude":
            if block.modulus_stimulus is None or block.modulus_stimulus not in design.stimuli:
                raise _refuse(where + ".modulus_stimulus", "magnitude estimation needs the stimulus that carries "
                              "the modulus: one of the design's stimuli")
            if not block.modulus > 0:
                raise _refuse(where + ".modulus", f"must be positive, got {block.modulus:g}")
        wanted_labels = _label_count(block)
        if block.labels and wanted_labels and len(block.labels) != wanted_labels:
            raise _refuse(where + ".labels", f"{block.task} with these settings takes {wanted_labels} labels "
                          f"(one per answer), got {len(block.labels)}")
    total = sum(block_trial_count(design, block) for block in design.blocks)
    if total > MAX_TRIALS:
        raise _refuse("blocks", f"the design has {total} trials; at most {MAX_TRIALS}")


def _check_word(key, text) -> None:
    """A ``[words]`` entry: a known key, printable text, only the placeholders its key takes."""
    import string

    where = f"words.{str(key)[:40]}"
    if key not in WORDS:
        raise _refuse(where, f"no such words; a design's [words] are {', '.join(WORDS)}")
    if not isinstance(text, str) or not text.isprintable() or len(text) > 1000:
        raise _refuse(where, f"must be printable text (at most 1000 characters), got {str(text)[:40]!r}")
    takes = WORD_FIELDS.get(key, ())
    said = f"it takes {', '.join('{' + f + '}' for f in takes)}" if takes else "it takes none"
    try:
        fields = [(name, spec, conversion) for _, name, spec, conversion in string.Formatter().parse(text)
                  if name is not None]
    except ValueError:
        raise _refuse(where, f"a brace without its pair in {text[:40]!r}; write a brace itself as {{{{ or }}}}") \
            from None
    for name, spec, conversion in fields:
        if name not in takes or spec or conversion:
            raise _refuse(where, f"{{{name}{'!' + conversion if conversion else ''}{':' + spec if spec else ''}}} "
                          f"is not a placeholder it takes; {said} (a brace itself is {{{{ or }}}})")


def _label_count(block: Block) -> int | None:
    if block.task == "rating":
        return block.scale[1] - block.scale[0] + 1
    if block.task == "same_different" or (block.task == "constant" and block.intervals == 1):
        return 2
    if block.task == "magnitude":
        return None
    if block.task == "adjustment":
        return 3
    return block.intervals


def response_labels(block: Block) -> tuple[str, ...]:
    """The answer buttons' labels: the block's own, else numbers, Yes/No or Same/Different.

    Parameters
    ----------
    block : Block

    Returns
    -------
    tuple of str

    Examples
    --------
    >>> response_labels(Block("b", "afc", ("c",), intervals=3)), response_labels(Block("b", "same_different", ("c",)))
    (('1', '2', '3'), ('Same', 'Different'))
    """
    if block.labels:
        return tuple(block.labels)
    if block.task == "rating":
        return tuple(str(v) for v in range(block.scale[0], block.scale[1] + 1))
    if block.task == "same_different":
        return ("Same", "Different")
    if block.task == "constant" and block.intervals == 1:
        return ("Yes", "No")
    if block.task == "magnitude":
        return ()
    if block.task == "adjustment":
        return ("−", "+", "OK")
    return tuple(str(i + 1) for i in range(block.intervals))


def block_trial_count(design: Design, block: Block) -> int:
    """Trials of ``block`` (its practice included).

    Parameters
    ----------
    design : Design
    block : Block

    Returns
    -------
    int

    Examples
    --------
    Same-different shows each of the four pair orders (AA, BB, AB, BA) ``repeats`` times:

    >>> design = Design("sd", {"a": Stimulus("a", "grating-1mm"), "b": Stimulus("b", "grating-2mm")},
    ...                 {"ab": Condition("ab", "a", "b")},
    ...                 (Block("m", "same_different", ("ab",), repeats=5, practice=2),))
    >>> block_trial_count(design, design.blocks[0]), 4 * 5 + 2
    (22, 22)
    """
    n = len(block.conditions)
    if block.task in ADAPTIVE:
        own = block.trials * n
    elif block.task == "constant":
        own = sum(len(design.conditions[c].levels) for c in block.conditions) * block.repeats
    elif block.task == "same_different":
        own = 4 * block.repeats * n  # AA, BB, AB, BA
    else:
        own = block.repeats * n
    return own + block.practice


# ---- the trial plan --------------------------------------------------------------------------------------------


def participant_number(participant: str) -> int:
    """The number in a participant's code (``P07`` -> 7; 0 if it has none): it picks the counterbalanced order.

    Parameters
    ----------
    participant : str

    Returns
    -------
    int
        The last run of digits in the code.

    Examples
    --------
    >>> participant_number("P07"), participant_number("lab2-s14"), participant_number("anonymous")
    (7, 14, 0)
    """
    digits = re.findall(r"\d+", participant)
    return int(digits[-1]) if digits else 0


def latin_square_row(n: int, row: int) -> list[int]:
    """Row ``row`` (mod n) of a balanced Latin square of n items (Williams 1949; for odd n, rows n..2n-1 are the
    mirror images): every item comes first, and follows every other, equally often over the rows.

    Parameters
    ----------
    n : int
        The items (blocks).
    row : int
        Any whole number (taken mod n, or mod 2n for odd n).

    Returns
    -------
    list of int
        A permutation of 0..n-1.

    Examples
    --------
    Over the four rows of n = 4 each item comes first once and each ordered pair of neighbours appears once
    (4 × 3 = 12 pairs):

    >>> rows = [latin_square_row(4, r) for r in range(4)]
    >>> rows[0], sorted(row[0] for row in rows), len({(row[i], row[i + 1]) for row in rows for i in range(3)})
    ([0, 3, 1, 2], [0, 1, 2, 3], 12)
    """
    base, low, high = [], 0, n - 1
    for index in range(n):  # 0, 1, n-1, 2, n-2, ...
        if index % 2 == 0:
            base.append(low)
            low += 1
        else:
            base.append(high)
            high -= 1
    rows = 2 * n if n % 2 else n
    r = row % max(rows, 1)
    shifted = [(b + r) % n for b in base]
    return shifted[::-1] if r >= n else shifted


def block_order(design: Design, participant: str = "P01") -> list[int]:
    """The blocks' indices in the order a participant meets them.

    Parameters
    ----------
    design : Design
    participant : str
        Its number picks the Latin square's row when the order is counterbalanced.

    Returns
    -------
    list of int

    Examples
    --------
    >>> g = {"g": Stimulus("g", "grating-1mm")}, {"g": Condition("g", "g")}
    >>> blocks = tuple(Block(f"b{k}", "rating", ("g",)) for k in range(3))
    >>> block_order(Design("d", *g, blocks)), block_order(Design("d", *g, blocks, order="counterbalanced"), "P01")
    ([0, 1, 2], [1, 0, 2])
    """
    if design.order == "counterbalanced":
        return latin_square_row(len(design.blocks), participant_number(participant))
    return list(range(len(design.blocks)))


def _condition_seed(design: Design, block_index: int, condition_index: int) -> int:
    """Each condition of each block draws its orders from a seed of its own (block 0's first: the design's)."""
    return design.seed + 1000 * block_index + condition_index


def plan(design: Design, participant: str = "P01") -> list[Trial]:
    """The trials ``participant`` meets, in order: a function of the design (its seed) and the participant's
    number (counterbalanced block order) only.

    Parameters
    ----------
    design : Design
    participant : str
        The participant's code; its number picks the block order when ``design.order`` is "counterbalanced".

    Returns
    -------
    list of Trial
        Adaptive blocks' trials carry ``level=None``: the procedure chooses it as the session goes.

    Examples
    --------
    >>> design = Design("d", {"g": Stimulus("g", "grating-1mm")}, {"g": Condition("g", "g")},
    ...                 (Block("main", "staircase", ("g",), trials=4, practice=1, break_every=2),))
    >>> [(t.number, t.practice, t.level is None, t.break_before) for t in plan(design)]
    [(1, True, False, False), (2, False, True, False), (3, False, True, True), (4, False, True, False),
     (5, False, True, True)]
    """
    trials: list[Trial] = []
    for block_index in block_order(design, participant):
        block = design.blocks[block_index]
        slots = _block_slots(design, block, block_index)
        practice = _practice_slots(design, block, block_index, slots)
        for count, (condition, target, level, zones, is_practice) in enumerate(practice + slots):
            number = len(trials) + 1
            pause = bool(block.break_every and count and count % block.break_every == 0) or (
                count == 0 and bool(trials))
            trials.append(Trial(number, block.name, block.task, condition, is_practice, target, level, tuple(zones),
                                pause))
    return trials


def _interleave(design: Design, block: Block, block_index: int, per_condition: list[list]) -> list:
    """The conditions' trials in the block's order: interleaved at random (seeded) or one condition after another."""
    if design.order == "blocked" or len(per_condition) == 1:
        return [slot for slots in per_condition for slot in slots]
    owners = np.concatenate([np.full(len(s), i) for i, s in enumerate(per_condition)])
    np.random.default_rng([design.seed, block_index, 13]).shuffle(owners)
    iterators = [iter(s) for s in per_condition]
    return [next(iterators[i]) for i in owners]


def _block_slots(design: Design, block: Block, block_index: int) -> list[tuple]:
    """(condition, target, level, zones, practice) of each of the block's own trials, in order."""
    per_condition = []
    for condition_index, name in enumerate(block.conditions):
        condition = design.conditions[name]
        seed = _condition_seed(design, block_index, condition_index)
        a, b = condition.stimulus, condition.reference or ""
        if block.task in ADAPTIVE + ("constant",):
            if block.task == "constant":
                levels = ConstantStimuli(ConstantParams(tuple(condition.levels), block.repeats, seed)).schedule
            else:
                levels = [None] * block.trials
            positions = interval_positions(seed, len(levels), max(block.intervals, 1))
            slots = []
            for level, position in zip(levels, positions, strict=True):
                target = position if block.intervals > 1 else None
                zones = [a if z == (target or 0) else b for z in range(max(block.intervals, 1))]
                slots.append((name, target, level, zones, False))
        elif block.task == "afc":
            positions = interval_positions(seed, block.repeats, block.intervals)
            slots = [(name, p, None, [a if z == p else b for z in range(block.intervals)], False) for p in positions]
        elif block.task == "same_different":
            pairs = [(a, a, 0), (b, b, 0), (a, b, 1), (b, a, 1)] * block.repeats
            order = np.random.default_rng([seed, 17]).permutation(len(pairs))
            slots = [(name, pairs[i][2], None, [pairs[i][0], pairs[i][1]], False) for i in order]
        elif block.task == "rating":
            slots = [(name, None, None, [a], False)] * block.repeats
        elif block.task == "adjustment":  # the reference first, the adjusted stimulus from a random start level
            low, high = condition.range
            starts = np.exp(np.random.default_rng([seed, 23]).uniform(np.log(low), np.log(high), block.repeats))
            slots = [(name, None, float(start), [b, a], False) for start in starts]
        else:  # magnitude: the modulus's stimulus first, then the condition's
            slots = [(name, None, None, [block.modulus_stimulus, a], False)] * block.repeats
        per_condition.append(slots)
    return _interleave(design, block, block_index, per_condition)


def _practice_slots(design: Design, block: Block, block_index: int, slots: list[tuple]) -> list[tuple]:
    """``block.practice`` trials drawn from the block's own (adaptive: at the top of the condition's range, the
    easiest level), marked as practice."""
    if not block.practice:
        return []
    rng = np.random.default_rng([design.seed, block_index, 19])
    picks = rng.integers(0, len(slots), block.practice)
    practice = []
    for pick in picks:
        condition, target, level, zones, _ = slots[int(pick)]
        if block.task in ADAPTIVE:
            level = design.conditions[condition].range[1]
        practice.append((condition, target, level, zones, True))
    return practice


# ---- TOML ------------------------------------------------------------------------------------------------------

MAX_DESIGN_BYTES = 1 << 20


def load_design(path) -> Design:
    r"""A design from a TOML file (see docs/experiments.md for its tables).

    Parameters
    ----------
    path : str or os.PathLike
        The DESIGN.toml.

    Returns
    -------
    Design

    Raises
    ------
    ExperimentError
        One line naming the file and the key: unreadable, not TOML, or a value the design cannot take.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "design.toml"
    >>> _ = path.write_text('[stimuli.g]\ntexture = "grating-1mm"\n[[conditions]]\nname = "g"\nstimulus = "g"\n'
    ...                     '[[blocks]]\ntask = "rating"\nconditions = ["g"]\nrepeats = 3\n', encoding="utf-8")
    >>> design = load_design(path)
    >>> design.blocks[0].name, design.blocks[0].repeats, design.stimuli["g"].texture
    ('block1', 3, 'grating-1mm')
    """
    from ultraglide.inputs import decode_text, read_input

    text = decode_text(read_input(path, "design", ExperimentError, max_bytes=MAX_DESIGN_BYTES), str(path), "design",
                       ExperimentError)
    return design_from_toml(text, str(path))


def design_from_toml(text: str, where: str = "design") -> Design:
    r""":func:`design_from_dict` of TOML text; ExperimentError naming ``where`` for anything wrong.

    Parameters
    ----------
    text : str
        The TOML.
    where : str
        What the errors name (the file).

    Returns
    -------
    Design

    Raises
    ------
    ExperimentError
        Not TOML, or a table or value :func:`design_from_dict` refuses.

    Examples
    --------
    >>> design_from_toml('[stimuli.g]\ntexture = "grating-1mm"\nsize = 2\n', "my.toml")
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: my.toml: stimuli.g: unknown key 'size'
    """
    try:
        tables = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ExperimentError(f"{where}: not TOML ({error})") from None
    try:
        return design_from_dict(tables)
    except ExperimentError as error:
        raise ExperimentError(f"{where}: {error}") from None


class _Table:
    """Typed access to one TOML table: each key read once, its type checked; unknown keys refused."""

    def __init__(self, data, where: str):
        if not isinstance(data, dict):
            raise _refuse(where, "must be a table")
        self.data, self.where, self.read = data, where, set()

    def get(self, key: str, kind, default=None, required: bool = False):
        self.read.add(key)
        if key not in self.data:
            if required:
                raise _refuse(self.where, f"needs {key}")
            return default
        value = self.data[key]
        where = f"{self.where}.{key}" if self.where else key
        if kind in (dict, list):
            if not isinstance(value, kind):
                raise _refuse(where, "must be a table" if kind is dict else "must be an array of tables ([[...]])")
            return value
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise _refuse(where, f"must be a number, got {str(value)[:40]!r}")
            return float(value)
        if kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise _refuse(where, f"must be a whole number, got {str(value)[:40]!r}")
            return value
        if kind is str:
            if not isinstance(value, str) or not value.isprintable() or len(value) > 1000:
                raise _refuse(where, f"must be printable text, got {str(value)[:40]!r}")
            return value
        if kind == "name":
            if not isinstance(value, str) or not NAME.match(value):
                raise _refuse(where, f"must be a name (letters, digits, '_', '-', '.'), got {str(value)[:40]!r}")
            return value
        if kind == "floats":
            if not isinstance(value, list) or len(value) > 1000:
                raise _refuse(where, "must be a list of numbers")
            return tuple(_Table({"v": v}, where).get("v", float) for v in value)
        if kind == "strs":
            if not isinstance(value, list) or len(value) > 1000:
                raise _refuse(where, "must be a list of text")
            return tuple(_Table({"v": v}, where).get("v", str) for v in value)
        if kind == "names":
            if not isinstance(value, list) or len(value) > 1000:
                raise _refuse(where, "must be a list of names")
            return tuple(_Table({"v": v}, where).get("v", "name") for v in value)
        if kind == "factors":
            if not isinstance(value, dict):
                raise _refuse(where, "must be a table of factor = level")
            table = _Table(value, where)
            out = {}
            for name in value:
                if not NAME.match(name) or name in DESIGN_COLUMN_NAMES:
                    raise _refuse(f"{where}.{name}", "a factor's name must be a name, and not one of trials.csv's "
                                  "own columns")
                level = value[name]
                out[name] = table.get(name, float) if isinstance(level, int | float) and not isinstance(
                    level, bool) else table.get(name, str)
            return out
        raise AssertionError(kind)

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.read)
        if unknown:
            raise _refuse(self.where or "design", f"unknown key {unknown[0]!r}")


def _pair(values, where: str) -> tuple[float, float] | None:
    if values is None:
        return None
    if len(values) != 2:
        raise _refuse(where, f"must be two numbers, got {len(values)}")
    return (values[0], values[1])


def design_from_dict(tables: dict) -> Design:
    """A design from the TOML's tables as a dict (``experiment``, ``stimuli``, ``conditions``, ``blocks``,
    ``rig``): every key and type checked (ExperimentError, one line naming the key).

    Parameters
    ----------
    tables : dict
        As ``tomllib`` reads a DESIGN.toml.

    Returns
    -------
    Design

    Raises
    ------
    ExperimentError
        An unknown key, a value of the wrong type or out of range, or a design :func:`validate` refuses.

    Examples
    --------
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
    ...     "conditions": [{"name": "g", "stimulus": "g"}],
    ...     "blocks": [{"task": "rating", "conditions": ["g"]}], "rig": {"speed_mm_s": 80}})
    >>> design.speed_mm_s, design.zone_mm, design.blocks[0].scale           # mm/s; mm; the defaults
    (80.0, (40.0, 40.0), (1, 7))
    >>> design_from_dict({"stimuli": {"g": {"texture": "grating-1mm", "contrast": "high"}}})
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: stimuli.g.contrast: must be a number, got 'high'
    """
    top = _Table(tables, "")
    experiment = _Table(top.get("experiment", dict, {}), "experiment")
    words = top.get("words", dict, {})
    rig = _Table(top.get("rig", dict, {}), "rig")
    stimuli_tables = top.get("stimuli", dict, {}, required=True)
    if not isinstance(stimuli_tables, dict) or not stimuli_tables:
        raise _refuse("stimuli", "a design needs at least one stimulus")
    stimuli = {}
    for name, values in stimuli_tables.items():
        if not NAME.match(name):
            raise _refuse(f"stimuli.{name[:40]}", "a stimulus's name must be a name (letters, digits, '_', '-', '.')")
        table = _Table(values, f"stimuli.{name}")
        stimuli[name] = Stimulus(name, table.get("texture", str, required=True), table.get("contrast", float),
                                 table.get("mean", float), table.get("scale", float, 1.0),
                                 table.get("rotation_deg", float, 0.0), table.get("effects", str))
        table.done()
    conditions = {}
    condition_list = top.get("conditions", list, [])
    if not isinstance(condition_list, list) or not condition_list:
        raise _refuse("conditions", "a design needs at least one condition ([[conditions]])")
    for index, values in enumerate(condition_list):
        table = _Table(values, f"conditions[{index}]")
        name = table.get("name", "name", required=True)
        if name in conditions:
            raise _refuse(f"conditions[{index}].name", f"{name!r} names two conditions")
        stimulus = table.get("stimulus", "name") or table.get("a", "name")
        if stimulus is None:
            raise _refuse(f"conditions[{index}]", "needs stimulus (or a and b)")
        reference = table.get("reference", "name") or table.get("b", "name")
        conditions[name] = Condition(name, stimulus, reference, table.get("factors", "factors", {}),
                                     table.get("vary", str, "contrast"), table.get("levels", "floats", ()),
                                     _pair(table.get("range", "floats"), f"conditions[{index}].range"),
                                     table.get("start_level", float))
        if any(level < 0 for level in conditions[name].levels):
            raise _refuse(f"conditions[{index}].levels", "levels must not be negative")
        table.done()
    blocks = []
    block_list = top.get("blocks", list, [])
    if not isinstance(block_list, list):
        raise _refuse("blocks", "must be an array of tables ([[blocks]])")
    for index, values in enumerate(block_list):
        table = _Table(values, f"blocks[{index}]")
        scale = table.get("scale", list, [1, 7])
        if not (isinstance(scale, list) and len(scale) == 2 and all(isinstance(v, int) and not isinstance(v, bool)
                                                                    for v in scale)):
            raise _refuse(f"blocks[{index}].scale", "must be two whole numbers [LOW, HIGH]")
        blocks.append(Block(
            table.get("name", "name", f"block{index + 1}"), table.get("task", str, required=True),
            table.get("conditions", "names", required=True), table.get("trials", int, 40),
            table.get("repeats", int, 10), table.get("intervals", int, 2), table.get("rule", str, "1u2d"),
            table.get("function", str, "weibull"), table.get("question", str, ""), table.get("labels", "strs", ()),
            (scale[0], scale[1]), table.get("modulus", float, 10.0), table.get("modulus_stimulus", "name"),
            table.get("practice", int, 0), table.get("break_every", int, 0)))
        table.done()
    zone = rig.get("zone_mm", "floats", (40.0, 40.0))
    design = dict(
        name=experiment.get("name", str, "experiment"), seed=experiment.get("seed", int, 0),
        order=experiment.get("order", str, "random"), language=experiment.get("language", str, "en"),
        break_message=experiment.get("break_message", str, "Take a break. Tap or press space to go on."),
        zone_mm=_pair(zone, "rig.zone_mm"), gap_mm=rig.get("gap_mm", float, 10.0),
        speed_mm_s=rig.get("speed_mm_s", float, 100.0), force_n=rig.get("force_n", float, 0.5),
        model=rig.get("model", str, EXPERIMENT_MODEL), profile=rig.get("profile", str, "sim-plate"),
        check_paths=rig.get("check_paths", "strs", ()), words=dict(words))
    for table in (top, experiment, rig):
        table.done()
    if not 0 <= design["seed"] < 2**32:
        raise _refuse("experiment.seed", f"must be a whole number from 0 to {2**32 - 1}")
    if not (1 <= design["zone_mm"][0] <= 1000 and 1 <= design["zone_mm"][1] <= 1000 and 0 <= design["gap_mm"] <= 1000):
        raise _refuse("rig", "zone_mm must lie in 1..1000 mm and gap_mm in 0..1000 mm")
    if not (0 < design["speed_mm_s"] <= 10_000 and 0 < design["force_n"] <= 50):
        raise _refuse("rig", "speed_mm_s must lie in 0..10000 mm/s and force_n in 0..50 N")
    return Design(stimuli=stimuli, conditions=conditions, blocks=tuple(blocks), **design)


def design_to_dict(design: Design) -> dict:
    """The TOML tables of ``design`` (defaults left out where they are the loader's).

    Parameters
    ----------
    design : Design

    Returns
    -------
    dict

    Examples
    --------
    >>> design = Design("d", {"g": Stimulus("g", "grating-1mm", contrast=0.2)}, {"g": Condition("g", "g")},
    ...                 (Block("main", "rating", ("g",), repeats=4),))
    >>> tables = design_to_dict(design)
    >>> tables["stimuli"], tables["blocks"]
    ({'g': {'texture': 'grating-1mm', 'contrast': 0.2}},
     [{'name': 'main', 'task': 'rating', 'conditions': ['g'], 'repeats': 4}])
    """
    def stimulus(s: Stimulus) -> dict:
        out = {"texture": s.texture}
        for key in ("contrast", "mean"):
            if getattr(s, key) is not None:
                out[key] = getattr(s, key)
        if s.scale != 1.0:
            out["scale"] = s.scale
        if s.rotation_deg:
            out["rotation_deg"] = s.rotation_deg
        if s.effects is not None:
            out["effects"] = s.effects
        return out

    def condition(c: Condition) -> dict:
        out = {"name": c.name, "stimulus": c.stimulus}
        if c.reference is not None:
            out["reference"] = c.reference
        if c.factors:
            out["factors"] = dict(c.factors)
        if c.vary != "contrast":
            out["vary"] = c.vary
        if c.levels:
            out["levels"] = list(c.levels)
        if c.level_range:
            out["range"] = list(c.level_range)
        if c.start_level is not None:
            out["start_level"] = c.start_level
        return out

    def block(b: Block) -> dict:
        out = {"name": b.name, "task": b.task, "conditions": list(b.conditions)}
        defaults = Block("", "", ())
        for key in ("trials", "repeats", "intervals", "rule", "function", "question", "modulus", "practice",
                    "break_every"):
            if getattr(b, key) != getattr(defaults, key):
                out[key] = getattr(b, key)
        if b.labels:
            out["labels"] = list(b.labels)
        if b.scale != defaults.scale:
            out["scale"] = list(b.scale)
        if b.modulus_stimulus:
            out["modulus_stimulus"] = b.modulus_stimulus
        return out

    return {"experiment": {"name": design.name, "seed": design.seed, "order": design.order,
                           "language": design.language, "break_message": design.break_message},
            "rig": {"model": design.model, "profile": design.profile, "zone_mm": list(design.zone_mm),
                    "gap_mm": design.gap_mm, "speed_mm_s": design.speed_mm_s, "force_n": design.force_n,
                    **({"check_paths": list(design.check_paths)} if design.check_paths else {})},
            "stimuli": {name: stimulus(s) for name, s in design.stimuli.items()},
            "conditions": [condition(c) for c in design.conditions.values()],
            "blocks": [block(b) for b in design.blocks],
            **({"words": dict(design.words)} if design.words else {})}


def to_toml(design: Design) -> str:
    """``design`` as DESIGN.toml text (:func:`design_from_toml` reads it back to an equal design).

    Parameters
    ----------
    design : Design

    Returns
    -------
    str

    Examples
    --------
    Read back by ``tomllib``:

    >>> import tomllib
    >>> design = Design("d", {"g": Stimulus("g", "grating-1mm", contrast=0.2)}, {"g": Condition("g", "g")},
    ...                 (Block("main", "rating", ("g",), repeats=4),))
    >>> text = to_toml(design)
    >>> tomllib.loads(text)["stimuli"]["g"], design_from_toml(text) == design
    ({'texture': 'grating-1mm', 'contrast': 0.2}, True)
    """
    tables = design_to_dict(design)
    lines = [f"# {design.name}: an ultraglide experiment design (ultraglide experiment check|run)"]

    def emit(prefix: str, table: dict) -> None:
        for key, value in table.items():
            if not isinstance(value, dict):
                lines.append(f"{key} = {_toml_value(value)}")
        for key, value in table.items():
            if isinstance(value, dict):
                lines.append(f"{prefix}{key} = {_toml_value(value)}")

    for name in ("experiment", "rig", "words"):
        if name in tables:
            lines += ["", f"[{name}]"]
            emit("", tables[name])
    for name, values in tables["stimuli"].items():
        lines += ["", f"[stimuli.{name}]"]
        emit("", values)
    for key in ("conditions", "blocks"):
        for values in tables[key]:
            lines += ["", f"[[{key}]]"]
            emit("", values)
    return "\n".join(lines) + "\n"


def _toml_value(value) -> str:
    import json

    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(type(value))


DESIGN_COLUMN_NAMES: set[str] = set()  # filled below: factors may not take these names


def _fill_column_names() -> None:
    from ultraglide.experiment.columns import DESIGN_COLUMNS

    DESIGN_COLUMN_NAMES.update(DESIGN_COLUMNS)


_fill_column_names()
