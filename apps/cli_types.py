"""argparse value types: each refuses bad values with a sentence that says what is expected."""

from __future__ import annotations

import argparse
import math


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


def point_mm(text: str) -> tuple[float, float]:
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"a point is X,Y in mm, e.g. 10,25, got {text!r}")
    return finite(parts[0]), finite(parts[1])


def size_mm(text: str) -> tuple[float, float]:
    """WIDTHxHEIGHT in millimetres, e.g. 80x50."""
    parts = text.lower().replace("×", "x").split("x")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"size is WIDTHxHEIGHT in mm, e.g. 80x50, got {text!r}")
    return positive(parts[0]), positive(parts[1])


def crop_box(text: str) -> tuple[int, int, int, int]:
    """X,Y,WIDTH,HEIGHT in pixels."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"crop is X,Y,WIDTH,HEIGHT in whole pixels, got {text!r}") from None
    if len(values) != 4 or min(values) < 0 or min(values[2:]) == 0:
        raise argparse.ArgumentTypeError(f"crop is X,Y,WIDTH,HEIGHT with a positive size, got {text!r}")
    return values
