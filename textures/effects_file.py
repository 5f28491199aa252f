"""Temporal effects as saved: the versioned JSON description a texture file keeps in its metadata (or an
effects file holds), both ways, validated with ranges and one-line :class:`TextureError`.
Re-exported by :mod:`ultraglide.textures.effects`.
"""

from __future__ import annotations

import math

from ultraglide.textures.effect_types import (
    ADSR,
    EFFECTS_VERSION,
    MAX_BINDINGS,
    ON,
    Binding,
    Constant,
    Effect,
    Oscillator,
    Product,
    Sawtooth,
    Sequence,
    Sine,
    Square,
    Sum,
    Triangle,
    Trigger,
)
from ultraglide.textures.errors import TextureError

_OSCILLATORS = {"sine": Sine, "square": Square, "sawtooth": Sawtooth, "triangle": Triangle}
_NAMES = {cls: name for name, cls in _OSCILLATORS.items()}


def effect_to_dict(effect: Effect) -> dict:
    """An effect as the JSON of an effects file holds it (:func:`effect_from_dict` reads it back).

    Parameters
    ----------
    effect : Effect

    Returns
    -------
    dict
        ``type`` and the effect's fields (Hz, s, ratios); compositions nest their parts.

    Examples
    --------
    >>> from ultraglide.textures.effect_types import Constant, Sine
    >>> effect_to_dict(Sine(10.0, 0.2) + Constant(0.1, 2.0))
    ... # doctest: +NORMALIZE_WHITESPACE
    {'type': 'sum', 'terms': [{'type': 'sine', 'frequency_hz': 10.0, 'depth': 0.2},
                              {'type': 'constant', 'level': 0.1, 'length_s': 2.0}]}
    """
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
    """An effect from its description (what :func:`effect_to_dict` writes).

    Parameters
    ----------
    data : dict
        ``type`` and the effect's fields (Hz, s, ratios); compositions nest their parts.

    Returns
    -------
    Effect

    Raises
    ------
    TextureError
        An unknown type, a field missing or out of range, in one line.

    Examples
    --------
    >>> effect_from_dict({"type": "sine", "frequency_hz": 10.0, "depth": 0.2})
    Sine(frequency_hz=10.0, depth=0.2)
    >>> effect_from_dict({"type": "wobble"})                           # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: unknown effect type 'wobble' (sine, square, sawtooth, triangle, ...)
    """
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
    """A binding (its trigger, effect and release) as the JSON of an effects file holds it; the trigger's
    defaults left out.

    Parameters
    ----------
    binding : Binding

    Returns
    -------
    dict

    Examples
    --------
    >>> from ultraglide.textures.effect_types import ADSR, Binding, Trigger
    >>> binding_to_dict(Binding(Trigger("start"), ADSR(0.01, 0.02, 0.1, 0.05)))["trigger"]
    {'on': 'start'}
    """
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
    """The versioned description kept in a texture file's metadata (plain JSON values).

    Parameters
    ----------
    bindings : iterable of Binding

    Returns
    -------
    dict
        ``effects_version`` and the ``bindings``' descriptions.

    Examples
    --------
    >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
    >>> to_json([Binding(Trigger("start"), Constant(0.3, 0.05))])["effects_version"]
    1
    """
    return {"effects_version": EFFECTS_VERSION, "bindings": [binding_to_dict(b) for b in bindings]}


def from_json(data, where: str = "effects") -> tuple[Binding, ...]:
    """Bindings from :func:`to_json`'s description.

    Parameters
    ----------
    data : dict
        The description.
    where : str
        What to name in a refusal (a file, a chunk).

    Returns
    -------
    tuple of Binding

    Raises
    ------
    TextureError
        A bad description, naming ``where`` and what is wrong, in one line.

    Examples
    --------
    >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
    >>> bindings = (Binding(Trigger("start"), Constant(0.3, 0.05)),)
    >>> from_json(to_json(bindings)) == bindings                        # read back as written
    True
    """
    try:
        if not isinstance(data, dict):
            raise TextureError("the effects description must be a JSON object")
        version = data.get("effects_version")
        if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= EFFECTS_VERSION:
            raise TextureError(f"effects version {version!r} is not one this ultraglide reads (up to "
                               f"{EFFECTS_VERSION}); upgrade ultraglide")
        unknown = sorted(set(data) - {"effects_version", "bindings"}, key=str)
        if unknown:
            raise TextureError(f"unknown field {unknown[0]!r} (an effects description holds effects_version and "
                               "bindings)")
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
    """Bindings from a JSON file holding :func:`to_json`'s description. A designer's file (``.ahap``,
    ``.haptic``, ``.hjif``, ``.haps``) is read by
    :func:`ultraglide.textures.formats.effects_in.load_designer_effects`.

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file; a path that is not a regular file is refused without being read.

    Returns
    -------
    tuple of Binding

    Raises
    ------
    TextureError
        A file that cannot be read or a bad description, in one line.

    Examples
    --------
    >>> import json, os, tempfile
    >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
    >>> path = os.path.join(tempfile.mkdtemp(), "effects.json")
    >>> with open(path, "w") as file:
    ...     json.dump(to_json([Binding(Trigger("start"), Constant(0.3, 0.05))]), file)
    >>> load_effects(path)[0].effect
    Constant(level=0.3, length_s=0.05)
    """
    from ultraglide.inputs import parse_json, read_input

    if str(path).lower().endswith((".ahap", ".haptic", ".hjif", ".haps")):
        from ultraglide.textures.formats.effects_in import load_designer_effects

        return load_designer_effects(path)

    data = parse_json(read_input(path, "effects file", TextureError), str(path), TextureError, what="effects file")
    return from_json(data, where=str(path))


def _binding_from_dict(item) -> Binding:
    if not isinstance(item, dict) or not isinstance(item.get("trigger"), dict) or "effect" not in item:
        raise TextureError("each binding is an object with a 'trigger' object and an 'effect'")
    unknown = sorted(set(item) - {"trigger", "effect", "release_s", "label"}, key=str)
    if unknown:  # a misspelt release_s would otherwise be the default, silently
        raise TextureError(f"unknown field {unknown[0]!r} (a binding takes trigger, effect, release_s and label)")
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

