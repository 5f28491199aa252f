"""The command line's parser: built whole for help and unknown commands, and for a named command only that
command's parser (apps/cli/parser.py), which must parse, help and refuse exactly as within the whole."""

from __future__ import annotations

import argparse

import pytest
from conftest import run_cli
from ultraglide.apps.cli.parser import NAMES, build_parser


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


def test_the_names_are_the_commands_the_modules_add():
    assert sorted(commands_of(WHOLE)) == sorted(NAMES)


@pytest.mark.parametrize("name", sorted(NAMES))
def test_a_command_alone_has_the_same_parsers_as_within_the_whole(name):
    alone = build_parser([name, "--anything"])
    assert name in commands_of(alone) and len(commands_of(alone)) <= 2  # texture adds "texture" and "textures"
    expected = {words: text for words, text in helps(WHOLE).items() if words[:1] == (name,)}
    got = {words: text for words, text in helps(alone).items() if words[:1] == (name,)}
    assert got == expected and len(got) >= 1


@pytest.mark.parametrize("argv", [[], ["-h", "export"], ["--version"], ["exprot"], ["EXPORT"], ["export!"]])
def test_a_line_naming_no_command_first_gets_every_command(argv):
    assert sorted(commands_of(build_parser(argv))) == sorted(NAMES)


def test_a_misspelt_command_is_refused_with_every_command_listed():
    result = run_cli("exprot", "grating-1mm")
    assert result.returncode == 2 and result.stdout == ""
    line = result.stderr.strip()
    assert "\n" not in line and "invalid choice: 'exprot'" in line
    assert all(f"'{name}'" in line for name in NAMES), line


def test_the_top_level_help_lists_every_command_even_before_one():
    result = run_cli("-h", "export")
    assert result.returncode == 0
    assert all(name in result.stdout for name in NAMES)


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
