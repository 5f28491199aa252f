"""The ``ultraglide`` command: argument parsing only, so that ``--help`` starts fast.

Each subcommand names a handler ``module:function`` that is imported when it runs; numpy, scipy,
pygame and the rest are loaded only by the subcommands that need them.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
from importlib import metadata

from apps import errors


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line, as every error of ours is."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _number(kind: str, test, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or not test(value):
        raise argparse.ArgumentTypeError(f"must be {kind}, got {text}")
    return value


def positive(text: str) -> float:
    return _number("a positive number", lambda v: v > 0, text)


def non_negative(text: str) -> float:
    return _number("zero or more", lambda v: v >= 0, text)


def ratio(text: str) -> float:
    return _number("a friction ratio in (0, 1]", lambda v: 0 < v <= 1, text)


def finite(text: str) -> float:
    return _number("a finite number", lambda v: True, text)


MODEL_HELP = "friction model: paper, paper-uniform, exponential, table:FILE.csv or CAL.toml"


def _add_model(parser: argparse.ArgumentParser, default: str = "paper") -> None:
    parser.add_argument("--model", default=default, metavar="MODEL",
                        help=f"{MODEL_HELP} (default: {default})")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="ultraglide",
        description="Tactile texture rendering for ultrasonic friction displays.",
    )
    parser.add_argument("--version", action="version",
                        version=f"ultraglide {metadata.version('ultraglide')}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)

    model = commands.add_parser(
        "model", help="the fingerprint physics at one normal force",
        description="Contact area, ridge stiffness, detachment amplitude, glide threshold and "
                    "relative friction against amplitude, from the paper's model.")
    model.add_argument("--force", type=positive, default=0.5, metavar="N",
                       help="normal force of the finger, N (default: 0.5)")
    _add_model(model)
    model.add_argument("--ratio", type=ratio, metavar="R",
                       help="also give the amplitude that yields friction ratio R")
    model.add_argument("--json", action="store_true", help="print one JSON object")
    model.add_argument("--plots", metavar="DIR", help="write the paper's figures 2-9 as PNGs here")
    model.add_argument("--data", metavar="CSV",
                       help="measured points for figure 9 (default: the bundled Monnoyer 2018 fit)")
    model.set_defaults(handler="apps.model_command:run")

    calibrate = commands.add_parser(
        "calibrate", help="fit a friction model to measured points",
        description="Fit a model's free parameters to a CSV of amplitude_um_pp,relative_friction"
                    "[,force_n] and write a calibration file usable as --model.")
    calibrate.add_argument("data", metavar="DATA.csv")
    calibrate.add_argument("--model", default="exponential",
                           choices=["exponential", "paper", "paper-uniform"])
    calibrate.add_argument("-o", "--output", required=True, metavar="CAL.toml")
    calibrate.set_defaults(handler="apps.calibrate_command:run")

    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return 0
    module_name, function_name = args.handler.split(":")
    try:
        handler = getattr(importlib.import_module(module_name), function_name)
        return int(handler(args) or 0)
    except KeyboardInterrupt:
        print("ultraglide: stopped", file=sys.stderr)
        return 130
    except errors.user_errors() as error:
        print(f"ultraglide {args.command}: error: {errors.describe(error)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
