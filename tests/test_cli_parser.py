"""The command line's parser: every command's help and usage render."""

from __future__ import annotations

import argparse

from conftest import run_cli
from ultraglide.apps.cli.parser import build_parser


def commands_of(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """A parser's subcommands by name (none: {})."""
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(actions[0].choices) if actions else {}


def helps(parser: argparse.ArgumentParser, words: tuple[str, ...] = ()) -> dict[tuple[str, ...], str]:
    """Every parser under ``parser`` (itself included) by its words, with its help text."""
    found = {words: parser.format_help()}
    for name, inner in commands_of(parser).items():
        found.update(helps(inner, (*words, name)))
    return found


WHOLE = build_parser()


def test_every_commands_help_and_usage_render():
    """``--help`` of every command and subcommand, and the usage an error prints (a positional's tuple metavar
    made argparse raise in both: ``texture compose tile``)."""
    texts = helps(WHOLE)
    assert len(texts) > 30
    for words, text in texts.items():
        assert text.startswith(f"usage: {' '.join(('ultraglide', *words))}"), words


def test_compose_tile_helps_and_names_its_missing_input():
    shown = run_cli("texture", "compose", "tile", "--help")
    assert shown.returncode == 0 and "INNER" in shown.stdout and "OUTER" in shown.stdout, shown.stderr
    refused = run_cli("texture", "compose", "tile", "dots")
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert "the following arguments are required: OUTER" in refused.stderr.strip().splitlines()[-1]
