"""Temporal friction effects as values: what they are and how they are saved (evaluation: ``render.effects``).

An effect's value at time t (s since it was triggered) is a **drop in friction ratio**: 0 = no effect,
0.3 = the friction ratio 0.3 lower than the texture's there; a negative value raises friction where
the texture is below 1. The renderer subtracts it from the texture's ratio before the model inverse and
clips the result to what the model reaches, so effects pass the same envelope and limiter as textures.

Effects compose as Syntacts composes signals::

    >>> click = Square(200.0, 0.5) * ADSR(attack_s=0.001, decay_s=0.004, sustain_s=0.0, release_s=0.01)
    >>> buzz = Sine(150.0, 0.3)
    >>> round(click.duration_s, 3), buzz.duration_s
    (0.015, inf)
    >>> twice = click >> Constant(0.0, 0.02) >> click     # a double click, 20 ms apart
    >>> round(twice.duration_s, 3)
    0.05

Oscillators start at no effect and swing between 0 and ``depth`` (a sine: depth·(1 − cos 2πft)/2).
``+`` sums, ``*`` multiplies (a number scales), ``>>`` plays one after the other. An effect ends when
its duration is over (oscillators last for ever; a product lasts as long as its shortest factor).

A :class:`Binding` says when an effect plays: a :class:`Trigger` (the finger landing or lifting in a
region, moving in it, crossing lines, or a named event from the app) and, for ``while`` triggers, the
release when the condition ends. A texture file keeps its bindings in its metadata as a versioned JSON
description (:func:`to_json`, :func:`from_json`), validated with ranges and one-line errors.
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
    """The composable part every effect shares: ``+``, ``*`` (or a number), ``>>``."""

    __slots__ = ()

    @property
    def duration_s(self) -> float:
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
    """Shared by the periodic effects: ``frequency_hz`` (Hz) and ``depth`` (friction ratio, −1..1)."""

    frequency_hz: float
    depth: float

    def __post_init__(self) -> None:
        _check("frequency_hz", self.frequency_hz, 0.0, MAX_FREQUENCY_HZ, " Hz", low_open=True)
        _check("depth", self.depth, -1.0, 1.0)

    @property
    def duration_s(self) -> float:
        return math.inf


@dataclass(frozen=True, slots=True)
class Sine(Oscillator):
    """depth·(1 − cos 2πft)/2: from 0 to depth and back, once a period."""


@dataclass(frozen=True, slots=True)
class Square(Oscillator):
    """0 for the first half of each period, depth for the second."""


@dataclass(frozen=True, slots=True)
class Sawtooth(Oscillator):
    """Rises from 0 to depth over each period, then drops back."""


@dataclass(frozen=True, slots=True)
class Triangle(Oscillator):
    """Rises from 0 to depth over half a period and back over the other half."""


@dataclass(frozen=True, slots=True)
class Constant(Effect):
    """``level`` (friction ratio, −1..1) for ``length_s`` (s; for ever by default): a step, or a pulse."""

    level: float
    length_s: float = math.inf

    def __post_init__(self) -> None:
        _check("level", self.level, -1.0, 1.0)
        if self.length_s != math.inf:
            _check("length_s", self.length_s, 0.0, MAX_TIME_S, " s", low_open=True)

    @property
    def duration_s(self) -> float:
        return self.length_s


@dataclass(frozen=True, slots=True)
class ADSR(Effect):
    """Linear attack to ``peak``, decay to ``sustain_level``·peak, held for ``sustain_s``, release to 0 (s)."""

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
        return self.attack_s + self.decay_s + self.sustain_s + self.release_s


@dataclass(frozen=True, slots=True)
class Sum(Effect):
    terms: tuple[Effect, ...]

    @property
    def duration_s(self) -> float:
        return max(term.duration_s for term in self.terms)

    def __add__(self, other: Effect) -> Effect:  # flat: a + b + c is one sum
        return Sum((*self.terms, _effect(other)))


@dataclass(frozen=True, slots=True)
class Product(Effect):
    factors: tuple[Effect, ...]

    @property
    def duration_s(self) -> float:
        return min(factor.duration_s for factor in self.factors)

    def __mul__(self, other) -> Effect:
        return Product((*self.factors, _effect(other)))

    __rmul__ = __mul__


@dataclass(frozen=True, slots=True)
class Sequence(Effect):
    """Each part after the one before has ended."""

    parts: tuple[Effect, ...]

    def __post_init__(self) -> None:
        for part in self.parts[:-1]:
            if not math.isfinite(part.duration_s):
                raise TextureError("in a sequence, every part but the last needs a finite duration")

    @property
    def duration_s(self) -> float:
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
    """An effect and its trigger; ``release_s``: the fade when a ``while`` trigger's condition ends, s."""

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


# ---- the saved description -------------------------------------------------------------------------------
_OSCILLATORS = {"sine": Sine, "square": Square, "sawtooth": Sawtooth, "triangle": Triangle}
_NAMES = {cls: name for name, cls in _OSCILLATORS.items()}


def effect_to_dict(effect: Effect) -> dict:
    if isinstance(effect, Oscillator):
        return {"type": _NAMES[type(effect)], "frequency_hz": effect.frequency_hz, "depth": effect.depth}
    if isinstance(effect, Constant):
        out = {"type": "constant", "level": effect.level}
        if math.isfinite(effect.length_s):
            out["length_s"] = effect.length_s
        return out
    if isinstance(effect, ADSR):
        return {"type": "adsr", "attack_s": effect.attack_s, "decay_s": effect.decay_s, "sustain_s": effect.sustain_s,
                "release_s": effect.release_s, "peak": effect.peak, "sustain_level": effect.sustain_level}
    for cls, key in ((Sum, "terms"), (Product, "factors"), (Sequence, "parts")):
        if isinstance(effect, cls):
            return {"type": cls.__name__.lower(), key: [effect_to_dict(child) for child in getattr(effect, key)]}
    raise TextureError(f"not an effect: {effect!r}")


def effect_from_dict(data, depth: int = 0) -> Effect:
    """An effect from its description; TextureError (one line) for a bad one."""
    if depth > 16:
        raise TextureError("effect descriptions may nest at most 16 deep")
    if not isinstance(data, dict) or not isinstance(data.get("type"), str):
        raise TextureError("each effect is an object with a 'type' (sine, square, sawtooth, triangle, constant, adsr, "
                           "sum, product, sequence)")
    kind = data["type"]
    fields = {key: value for key, value in data.items() if key != "type"}
    try:
        if kind in _OSCILLATORS:
            return _OSCILLATORS[kind](**_only(fields, kind, ("frequency_hz", "depth")))
        if kind == "constant":
            return Constant(**_only(fields, kind, ("level", "length_s")))
        if kind == "adsr":
            return ADSR(**_only(fields, kind, ("attack_s", "decay_s", "sustain_s", "release_s", "peak",
                                               "sustain_level")))
        for cls, key in ((Sum, "terms"), (Product, "factors"), (Sequence, "parts")):
            if kind == cls.__name__.lower():
                children = _only(fields, kind, (key,)).get(key)
                if not isinstance(children, list) or not children:
                    raise TextureError(f"a {kind} effect needs a non-empty list '{key}'")
                return cls(tuple(effect_from_dict(child, depth + 1) for child in children))
    except TypeError as error:  # a missing field
        raise TextureError(f"{kind} effect: {str(error).split('__init__() ')[-1]}") from None
    raise TextureError(f"unknown effect type {kind!r} (sine, square, sawtooth, triangle, constant, adsr, sum, "
                       "product, sequence)")


def _only(fields: dict, kind: str, allowed: tuple[str, ...]) -> dict:
    unknown = sorted(set(fields) - set(allowed))
    if unknown:
        raise TextureError(f"{kind} effect: unknown field {unknown[0]!r} (it takes {', '.join(allowed)})")
    return fields


def binding_to_dict(binding: Binding) -> dict:
    t = binding.trigger
    trigger = {"on": t.on}
    if t.region_mm is not None:
        trigger["region_mm"] = list(t.region_mm)
    if t.min_speed_mm_s:
        trigger["min_speed_mm_s"] = t.min_speed_mm_s
    if t.lines_mm:
        trigger["lines_mm"], trigger["axis"] = list(t.lines_mm), t.axis
    if t.name:
        trigger["name"] = t.name
    out = {"trigger": trigger, "effect": effect_to_dict(binding.effect), "release_s": binding.release_s}
    if binding.label:
        out["label"] = binding.label
    return out


def to_json(bindings) -> dict:
    """The versioned description kept in a texture file's metadata (plain JSON values)."""
    return {"effects_version": EFFECTS_VERSION, "bindings": [binding_to_dict(b) for b in bindings]}


def from_json(data, where: str = "effects") -> tuple[Binding, ...]:
    """Bindings from :func:`to_json`'s description; TextureError naming ``where`` and what is wrong."""
    try:
        if not isinstance(data, dict):
            raise TextureError("the effects description must be a JSON object")
        version = data.get("effects_version")
        if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= EFFECTS_VERSION:
            raise TextureError(f"effects version {version!r} is not one this ultraglide reads (up to "
                               f"{EFFECTS_VERSION}); upgrade ultraglide")
        bindings = data.get("bindings")
        if not isinstance(bindings, list) or len(bindings) > MAX_BINDINGS:
            raise TextureError(f"'bindings' must be a list of at most {MAX_BINDINGS}")
        out = []
        for k, item in enumerate(bindings):
            try:
                out.append(_binding_from_dict(item))
            except TextureError as error:
                raise TextureError(f"binding {k + 1}: {error}") from None
        return tuple(out)
    except TextureError as error:
        raise TextureError(f"{where}: {error}") from None


def load_effects(path) -> tuple[Binding, ...]:
    """Bindings from a JSON file holding :func:`to_json`'s description; one-line TextureError for a bad one
    (a path that is not a regular file is refused without being read)."""
    from ultraglide.inputs import parse_json, read_input

    data = parse_json(read_input(path, "effects file", TextureError), str(path), TextureError, what="effects file")
    return from_json(data, where=str(path))


def _binding_from_dict(item) -> Binding:
    if not isinstance(item, dict) or not isinstance(item.get("trigger"), dict) or "effect" not in item:
        raise TextureError("each binding is an object with a 'trigger' object and an 'effect'")
    trigger = dict(item["trigger"])
    unknown = sorted(set(trigger) - {"on", "region_mm", "min_speed_mm_s", "lines_mm", "axis", "name"})
    if unknown:
        raise TextureError(f"trigger: unknown field {unknown[0]!r}")
    if "on" not in trigger:
        raise TextureError(f"trigger: 'on' is missing (one of {', '.join(ON)})")
    for key in ("region_mm", "lines_mm"):
        if key in trigger and trigger[key] is not None:
            if not isinstance(trigger[key], list) or not all(isinstance(v, int | float) for v in trigger[key]):
                raise TextureError(f"trigger: {key} must be a list of numbers")
            trigger[key] = tuple(trigger[key])
    if not isinstance(trigger.get("name", ""), str):
        raise TextureError("trigger: name must be a string")
    release = item.get("release_s", 0.02)
    return Binding(Trigger(**trigger), effect_from_dict(item["effect"]), release, str(item.get("label", "")))


# ---- a few effects for interfaces (what the demo's widgets play) ------------------------------------------
def click(depth: float = 0.5) -> Effect:
    """A button's click: a 250 Hz square burst under a 15 ms envelope (friction drops by up to ``depth``)."""
    return Square(250.0, depth) * ADSR(0.001, 0.004, 0.0, 0.010, sustain_level=0.5)


def pulse(depth: float = 0.4, length_s: float = 0.012) -> Effect:
    """A detent's pulse: friction ``depth`` lower for ``length_s``."""
    return Constant(depth, length_s)


def buzz(frequency_hz: float = 150.0, depth: float = 0.25) -> Effect:
    """A buzz for as long as it is held (bind it to a ``while`` trigger)."""
    return Sine(frequency_hz, depth)


def snap(depth: float = 0.6) -> Effect:
    """A toggle's snap: two sharp drops 20 ms apart."""
    hit = Sawtooth(100.0, depth) * ADSR(0.0, 0.0, 0.008, 0.004, sustain_level=1.0)
    return hit >> Constant(0.0, 0.008) >> hit


# ---- effects when textures are combined ---------------------------------------------------------------------
def moved(bindings, dx_mm: float, dy_mm: float, region_mm: tuple[float, float, float, float] | None = None,
          ) -> tuple[Binding, ...]:
    """``bindings`` for a texture whose top-left corner moves to (``dx_mm``, ``dy_mm``): regions and crossing
    lines shifted with it. A binding that played anywhere plays in ``region_mm`` (where the texture now lies),
    or still anywhere if that is None."""
    out = []
    for binding in bindings:
        t = binding.trigger
        if t.region_mm is None:
            region = region_mm
        else:
            x, y, w, h = t.region_mm
            region = (x + dx_mm, y + dy_mm, w, h)
        lines = tuple(v + (dx_mm if t.axis == "x" else dy_mm) for v in t.lines_mm)
        trigger = Trigger(t.on, region, t.min_speed_mm_s, lines, t.axis, t.name)
        out.append(Binding(trigger, binding.effect, binding.release_s, binding.label))
    return tuple(out)


def combined(*groups) -> tuple[Binding, ...]:
    """Every binding of ``groups`` in order, each once (an input given twice brings its effects once);
    TextureError beyond the :data:`MAX_BINDINGS` a texture keeps."""
    out, seen = [], set()
    for binding in (binding for group in groups for binding in group):
        key = repr(binding_to_dict(binding))
        if key not in seen:
            seen.add(key)
            out.append(binding)
    if len(out) > MAX_BINDINGS:
        raise TextureError(f"the inputs have {len(out)} temporal effects together, more than the {MAX_BINDINGS} a "
                           "texture keeps; leave them out (texture.with_(effects=()), or --no-effects) or attach fewer")
    return tuple(out)
