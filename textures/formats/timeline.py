"""A designer's effect as a friction display plays it: the common ground of the AHAP, Meta and MPEG readers.

Each reader turns its file into a :class:`Timeline`: **segments** (a stretch of time over which the drop in
friction ratio goes linearly from one depth to another, either directly or as the depth of a modulation at a
frequency) and **pulses** (a short drop for a transient), plus **notes**: what the file asks that a friction
display cannot render, each said in words (never dropped silently). :meth:`Timeline.bindings` builds
ultraglide's temporal effects from it (:mod:`ultraglide.textures.effects`), played from the moment the finger
lands (a ``start`` trigger, anywhere).

The mappings, in one place:

- **intensity → depth**: an intensity of 1 is a friction ratio 1 lower (as slippery as the plate goes; the
  renderer clips to what the friction model reaches), 0 no change: ``depth = intensity`` (``full_depth`` scales);
- **sharpness (0..1) → modulation frequency**: ``SHARPNESS_LOW_HZ + sharpness × (SHARPNESS_HIGH_HZ −
  SHARPNESS_LOW_HZ)``, 50 to 300 Hz, inside what a plate's amplitude envelope follows (about 400 Hz with the
  drive's pre-compensation, docs/design.md); a frequency a file gives in Hz above :data:`RENDERABLE_MAX_HZ` is
  played at that limit, and said;
- **transient → pulse**: a drop of the transient's depth lasting ``PULSE_LONGEST_S − sharpness ×
  (PULSE_LONGEST_S − PULSE_SHORTEST_S)``: 20 ms when dull, 5 ms when sharp;
- a modulation is ``depth · (1 − cos 2πft)/2`` (:class:`~ultraglide.textures.effects.Sine`): it swings from no
  change to the full depth; its phase starts again at each breakpoint where the frequency changes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ultraglide.textures.effect_types import (
    ADSR,
    MAX_BINDINGS,
    MAX_NODES,
    MAX_TIME_S,
    Binding,
    Constant,
    Effect,
    Sequence,
    Sine,
    Sum,
    Trigger,
)
from ultraglide.textures.errors import TextureError

SHARPNESS_LOW_HZ = 50.0
SHARPNESS_HIGH_HZ = 300.0
RENDERABLE_MAX_HZ = 400.0
RENDERABLE_MIN_HZ = 1.0  # below this a "modulation" is a slow change of the level: played as the level itself
PULSE_LONGEST_S = 0.020
PULSE_SHORTEST_S = 0.005
MAX_EVENTS = 10_000  # events, keyframes or breakpoints a file may have before it is refused unread further
SHORTEST_S = 1e-4  # segments shorter than 0.1 ms are below the control rate's resolution: merged away


def sharpness_hz(sharpness: float) -> float:
    """The modulation frequency for a sharpness in 0..1: 50 Hz (dull) to 300 Hz (sharp), linearly.

    Parameters
    ----------
    sharpness : float
        0..1 (clipped).

    Returns
    -------
    float
        The frequency, Hz.

    Examples
    --------
    >>> sharpness_hz(0.0), sharpness_hz(0.5), sharpness_hz(2.0)
    (50.0, 175.0, 300.0)
    """
    return SHARPNESS_LOW_HZ + min(max(sharpness, 0.0), 1.0) * (SHARPNESS_HIGH_HZ - SHARPNESS_LOW_HZ)


def pulse_length_s(sharpness: float) -> float:
    """A transient's pulse length for a sharpness in 0..1: 20 ms (dull) to 5 ms (sharp), linearly.

    Parameters
    ----------
    sharpness : float
        0..1 (clipped).

    Returns
    -------
    float
        The pulse's length, s.

    Examples
    --------
    >>> [round(pulse_length_s(sharpness), 6) for sharpness in (0.0, 0.5, 1.0)]
    [0.02, 0.0125, 0.005]
    """
    return PULSE_LONGEST_S - min(max(sharpness, 0.0), 1.0) * (PULSE_LONGEST_S - PULSE_SHORTEST_S)


@dataclass(frozen=True)
class Segment:
    """From ``start_s`` for ``length_s``, the friction drop goes from ``depth0`` to ``depth1`` (linearly); as the
    depth of a modulation at ``frequency_hz``, or directly when that is None.

    Examples
    --------
    A ramp of the friction drop from 0 to 0.5 over 100 ms, then the ramp as a 50 Hz modulation's depth:

    >>> ramp = Segment(0.0, 0.1, 0.0, 0.5)
    >>> ramp.start_s + ramp.length_s, ramp.frequency_hz, Segment(0.1, 0.1, 0.5, 0.5, 50.0).frequency_hz
    (0.1, None, 50.0)
    """

    start_s: float
    length_s: float
    depth0: float
    depth1: float
    frequency_hz: float | None = None


@dataclass(frozen=True)
class Pulse:
    """A transient: from ``start_s``, the friction drops by ``depth`` (0..1) for ``length_s`` (s).

    Parameters
    ----------
    start_s : float
        When it starts, s from the effect's start.
    depth : float
        The friction drop, 0..1.
    length_s : float
        How long it lasts, s.

    Examples
    --------
    >>> pulse = Pulse(0.1, 0.8, pulse_length_s(1.0))
    >>> round(pulse.start_s + pulse.length_s, 6)     # ends 5 ms after it starts
    0.105
    """
    start_s: float
    depth: float
    length_s: float


@dataclass
class Timeline:
    """Segments, pulses and notes (what is not rendered) read from a designer's file.

    Examples
    --------
    >>> timeline = Timeline("tap.ahap", pulses=[Pulse(0.0, 0.8, pulse_length_s(1.0))])
    >>> timeline.where, len(timeline.pulses), timeline.segments, timeline.notes
    ('tap.ahap', 1, [], [])
    """

    where: str
    segments: list[Segment] = field(default_factory=list)
    pulses: list[Pulse] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def note(self, text: str) -> None:
        """Say once what of the file is not rendered (a repeated note is kept once).

        Parameters
        ----------
        text : str
            The note, in words.

        Returns
        -------
        None

        Examples
        --------
        >>> timeline = Timeline("tap.ahap")
        >>> timeline.note("audio events are not rendered"); timeline.note("audio events are not rendered")
        >>> timeline.notes
        ['audio events are not rendered']
        """
        if text not in self.notes:
            self.notes.append(text)

    def frequency(self, hz: float) -> float:
        """A frequency a file gives (Hz), within what the plate renders; a note when it is not.

        Parameters
        ----------
        hz : float
            The file's frequency, Hz.

        Returns
        -------
        float
            Hz, at most :data:`RENDERABLE_MAX_HZ`.

        Examples
        --------
        >>> timeline = Timeline("buzz.ahap")
        >>> timeline.frequency(150.0), timeline.frequency(5000.0), len(timeline.notes)
        (150.0, 400.0, 1)
        """
        if hz > RENDERABLE_MAX_HZ:
            self.note(f"modulation above {RENDERABLE_MAX_HZ:g} Hz (up to {hz:g} Hz) is played at "
                      f"{RENDERABLE_MAX_HZ:g} Hz, the most a plate's envelope follows")
            return RENDERABLE_MAX_HZ
        return hz

    def add_envelope(self, start_s: float, times_s, depths, frequencies=None) -> None:
        """Breakpoints (times from ``start_s``, s; depths 0..1; a frequency per stretch between them, Hz or None).
        A breakpoint on the straight line between its neighbours (within 1e-4, and of one frequency) is left out.

        Parameters
        ----------
        start_s : float
            When the envelope starts, s.
        times_s : sequence of float
            Breakpoints' times from ``start_s``, s.
        depths : sequence of float
            Depths at the breakpoints, 0..1.
        frequencies : sequence of float or None, optional
            A frequency per stretch between breakpoints, Hz.

        Examples
        --------
        A ramp whose middle breakpoint lies on the line between the others is one segment:

        >>> timeline = Timeline("ramp.ahap")
        >>> timeline.add_envelope(0.0, [0.0, 0.05, 0.1], [0.0, 0.5, 1.0])
        >>> timeline.segments
        [Segment(start_s=0.0, length_s=0.1, depth0=0.0, depth1=1.0, frequency_hz=None)]
        """
        keep = [0]
        for k in range(1, len(times_s) - 1):
            a, b = keep[-1], k + 1
            span = times_s[b] - times_s[a]
            between = depths[a] + (depths[b] - depths[a]) * ((times_s[k] - times_s[a]) / span if span > 0 else 0.0)
            same = frequencies is None or frequencies[k - 1] == frequencies[k]
            if not (same and abs(depths[k] - between) <= 1e-4):
                keep.append(k)
        keep.append(len(times_s) - 1)
        if frequencies is not None:
            frequencies = [frequencies[k] for k in keep[:-1]]
        times_s, depths = [times_s[k] for k in keep], [depths[k] for k in keep]
        for k in range(len(times_s) - 1):
            length = times_s[k + 1] - times_s[k]
            if length < SHORTEST_S:
                continue
            frequency = None if frequencies is None else frequencies[k]
            if frequency is not None and frequency < RENDERABLE_MIN_HZ:
                frequency = None
            self.segments.append(Segment(start_s + times_s[k], length, depths[k], depths[k + 1], frequency))

    def bindings(self, label: str) -> tuple[Binding, ...]:
        """ultraglide's temporal effects for this timeline (:data:`MAX_BINDINGS` at most, each of
        :data:`MAX_NODES` parts at most); TextureError in one line when the file holds more than that.

        Parameters
        ----------
        label : str
            The bindings' label.

        Returns
        -------
        tuple of Binding

        Raises
        ------
        TextureError
            More effects or parts than ultraglide plays, in one line naming the file.

        Examples
        --------
        One pulse of depth 0.8 plays from the start:

        >>> binding, = Timeline("tap.ahap", pulses=[Pulse(0.0, 0.8, pulse_length_s(1.0))]).bindings("tap")
        >>> binding.trigger.on, binding.effect.level, binding.label
        ('start', 0.8, 'tap')
        """
        try:
            return self._bindings(label)
        except TextureError as error:
            text = str(error)
            raise TextureError(text if text.startswith(self.where) else f"{self.where}: {text}") from None

    def _bindings(self, label: str) -> tuple[Binding, ...]:
        pieces = [(start, effect, _count(effect)) for start, effect in self._pieces()]
        pieces.sort(key=lambda piece: piece[0])
        groups: list[list] = []
        used = 0
        for start, effect, count in pieces:
            cost = count + (2 if start > 0 else 0)
            if not groups or used + cost + 1 > MAX_NODES:
                groups.append([])
                used = 0
            groups[-1].append((start, effect))
            used += cost
        if len(groups) > MAX_BINDINGS:
            raise TextureError(f"{self.where}: too many events for ultraglide's temporal effects ({len(pieces)} parts "
                               f"need {len(groups)} bindings, at most {MAX_BINDINGS}); shorten or simplify it")
        out = []
        for number, group in enumerate(groups, 1):
            parts = [_delayed(start, effect, self.where) for start, effect in group]
            effect = parts[0] if len(parts) == 1 else Sum(tuple(parts))
            name = label if len(groups) == 1 else f"{label} ({number}/{len(groups)})"
            out.append(Binding(Trigger("start"), effect, label=name))
        return tuple(out)

    def _pieces(self):
        """(start, effect): runs of segments of one frequency as one piece, and each pulse."""
        run: list[Segment] = []

        def flush():
            if run:
                yield run[0].start_s, _run_effect(run)
                run.clear()

        for segment in sorted(self.segments, key=lambda s: s.start_s):
            if segment.depth0 == 0 and segment.depth1 == 0:
                yield from flush()
                continue
            if run and (run[-1].frequency_hz != segment.frequency_hz
                        or abs(run[-1].start_s + run[-1].length_s - segment.start_s) > SHORTEST_S
                        or len(run) >= 12):
                yield from flush()
            run.append(segment)
        yield from flush()
        for pulse in self.pulses:
            if pulse.depth > 0:
                yield pulse.start_s, Constant(_depth(pulse.depth), pulse.length_s)


def _depth(value: float) -> float:
    return min(max(float(value), -1.0), 1.0)


def _ramp(segment: Segment) -> Effect:
    """The segment's depth going linearly from depth0 to depth1 over its length."""
    d0, d1 = _depth(segment.depth0), _depth(segment.depth1)
    if abs(d1 - d0) < 1e-6:
        return Constant(d0, segment.length_s)
    ramp = ADSR(segment.length_s, 0.0, 0.0, 0.0, peak=d1 - d0, sustain_level=1.0)
    return ramp if d0 == 0 else Sum((Constant(d0, segment.length_s), ramp))


def _run_effect(run: list[Segment]) -> Effect:
    envelope = _ramp(run[0]) if len(run) == 1 else Sequence(tuple(_ramp(segment) for segment in run))
    if run[0].frequency_hz is None:
        return envelope
    return Sine(run[0].frequency_hz, 1.0) * envelope


def _delayed(start: float, effect: Effect, where: str) -> Effect:
    if start <= 0:
        return effect
    if start > MAX_TIME_S:
        raise TextureError(f"{where}: an event at {start:g} s; ultraglide's effects last at most {MAX_TIME_S:g} s")
    return Sequence((Constant(0.0, start), effect))


def _count(effect: Effect) -> int:
    children = getattr(effect, "terms", None) or getattr(effect, "factors", None) or getattr(effect, "parts", None)
    return 1 + sum(_count(child) for child in children or ())


def number(value, where: str, low: float = -math.inf, high: float = math.inf) -> float:
    """A finite number in ``low..high`` from a file, or one line naming ``where``.

    Parameters
    ----------
    value : object
        What the file holds (a bool is not a number).
    where : str
        Where in the file, for the message.
    low, high : float
        The range, inclusive.

    Returns
    -------
    float

    Raises
    ------
    TextureError
        Not a finite number in range.

    Examples
    --------
    >>> number(3, "event 1's Time", 0.0)
    3.0
    >>> number(True, "event 1's Time", 0.0)
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: event 1's Time must be a finite number from 0 to inf, got True
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
            or not low <= value <= high:
        raise TextureError(f"{where} must be a finite number from {low:g} to {high:g}, got {value!r}")
    return float(value)


def interpolate(times, values, at: float) -> float:
    """Piecewise-linear value of breakpoints (``times`` increasing) at ``at``; held beyond the ends.

    Parameters
    ----------
    times : sequence of float
        The breakpoints' times, s, increasing (empty: the value is 1).
    values : sequence of float
        The value at each.
    at : float
        The time wanted, s.

    Returns
    -------
    float

    Examples
    --------
    >>> interpolate([0.0, 1.0], [0.0, 0.5], 0.5), interpolate([0.0, 1.0], [0.0, 0.5], 2.0), interpolate([], [], 0.3)
    (0.25, 0.5, 1.0)
    """
    if not times:
        return 1.0
    if at <= times[0]:
        return values[0]
    for k in range(1, len(times)):
        if at <= times[k]:
            span = times[k] - times[k - 1]
            part = 0.0 if span <= 0 else (at - times[k - 1]) / span
            return values[k - 1] + part * (values[k] - values[k - 1])
    return values[-1]
