"""The columns of ``trials.csv``, in order, each with what it holds: the one place the log's header and the
documentation's tables (docs/experiments.md, checked by tests/test_experiment_outputs.py) come from.

:data:`THRESHOLD_COLUMNS`: the log of ``ultraglide experiment threshold|constant``. :data:`DESIGN_COLUMNS`: the
log of a design's session (``ultraglide experiment run``, :func:`ultraglide.experiment.run`); a design's factors
add a column each, after ``condition``.
"""

from __future__ import annotations

import re

_SHARED_HEAD = {
    "participant": "the participant's code (`--participant`)",
    "session": "the session's label",
    "trial": "the trial's number, from 1, in the order presented",
}
_FRICTION = {
    "target_ratio": "mean friction ratio the texture asked for while the finger touched (live engine; empty in "
                    "a dry run)",
    "measured_ratio": "mean friction ratio the plate's force sensors measured (`--closed-loop`; else empty)",
    "commanded_um_pp": "mean vibration amplitude sent while the finger touched, µm p-p (live engine; else empty)",
    "loop": "the friction loop's state at the answer, in words (empty without it)",
}

THRESHOLD_COLUMNS: dict[str, str] = {
    **_SHARED_HEAD,
    "condition": "the varied parameter, the task and the procedure, e.g. `contrast 2AFC 1u2d`",
    "level": "the level presented, in the parameter's unit, written exactly (Python's repr)",
    "stimulus": "the trial's zones in words",
    "target": "the zone holding the stimulus, from 1 (forced choice; empty in yes/no)",
    "response": "the zone chosen, from 1 (forced choice), or `yes`/`no`",
    "correct": "1 if the answer was right (in yes/no: right about whether the level was above 0), else 0",
    "rt_s": "reaction time, s, from the trial's first frame to the answer",
    "reversal": "1 if a staircase reversed its direction on this trial",
    "break_before": "1 if a pause came before this trial",
    "rendered_um_pp": "median plate amplitude the target zone delivered, µm p-p (dry run: the plate model)",
    "rendered_contrast": "friction contrast the target zone delivered (1st to 99th percentile of the ratio)",
    "time_utc": "when the answer was logged, ISO 8601, UTC",
    **_FRICTION,
}

DESIGN_COLUMNS: dict[str, str] = {
    **_SHARED_HEAD,
    "block": "the block's name",
    "task": "the block's design: `constant`, `staircase`, `quest`, `afc`, `same_different`, `rating`, "
            "`magnitude` or `adjustment`",
    "practice": "1 for a practice trial (left out of the summary's fits), else 0",
    "condition": "the condition's name; the design's factors follow, a column each, named after the factor",
    "stimuli": "the stimuli of the trial's intervals in order, names joined by ` | `",
    "level": "the level of the varied stimulus (staircases, QUEST+, constant stimuli) or the adjustment's start, "
             "exactly; else empty",
    "target": "the interval holding the odd stimulus, from 1 (forced choice); `same`/`different` "
              "(same-different); else empty",
    "response": "the interval chosen (from 1), `yes`/`no`, `same`/`different`, the rating, the number given, or "
                "the contrast set (adjustment)",
    "response_label": "the response in the participant's words (the design's labels)",
    "correct": "1 or 0 where an answer can be right (forced choice, same-different, yes/no); else empty",
    "rt_s": "reaction time, s (empty when unknown)",
    "reversal": "1 if the condition's staircase reversed on this trial",
    "break_before": "1 if a pause came before this trial",
    "delivered_contrast": "friction contrast the trial's first (varied, or A) stimulus delivered along the path "
                          "(1st to 99th percentile of the ratio)",
    "delivered_mean_ratio": "mean friction ratio the trial's first stimulus delivered along the path",
    "delivered_um_pp": "median plate amplitude the trial's first stimulus delivered, µm p-p",
    "time_utc": "when the answer was logged, ISO 8601, UTC",
    **_FRICTION,
}


def columns_markdown(columns: dict[str, str]) -> str:
    """A Markdown table of ``columns``: name and meaning, one row each (what docs/experiments.md holds).

    Parameters
    ----------
    columns : dict of str to str
        Column name to what it holds.

    Returns
    -------
    str

    Examples
    --------
    >>> from ultraglide.experiment.columns import THRESHOLD_COLUMNS, columns_markdown
    >>> columns_markdown(THRESHOLD_COLUMNS).splitlines()[2]
    "| `participant` | the participant's code (`--participant`) |"
    """
    rows = ["| column | what it holds |", "|---|---|"]
    rows += [f"| `{name}` | {meaning} |" for name, meaning in columns.items()]
    return "\n".join(rows)


BLOCK = re.compile(r"(<!-- columns: (\w+) -->\n)(.*?)(<!-- end columns -->)", re.DOTALL)


def documented_tables(text: str) -> dict[str, str]:
    r"""The column tables a Markdown page holds between ``<!-- columns: NAME -->`` and ``<!-- end columns -->``.

    Parameters
    ----------
    text : str
        The page's Markdown.

    Returns
    -------
    dict
        The table's text (stripped) by NAME.

    Examples
    --------
    >>> documented_tables("intro\n<!-- columns: T -->\n| a | b |\n<!-- end columns -->\n")
    {'T': '| a | b |'}
    """
    return {match.group(2): match.group(3).strip() for match in BLOCK.finditer(text)}


def update_docs(text: str) -> str:
    r"""``text`` with every column table regenerated from this module (:func:`rewrite_docs` rewrites a page).

    Parameters
    ----------
    text : str
        A Markdown page whose tables are marked ``<!-- columns: NAME -->`` ... ``<!-- end columns -->``, NAME one of
        this module's tables (``THRESHOLD_COLUMNS``, ``DESIGN_COLUMNS``).

    Returns
    -------
    str

    Examples
    --------
    >>> page = update_docs("<!-- columns: THRESHOLD_COLUMNS -->\nstale\n<!-- end columns -->\n")
    >>> len(page.splitlines()) == 2 + len(THRESHOLD_COLUMNS) + 2     # the markers, a header and a rule, a row each
    True
    """
    return BLOCK.sub(lambda m: m.group(1) + columns_markdown(globals()[m.group(2)]) + "\n" + m.group(4), text)



def rewrite_docs(path) -> None:
    r"""Rewrite the Markdown page at ``path`` with its column tables regenerated (:func:`update_docs`).

    Parameters
    ----------
    path : str or os.PathLike
        The page, rewritten in place (UTF-8).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> page = pathlib.Path(tempfile.mkdtemp()) / "columns.md"
    >>> _ = page.write_text("<!-- columns: DESIGN_COLUMNS -->\n<!-- end columns -->\n", encoding="utf-8")
    >>> rewrite_docs(page)
    >>> page.read_text(encoding="utf-8").splitlines()[3]
    "| `participant` | the participant's code (`--participant`) |"
    """
    from pathlib import Path

    page = Path(path)
    page.write_text(update_docs(page.read_text(encoding="utf-8")), encoding="utf-8")
