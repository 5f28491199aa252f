"""argparse value types: each refuses bad values with a sentence that says what is expected.

Every numeric option has a range (:class:`Bounded`): NaN, infinities and absurd magnitudes stop
at the parser with the allowed range in the message, before any file is read or written.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from ultraglide.textures.limits import MAX_PIXELS as TEXTURE_MAX_PIXELS


def _parse(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _number(kind: str, test, text: str) -> float:
    value = _parse(text)
    if not math.isfinite(value) or not test(value):
        raise argparse.ArgumentTypeError(f"must be {kind}, got {text}")
    return value


def _show(value: float) -> str:
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e16 else f"{value:g}"


@dataclass(frozen=True)
class Bounded:
    """An argparse type for a number in ``low..high`` (an end excluded when ``low_open`` or
    ``high_open``); ``whole`` asks for an integer. The error message states the range and the unit."""

    low: float
    high: float
    unit: str = ""
    low_open: bool = False
    whole: bool = False
    high_open: bool = False
    what: str = ""  # what the number is, when its name helps ("Hurst exponent")

    @property
    def __name__(self) -> str:  # argparse names a type by it in some messages
        return "whole number" if self.whole else "number"

    def describe(self) -> str:
        """The range in words: "a positive number up to 50 N", "a whole number in 1..100"."""
        unit = f" {self.unit}" if self.unit else ""
        kind = self.what or ("whole number" if self.whole else "number")
        low, high = _show(self.low), _show(self.high)
        if self.low_open and self.high_open:
            return f"a {kind} strictly between {low} and {high}{unit}"
        if self.high_open:
            return f"a {kind} from {low} up to (not including) {high}{unit}"
        if self.low_open and self.low == 0:
            return f"a positive {kind} up to {high}{unit}"
        if self.low_open:
            return f"a {kind} above {low}, up to {high}{unit}"
        if self.low > 0:
            return f"a positive {kind} from {low} to {high}{unit}"
        return f"a {kind} in {low}..{high}{unit}"

    def __call__(self, text: str) -> float | int:
        value = _parse(text)
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        if not (math.isfinite(value) and above and below) or (self.whole and value != math.floor(value)):
            raise argparse.ArgumentTypeError(f"must be {self.describe()}, got {text}")
        return int(value) if self.whole else value


# The ranges of the project's options: wide enough for any real plate, finger or image, narrow
# enough that no value can overflow, exhaust memory or run for days.
FORCE_N = Bounded(0.0, 10.0, "N", low_open=True, what="normal force (a fingertip's touch range)")
PRELOAD_N = Bounded(0.0, 10.0, "N", what="tangential preload")
RATIO = Bounded(0.0, 1.0, low_open=True)
UNIT_INTERVAL = Bounded(0.0, 1.0)
LENGTH_MM = Bounded(0.0, 10_000.0, "mm", low_open=True)
FEATURE_MM = Bounded(0.01, 10_000.0, "mm")
TEXTURE_SIDE_MM = Bounded(0.1, 10_000.0, "mm")
COORDINATE_MM = Bounded(-10_000.0, 10_000.0, "mm")
ANGLE_DEG = Bounded(-360.0, 360.0, "degrees")
SPEED_MM_S = Bounded(0.0, 10_000.0, "mm/s", low_open=True)
DURATION_S = Bounded(0.0, 3_600.0, "s", low_open=True)  # an hour of 768 kHz float32 is 11 GB already
CARRIER_HZ = Bounded(1_000.0, 200_000.0, "Hz")
AUDIO_RATE_HZ = Bounded(12_000, 768_000, "Hz", whole=True)
LOOKAHEAD_MS = Bounded(0.0, 1_000.0, "ms")
DPI = Bounded(1.0, 100_000.0, "pixels per inch")
GAMMA = Bounded(0.01, 100.0)
BLUR_MM = Bounded(0.0, 1_000.0, "mm")
MAX_PIXELS = Bounded(1, TEXTURE_MAX_PIXELS, "pixels", whole=True)  # the texture file's own limit
PX_PER_MM = Bounded(0.1, 1_000.0, "pixels per mm")
SEED = Bounded(0, 2**32 - 1, whole=True)
DETENTS = Bounded(1, 100, whole=True)
THREADS = Bounded(1, 256, whole=True)  # export's carrier threads
STEPS = Bounded(1, 10_000, whole=True)  # latency measurements: each takes a fraction of a second
SCREEN_WIDTH_MM = Bounded(10.0, 10_000.0, "mm")
PRINT_DPI = Bounded(10.0, 2_400.0, "dpi")  # a figure's resolution, not a texture's
Q_FACTOR = Bounded(1.0, 100_000.0)
DRIFT_HZ_PER_S = Bounded(-10_000.0, 10_000.0, "Hz/s")
CLOCK_PPM = Bounded(-50_000.0, 50_000.0, "ppm")
DUTY = Bounded(0.0, 1.0, low_open=True, high_open=True, what="duty cycle")
HURST = Bounded(0.0, 1.0, low_open=True, high_open=True, what="Hurst exponent")
SEAM_BAND = Bounded(0.0, 0.5, low_open=True)
CLIP_PERCENT = Bounded(0.0, 50.0, "%", high_open=True)
WEIGHT = Bounded(0.0, 1e6)
SWEEP_STEPS = Bounded(5, 2_000, whole=True)  # carriers in a resonance sweep
SENSITIVITY = Bounded(1e-6, 1e6, "µm p-p per unit")
TRIALS = Bounded(1, 100_000, whole=True)
TRIALS_BETWEEN_BREAKS = Bounded(0, 100_000, whole=True)  # 0: no breaks
BOOTSTRAP_SAMPLES = Bounded(10, 100_000, whole=True)
REPEATS = Bounded(1, 10_000, whole=True)
ZONES = Bounded(2, 3, whole=True)
LEVEL = Bounded(0.0, 10_000.0, what="level (in the varied parameter's unit)")


def PARTICIPANT(text: str) -> str:  # noqa: N802 (an argparse type, named like the others)
    """Whose finger: an id as experiments take it (P01), a number the same id however written (7, 7.0)."""
    from ultraglide.render.physics.measurements import participant_id

    try:
        return participant_id(text)
    except ValueError as problem:
        raise argparse.ArgumentTypeError(str(problem)) from None


MAX_NAME_CHARS = 200


def texture_name(text: str) -> str:
    """A texture's name: printable text of at most 200 characters (it is stored in the file)."""
    if len(text) > MAX_NAME_CHARS or not text.isprintable():
        raise argparse.ArgumentTypeError(f"a name is printable text of at most {MAX_NAME_CHARS} characters, "
                                         f"got {len(text)} characters")
    return text


label = texture_name  # a label written into a file and onto figures (a session's): the same rule


def positive(text: str) -> float:
    return _number("a positive number", lambda v: v > 0, text)


def non_negative(text: str) -> float:
    return _number("zero or more", lambda v: v >= 0, text)


def ratio(text: str) -> float:
    return RATIO(text)


def finite(text: str) -> float:
    return _number("a finite number", lambda v: True, text)


def point_mm(text: str) -> tuple[float, float]:
    """X,Y in millimetres, each within ±10 000 mm."""
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"a point is X,Y in mm, e.g. 10,25, got {text!r}")
    return COORDINATE_MM(parts[0]), COORDINATE_MM(parts[1])


def size_mm(text: str) -> tuple[float, float]:
    """WIDTHxHEIGHT in millimetres, e.g. 80x50; each side 0.1 to 10 000 mm."""
    parts = text.lower().replace("×", "x").split("x")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"size is WIDTHxHEIGHT in mm, e.g. 80x50, got {text!r}")
    return TEXTURE_SIDE_MM(parts[0]), TEXTURE_SIDE_MM(parts[1])


def crop_box(text: str) -> tuple[int, int, int, int]:
    """X,Y,WIDTH,HEIGHT in pixels."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"crop is X,Y,WIDTH,HEIGHT in whole pixels, got {text!r}") from None
    if len(values) != 4 or min(values) < 0 or min(values[2:]) == 0:
        raise argparse.ArgumentTypeError(f"crop is X,Y,WIDTH,HEIGHT with a positive size, got {text!r}")
    return values
