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
    texture,
)

from ultraglide import __version__

COMMANDS = (model, calibrate, author, texture, export, play, latency, devices, plate_sim, firmware, plate, demo,
            experiment)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="ultraglide",
        description="Tactile texture rendering for ultrasonic friction displays.",
    )
    parser.add_argument("--version", action="version", version=f"ultraglide {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    for command in COMMANDS:
        command.add_parser(commands)
    return parser
