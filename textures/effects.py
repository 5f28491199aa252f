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

# the types and the saved description live in their own modules; every name is importable from here
from ultraglide.textures.effect_types import (  # noqa: F401
    ADSR,
    EFFECTS_VERSION,
    MAX_BINDINGS,
    MAX_FREQUENCY_HZ,
    MAX_LINES,
    MAX_NODES,
    MAX_TIME_S,
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
from ultraglide.textures.effects_file import (  # noqa: F401
    binding_to_dict,
    effect_from_dict,
    effect_to_dict,
    from_json,
    load_effects,
    to_json,
)
from ultraglide.textures.errors import TextureError


# ---- a few effects for interfaces (what the demo's widgets play) ------------------------------------------
def click(depth: float = 0.5) -> Effect:
    """A button's click: a 250 Hz square burst under a 15 ms envelope (friction drops by up to ``depth``).

    Parameters
    ----------
    depth : float
        The largest drop in friction ratio.

    Returns
    -------
    Effect

    Examples
    --------
    >>> round(click().duration_s, 6)                                   # s: 1 + 4 + 0 + 10 ms
    0.015
    """
    return Square(250.0, depth) * ADSR(0.001, 0.004, 0.0, 0.010, sustain_level=0.5)


def pulse(depth: float = 0.4, length_s: float = 0.012) -> Effect:
    """A detent's pulse: friction ``depth`` lower for ``length_s``.

    Parameters
    ----------
    depth : float
        The drop in friction ratio.
    length_s : float
        How long (s).

    Returns
    -------
    Effect

    Examples
    --------
    >>> pulse(0.4, 0.012)
    Constant(level=0.4, length_s=0.012)
    """
    return Constant(depth, length_s)


def buzz(frequency_hz: float = 150.0, depth: float = 0.25) -> Effect:
    """A buzz for as long as it is held (bind it to a ``while`` trigger).

    Parameters
    ----------
    frequency_hz : float
        The buzz's frequency (Hz).
    depth : float
        The largest drop in friction ratio.

    Returns
    -------
    Effect

    Examples
    --------
    >>> buzz(150.0, 0.25).duration_s                                    # until released
    inf
    """
    return Sine(frequency_hz, depth)


def snap(depth: float = 0.6) -> Effect:
    """A toggle's snap: two sharp drops 20 ms apart.

    Parameters
    ----------
    depth : float
        The largest drop in friction ratio.

    Returns
    -------
    Effect

    Examples
    --------
    >>> round(snap().duration_s, 6)                                    # s: 12 + 8 + 12 ms
    0.032
    """
    hit = Sawtooth(100.0, depth) * ADSR(0.0, 0.0, 0.008, 0.004, sustain_level=1.0)
    return hit >> Constant(0.0, 0.008) >> hit


# ---- effects when textures are combined ---------------------------------------------------------------------
def moved(bindings, dx_mm: float, dy_mm: float, region_mm: tuple[float, float, float, float] | None = None,
          ) -> tuple[Binding, ...]:
    """``bindings`` for a texture whose top-left corner moves to (``dx_mm``, ``dy_mm``): regions and crossing
    lines shifted with it. A binding that played anywhere plays in ``region_mm`` (where the texture now lies),
    or still anywhere if that is None.

    Parameters
    ----------
    bindings : iterable of Binding
    dx_mm, dy_mm : float
        The move (mm).
    region_mm : (float, float, float, float), optional
        x, y, width, height (mm) where the texture now lies.

    Returns
    -------
    tuple of Binding

    Examples
    --------
    >>> held = Binding(Trigger("while", region_mm=(0.0, 0.0, 5.0, 5.0)), buzz())
    >>> moved([held], 10.0, 20.0)[0].trigger.region_mm
    (10.0, 20.0, 5.0, 5.0)
    """
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
    """Every binding of ``groups`` in order, each once (an input given twice brings its effects once).

    Parameters
    ----------
    *groups : iterable of Binding

    Returns
    -------
    tuple of Binding

    Raises
    ------
    TextureError
        More than the :data:`MAX_BINDINGS` a texture keeps.

    Examples
    --------
    >>> clicks = (Binding(Trigger("start"), click()),)
    >>> len(combined(clicks, clicks))
    1
    """
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
