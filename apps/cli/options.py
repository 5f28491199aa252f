"""What the commands' parsers share: the parser class, and options several commands take."""

from __future__ import annotations

import argparse
import re

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.output import one_line
from ultraglide.apps.cli.types import UNIT_INTERVAL

_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line, as every error of ours is, and which reads any
    negative number (``-1e+16``, ``-inf`` too, not only ``-3`` and ``-.5``) as a value, so that an option's
    own range check names the option instead of argparse calling the number an unknown option."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> None:  # type: ignore[override]
        # the arguments it quotes may be anything a script passed (escape sequences, 100 KB file names)
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


OUTPUTS = "checked_outputs"  # in the parsed arguments: the command's outputs, checked before it runs
OUTPUT_KINDS = ("file", "wav", "log", "link", "folder", "device")


def output_option(container, *flags: str, kind: str = "file", also: tuple[str, ...] = (), **kwargs) -> argparse.Action:
    """``add_argument`` for an option naming what the command writes. ``ultraglide``'s ``main`` checks every such
    option given before the command runs (:func:`ultraglide.apps.cli.files.check_outputs`), so a directory, a
    pipe nobody reads or a missing folder is refused before any work, not after it.

    ``kind``: ``file``, ``wav`` (no pipe), ``log`` (grows as ``NAME.part``), ``link`` (a link placed there),
    ``folder`` (files written into it) or ``device`` (a device URL: ``wav:PATH`` is a WAV file); ``also``: the
    suffixes of files written beside it (a calibration's ``.png`` and ``.pdf``) or, for a folder, the names of
    the files written into it (each checked as a file output when the folder exists)."""
    if kind not in OUTPUT_KINDS:
        raise ValueError(f"kind must be one of {OUTPUT_KINDS}, got {kind!r}")
    action = container.add_argument(*flags, **kwargs)
    outputs = dict(container.get_default(OUTPUTS) or {})
    outputs[action.dest] = (flags[0], kind, tuple(also))
    container.set_defaults(**{OUTPUTS: outputs})
    return action


def refuse_ignored(args, options: dict[str, object], why: str) -> None:
    """Refuse, in one line, an option that this combination of options would accept and then ignore: an option
    that silently does nothing is a mistake the person should hear of. ``options``: the options concerned (their
    dests) and their defaults, an option counting as given when it holds anything else; ``why``: when it counts
    and what to do, with ``{option}`` for the option's name."""
    for dest, default in options.items():
        value = getattr(args, dest, default)
        if value is not None and value is not False and value != default:
            raise UsageError(why.format(option="--" + dest.replace("_", "-")))


MODEL_HELP = ("friction model: stretched, squeeze-film, exponential, paper, paper-uniform, table:FILE.csv or "
              "CAL.toml; dynamic[:NAME] with the finger's friction dynamics; speed:S:NAME with the reduction "
              "weakening with sliding speed as (22 mm/s / v)^S, S in 0-1 (assumed)")


def add_model_option(parser: argparse.ArgumentParser, default: str = "paper") -> None:
    parser.add_argument("--model", default=default, metavar="MODEL",
                        help=f"{MODEL_HELP} (default: {default})")


def add_figure_width_option(parser: argparse.ArgumentParser, default: str = "column") -> None:
    parser.add_argument("--figure-width", choices=["column", "page"], default=default,
                        help="lay figures out for one IEEE column (3.5 in) or two (7.16 in), text of 8 pt or more "
                             f"at that size (default: {default})")


def add_range_option(parser: argparse.ArgumentParser, default=(0.4, 1.0)) -> None:
    parser.add_argument("--range", nargs=2, type=UNIT_INTERVAL, default=list(default), metavar=("LOW", "HIGH"),
                        help="friction ratio where the pattern is off (slippery) and on (sticky), each in 0..1 "
                             f"(default: {default[0]} {default[1]})")
