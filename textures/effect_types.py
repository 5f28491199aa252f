"""Temporal effects' types: oscillators, constants, ADSR and their compositions (``+``, ``*``, ``>>``), the
:class:`Trigger` that starts one and the :class:`Binding` that ties the two, each checked as it is made.
Re-exported by :mod:`ultraglide.textures.effects`, where the whole story is told.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ultraglide.textures.errors import TextureError

EFFECTS_VERSION = 1
MAX_FREQUENCY_HZ = 2000.0  # the control rate is 12 kHz and the plate's envelope corner a few hundred Hz
MAX_TIME_S = 60.0
MAX_NODES = 64
MAX_BINDINGS = 32
MAX_LINES = 64
ON = ("start", "end", "while", "cross", "event")


class Effect:
    """The composable part every effect shares: ``+``, ``*`` (or a number), ``>>``.

    Examples
    --------
    Effects combine into effects: a sum, a product, a sequence:

    >>> buzz = Sine(150.0, 0.3) * Constant(1.0, 0.1)        # 100 ms of a 150 Hz buzz
    >>> isinstance(buzz, Effect), buzz.duration_s, (buzz >> buzz).duration_s
    (True, 0.1, 0.2)
    """

    __slots__ = ()

    @property
    def duration_s(self) -> float:
        """How long the effect lasts (s); infinite for one that goes on until its binding releases it.

        Examples
        --------
        >>> (Constant(0.3, 0.1) >> Constant(0.2, 0.05)).duration_s          # a sequence: 0.1 s + 0.05 s
        0.15000000000000002
        """
        raise NotImplementedError

    def __add__(self, other: Effect) -> Effect:
        return Sum((self, _effect(other)))

    def __mul__(self, other) -> Effect:
        return Product((self, _effect(other)))

    __rmul__ = __mul__
    __radd__ = __add__

    def __rshift__(self, other: Effect) -> Effect:
        if not math.isfinite(self.duration_s):
            raise TextureError("an effect that lasts for ever cannot be followed by another (>>); "
                               "multiply it by an ADSR or a Constant with a duration first")
        return Sequence((self, _effect(other)))


def _effect(value) -> Effect:
    if isinstance(value, Effect):
        return value
    if isinstance(value, int | float) and math.isfinite(value):
        return Constant(float(value))
    raise TextureError(f"effects combine with effects or numbers, not {type(value).__name__}")


def _check(name: str, value, low: float, high: float, unit: str = "", low_open: bool = False) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (value > low if low_open else value >= low) and value <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise TextureError(f"effect {name} must lie in {bracket}{low:g}, {high:g}]{unit}, got {value!r}")


@dataclass(frozen=True, slots=True)
class Oscillator(Effect):
    """Shared by the periodic effects: ``frequency_hz`` (Hz) and ``depth`` (friction ratio, −1..1).

    Parameters
    ----------
    frequency_hz : float
        The frequency, Hz (above 0).
    depth : float
        The friction drop at the peak, friction ratio, -1..1.

    Raises
    ------
    TextureError
        A frequency or depth out of range.

    Examples
    --------
    Each periodic effect is one, going on for ever:

    >>> isinstance(Square(50.0, 0.5), Oscillator), Square(50.0, 0.5).duration_s
    (True, inf)
    >>> Sine(0.0, 0.5)
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: effect frequency_hz must lie in (0, 2000] Hz, got 0.0
    """

    frequency_hz: float
    depth: float

    def __post_init__(self) -> None:
        _check("frequency_hz", self.frequency_hz, 0.0, MAX_FREQUENCY_HZ, " Hz", low_open=True)
        _check("depth", self.depth, -1.0, 1.0)

    @property
    def duration_s(self) -> float:
        """Infinite: an oscillator runs until its binding releases it.

        Examples
        --------
        >>> Triangle(80.0, 0.4).duration_s
        inf
        """
        return math.inf


@dataclass(frozen=True, slots=True)
class Sine(Oscillator):
    """depth·(1 − cos 2πft)/2: from 0 to depth and back, once a period.

    Examples
    --------
    At 10 Hz: 0 at the start of each period, the whole depth at its middle (50 ms), half of it a quarter in:

    >>> from ultraglide.render.effects import sample
    >>> sample(Sine(10.0, 0.2), [0.0, 0.025, 0.05, 0.1]).round(9).tolist()
    [0.0, 0.1, 0.2, 0.0]
    """


@dataclass(frozen=True, slots=True)
class Square(Oscillator):
    """0 for the first half of each period, depth for the second.

    Examples
    --------
    >>> from ultraglide.render.effects import sample
    >>> sample(Square(10.0, 0.5), [0.02, 0.07, 0.12]).tolist()        # s: first half, second half, next period
    [0.0, 0.5, 0.0]
    """


@dataclass(frozen=True, slots=True)
class Sawtooth(Oscillator):
    """Rises from 0 to depth over each period, then drops back.

    Examples
    --------
    >>> from ultraglide.render.effects import sample
    >>> sample(Sawtooth(10.0, 1.0), [0.0, 0.025, 0.075]).round(9).tolist()
    [0.0, 0.25, 0.75]
    """


@dataclass(frozen=True, slots=True)
class Triangle(Oscillator):
    """Rises from 0 to depth over half a period and back over the other half.

    Examples
    --------
    >>> from ultraglide.render.effects import sample
    >>> sample(Triangle(10.0, 1.0), [0.0, 0.025, 0.05, 0.075]).round(9).tolist()
    [0.0, 0.5, 1.0, 0.5]
    """


@dataclass(frozen=True, slots=True)
class Constant(Effect):
    """``level`` (friction ratio, −1..1) for ``length_s`` (s; for ever by default): a step, or a pulse.

    Examples
    --------
    >>> from ultraglide.render.effects import sample
    >>> sample(Constant(0.3, 0.05), [0.0, 0.04, 0.06]).tolist()        # s: during, during, after
    [0.3, 0.3, 0.0]
    >>> Constant(0.3).duration_s
    inf
    """

    level: float
    length_s: float = math.inf

    def __post_init__(self) -> None:
        _check("level", self.level, -1.0, 1.0)
        if self.length_s != math.inf:
            _check("length_s", self.length_s, 0.0, MAX_TIME_S, " s", low_open=True)

    @property
    def duration_s(self) -> float:
        """``length_s`` (s): infinite unless given.

        Examples
        --------
        >>> Constant(0.3, 0.05).duration_s, Constant(0.3).duration_s
        (0.05, inf)
        """
        return self.length_s


@dataclass(frozen=True, slots=True)
class ADSR(Effect):
    """Linear attack to ``peak``, decay to ``sustain_level``·peak, held for ``sustain_s``, release to 0 (s).

    Examples
    --------
    10 ms up to the peak, 10 ms down to half of it, held 10 ms, 10 ms down to 0:

    >>> from ultraglide.render.effects import sample
    >>> envelope = ADSR(0.01, 0.01, 0.01, 0.01)
    >>> round(envelope.duration_s, 9), sample(envelope, [0.005, 0.01, 0.02, 0.025, 0.035]).round(9).tolist()
    (0.04, [0.5, 1.0, 0.5, 0.5, 0.25])
    """

    attack_s: float
    decay_s: float
    sustain_s: float
    release_s: float
    peak: float = 1.0
    sustain_level: float = 0.5

    def __post_init__(self) -> None:
        for name in ("attack_s", "decay_s", "sustain_s", "release_s"):
            _check(name, getattr(self, name), 0.0, MAX_TIME_S, " s")
        _check("peak", self.peak, -1.0, 1.0)
        _check("sustain_level", self.sustain_level, 0.0, 1.0)
        if self.duration_s <= 0:
            raise TextureError("an ADSR envelope needs some duration (attack, decay, sustain or release > 0 s)")

    @property
    def duration_s(self) -> float:
        """attack + decay + sustain + release (s).

        Examples
        --------
        >>> ADSR(0.01, 0.02, 0.03, 0.04).duration_s                  # 10 + 20 + 30 + 40 ms
        0.1
        """
        return self.attack_s + self.decay_s + self.sustain_s + self.release_s


@dataclass(frozen=True, slots=True)
class Sum(Effect):
    """Effects added (``a + b``): their values summed, sample by sample, for as long as the longest lasts.

    Parameters
    ----------
    terms : tuple of Effect

    Examples
    --------
    >>> (Sine(10.0, 0.2) + Constant(0.1, 2.0)).duration_s          # s: the sine goes on
    inf
    """

    terms: tuple[Effect, ...]

    @property
    def duration_s(self) -> float:
        """The longest term's duration (s).

        Examples
        --------
        >>> (Constant(0.1, 0.2) + Constant(0.1, 0.5)).duration_s
        0.5
        """
        return max(term.duration_s for term in self.terms)

    def __add__(self, other: Effect) -> Effect:  # flat: a + b + c is one sum
        return Sum((*self.terms, _effect(other)))


@dataclass(frozen=True, slots=True)
class Product(Effect):
    """Effects multiplied (``a * b``, or an effect times a number): their values' product, for as long as the
    shortest lasts.

    Parameters
    ----------
    factors : tuple of Effect

    Examples
    --------
    >>> (Sine(10.0, 0.2) * Constant(0.5, 2.0)).duration_s          # s: the constant ends it
    2.0
    """

    factors: tuple[Effect, ...]

    @property
    def duration_s(self) -> float:
        """The shortest factor's duration (s).

        Examples
        --------
        >>> (Sine(150.0, 0.3) * Constant(1.0, 0.1)).duration_s          # the sine goes on for ever: the constant's
        0.1
        """
        return min(factor.duration_s for factor in self.factors)

    def __mul__(self, other) -> Effect:
        return Product((*self.factors, _effect(other)))

    __rmul__ = __mul__


@dataclass(frozen=True, slots=True)
class Sequence(Effect):
    """Each part after the one before has ended.

    Examples
    --------
    >>> from ultraglide.render.effects import sample
    >>> steps = Constant(0.2, 0.01) >> Constant(0.4, 0.01)
    >>> isinstance(steps, Sequence), steps.duration_s, sample(steps, [0.005, 0.015, 0.025]).tolist()
    (True, 0.02, [0.2, 0.4, 0.0])
    """

    parts: tuple[Effect, ...]

    def __post_init__(self) -> None:
        for part in self.parts[:-1]:
            if not math.isfinite(part.duration_s):
                raise TextureError("in a sequence, every part but the last needs a finite duration")

    @property
    def duration_s(self) -> float:
        """The parts' durations (s) added.

        Examples
        --------
        >>> (ADSR(0.01, 0.0, 0.0, 0.01) >> Constant(0.2, 0.03)).duration_s        # 20 ms, then 30 ms
        0.05
        """
        return sum(part.duration_s for part in self.parts)

    def __rshift__(self, other: Effect) -> Effect:
        Effect.__rshift__(self, other)  # the checks
        return Sequence((*self.parts, _effect(other)))


@dataclass(frozen=True, slots=True)
class Trigger:
    """When an effect starts, on the texture (mm from its top-left corner, s, mm/s).

    ``on``: ``start`` when the finger lands in (or slides into) ``region_mm``, ``end`` when it lifts or
    leaves, ``while`` for as long as it is down there (and moving at ``min_speed_mm_s`` or faster),
    ``cross`` each time it crosses one of ``lines_mm`` (x positions if ``axis`` is ``x``, else y) inside
    the region, ``event`` when the app reports the event ``name`` (a widget's value changing).
    ``region_mm`` is (x, y, width, height); None: anywhere.

    Raises
    ------
    TextureError
        An unknown ``on``, a region that is not (x, y, width, height) with a positive size, lines out of order,
        an event trigger without a name.

    Examples
    --------
    >>> Trigger("start", region_mm=(0, 0, 10, 5)).region_mm
    (0.0, 0.0, 10.0, 5.0)
    >>> Trigger("cross", lines_mm=(2.0, 1.0))
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: a trigger's lines_mm must be finite and in increasing order
    """

    on: str
    region_mm: tuple[float, float, float, float] | None = None
    min_speed_mm_s: float = 0.0
    lines_mm: tuple[float, ...] = ()
    axis: str = "x"
    name: str = ""

    def __post_init__(self) -> None:
        if self.on not in ON:
            raise TextureError(f"a trigger's 'on' must be one of {', '.join(ON)}, got {self.on!r}")
        if self.region_mm is not None:
            if len(self.region_mm) != 4:
                raise TextureError("a trigger's region_mm is [x, y, width, height] in mm")
            for name, value in zip(("x", "y"), self.region_mm[:2], strict=True):
                _check(f"region {name}", value, -1e6, 1e6, " mm")
            for name, value in zip(("width", "height"), self.region_mm[2:], strict=True):
                _check(f"region {name}", value, 0.0, 1e6, " mm", low_open=True)
            object.__setattr__(self, "region_mm", tuple(float(v) for v in self.region_mm))
        _check("min_speed_mm_s", self.min_speed_mm_s, 0.0, 10000.0, " mm/s")
        if self.axis not in ("x", "y"):
            raise TextureError(f"a trigger's axis is x or y, got {self.axis!r}")
        lines = tuple(float(v) for v in self.lines_mm)
        if self.on == "cross" and not 1 <= len(lines) <= MAX_LINES:
            raise TextureError(f"a cross trigger needs 1 to {MAX_LINES} lines_mm")
        if any(not math.isfinite(v) for v in lines) or list(lines) != sorted(lines):
            raise TextureError("a trigger's lines_mm must be finite and in increasing order")
        object.__setattr__(self, "lines_mm", lines)
        if self.on == "event" and not self.name:
            raise TextureError("an event trigger needs the event's name")


@dataclass(frozen=True, slots=True)
class Binding:
    """An effect and its trigger; ``release_s``: the fade when a ``while`` trigger's condition ends, s.

    Raises
    ------
    TextureError
        A release out of range, an effect without an end on a trigger that plays it once, too many parts.

    Examples
    --------
    >>> click = Binding(Trigger("start"), Square(200.0, 0.5) * Constant(1.0, 0.01), label="click")
    >>> click.trigger.on, click.release_s
    ('start', 0.02)
    >>> Binding(Trigger("start"), Sine(150.0, 0.3))
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: a trigger on 'start' plays its effect once, so the effect needs a ...
    """

    trigger: Trigger
    effect: Effect
    release_s: float = 0.02
    label: str = ""

    def __post_init__(self) -> None:
        _check("release_s", self.release_s, 0.0, MAX_TIME_S, " s")
        if self.trigger.on != "while" and not math.isfinite(self.effect.duration_s):
            raise TextureError(f"a trigger on {self.trigger.on!r} plays its effect once, so the effect needs a "
                               "finite duration: multiply it by an ADSR or a Constant with a length")
        if _count(self.effect) > MAX_NODES:
            raise TextureError(f"an effect may have at most {MAX_NODES} parts")


def _count(effect: Effect) -> int:
    children = getattr(effect, "terms", None) or getattr(effect, "factors", None) or getattr(effect, "parts", None)
    return 1 + sum(_count(child) for child in children or ())

