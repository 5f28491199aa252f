"""The ``ultraglide`` command's parser: each command module in :mod:`ultraglide.apps.commands` adds its own
options (``add_parser``) and names the function that runs it (``run`` in the parsed arguments).

Command modules import only the standard library and :mod:`ultraglide.apps.cli` at their top, and their
heavy libraries inside the functions that use them, so that ``ultraglide --help`` loads no numpy.
"""

from __future__ import annotations

import argparse

from ultraglide.apps.cli.options import OneLineParser
from ultraglide.apps.commands import (
    author,
    calibrate,
    demo,
    devices,
    experiment,
    export,
    firmware,
    latency,
    model,
    plate,
    plate_sim,
    play,
    rig,
    serve,
    texture,
)

from ultraglide import __version__

# each command name and the module that adds it, in the order ``--help`` lists them (tests/test_cli_parser.py
# checks the names against the parser the modules build)
NAMES = {"model": model, "calibrate": calibrate, "author": author, "textures": texture, "texture": texture,
         "export": export, "play": play, "serve": serve, "latency": latency, "devices": devices,
         "plate-sim": plate_sim, "firmware": firmware, "plate": plate, "rig": rig, "demo": demo,
         "experiment": experiment}
COMMANDS = tuple(dict.fromkeys(NAMES.values()))


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The whole parser; given the command line, only the parser of the command it names (argparse builds a
    parser with every command's options in 15-20 ms, a twentieth of a short command's start; the command's own
    parser, its help and its errors are the same either way). A command line naming no known command (help,
    ``--version``, a misspelt command, a top-level option before the command) gets the whole parser, which lists
    every command."""
    parser = OneLineParser(
        prog="ultraglide",
        description="Tactile texture rendering for ultrasonic friction displays.",
    )
    parser.add_argument("--version", action="version", version=f"ultraglide {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    named = argv[0] if argv else None  # the command, if it comes first
    for command in (NAMES[named],) if named in NAMES else COMMANDS:
        command.add_parser(commands)
    return parser
