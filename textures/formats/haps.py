"""Interhaptics ``.haps`` files (Haptic Composer): a texture over distance in, and a vibration as effects.

A ``.haps`` file is JSON (version ``"5"`` in every published file)::

    {"m_version": "5", "m_description": "", "m_HDFlag": 0, "m_time_unit": 0, "m_length_unit": 7,
     "m_vibration": BLOCK, "m_texture": BLOCK, "m_stiffness": BLOCK, "m_gain": 1.0}

    BLOCK  = {"m_loop": 0, "m_maximum": 1.0, "m_gain": 1.0, "m_signalEvaluationMethod": 3, "m_melodies": [MELODY]}
    MELODY = {"m_mute": 0, "m_gain": 1.0, "m_notes": [NOTE]}
    NOTE   = {"m_startingPoint": S, "m_length": L, "m_priority": 1, "m_gain": G, "m_hapticEffect": {
                "m_underlyingSignal": {"m_phase", "m_amplitude", "m_frequency", "m_verticalOffset", "m_signalType"},
                "m_amplitudeModulation": {"m_extrapolationStrategy": 0, "m_keyframes": [{"m_time", "m_value"}]},
                "m_frequencyModulation": {"m_extrapolationStrategy": 0, "m_keyframes": [{"m_time", "m_value"}]}}}

(the structure of the files in Interhaptics' own SDKs, e.g. Interhaptics/Unity_CoreSDK ``Assets/HapticEffects``).
A note's keyframes are placed from the note's start (``m_startingPoint``) and last its ``m_length``; a note with
no amplitude modulation is a transient of amplitude ``m_gain``. In ``m_vibration`` positions are times, s
(``m_time_unit`` 0, the only value published files carry); in ``m_texture`` they are distances along the
stroke in the file's length unit. ``m_length_unit`` is 7 in every published file; its enumeration is not
published, and Interhaptics' Unity SDK plays a texture at a distance "real distance 1 unit = 1 meter"
(``MobileHapticsTexture.PlayTexture``): ultraglide reads unit 7 as metres. Another unit needs ``--width-mm``.

What ultraglide makes of it (docs/formats.md):

- **the texture** (:func:`haps_texture`): the amplitude over distance, the sum of the texture block's notes
  (each its amplitude modulation, linear between keyframes, times the note's, melody's, block's and file's gains
  and its underlying signal's amplitude), clipped to 0..1, becomes a grating along x (constant across y) through
  a :class:`~ultraglide.textures.formats.mapping.TexelMapping` (by default ``ratio = amplitude``: where the
  texture's amplitude is 1 the plate is at rest, full friction; where it is 0, the slipperiest); the texture
  spans the block's length (its last note's end), tiling when the block loops, else holding its end;
- **the vibration** (:func:`read_haps_effects`): each note with an amplitude modulation is a friction
  modulation of that depth at its frequency modulation's frequency (Hz; 175 Hz when the note gives none), each
  transient a pulse of its gain lasting its length (5 to 20 ms);
- not rendered, and said: the texture's underlying vibration (its frequency and waveform under the amplitude),
  its frequency modulation, the stiffness block, extrapolation beyond a note's keyframes (held), ``m_maximum``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from ultraglide.textures.errors import TextureError
from ultraglide.textures.formats.mapping import TexelMapping
from ultraglide.textures.formats.timeline import (
    MAX_EVENTS,
    PULSE_LONGEST_S,
    PULSE_SHORTEST_S,
    Pulse,
    Timeline,
    interpolate,
    number,
    sharpness_hz,
)
from ultraglide.textures.texture import Texture

LENGTH_UNITS_MM = {7: 1000.0}  # m_length_unit → millimetres per unit (7: metres, see the module's text)
TIME_UNITS_S = {0: 1.0}  # m_time_unit → seconds per unit
MAX_KEYFRAMES = 100_000  # keyframes in the whole file (a 4 MB file holds about 60 000)
MAX_COLS = 65_536  # columns of the imported grating
MIN_PX_PER_MM = 10.0  # the grating's least density; finer when its keyframes are closer (8 pixels to the closest)
FEATURE_PIXELS = 8
ROWS = 4  # the grating is constant across y: a few rows hold it
MAX_POSITION = 1e4  # seconds or length units: a note starting or lasting more is refused
DEFAULT_VIBRATION_HZ = sharpness_hz(0.5)
AMPLITUDE_IS_RATIO = TexelMapping()  # the default rule: amplitude 1 is the plate at rest, 0 the slipperiest


@dataclass(frozen=True)
class Note:
    """One note: where it starts and how long it lasts (s or length units), its gain (all gains above it
    multiplied in), its amplitude keyframes (positions from its start; None for a transient), its frequency
    keyframes (Hz; may be empty) and its underlying signal's frequency (Hz, or None).

    Examples
    --------
    >>> haps = read_haps({"m_texture": {"m_melodies": [{"m_notes": [
    ...     {"m_startingPoint": 0.0, "m_length": 0.01, "m_gain": 0.5}]}]}}, "t.haps")
    >>> note = haps.texture.notes[0]
    >>> note.start, note.length, note.gain
    (0.0, 0.01, 0.5)
    """

    start: float
    length: float
    gain: float
    positions: tuple[float, ...] | None
    amplitudes: tuple[float, ...] | None
    frequency_positions: tuple[float, ...]
    frequencies: tuple[float, ...]
    underlying_hz: float | None = None


@dataclass(frozen=True)
class Block:
    """A perception block (``m_vibration``, ``m_texture``, ``m_stiffness``): its playing notes and its loop.

    Examples
    --------
    >>> haps = read_haps({"m_texture": {"m_loop": 1, "m_melodies": [{"m_notes": [
    ...     {"m_startingPoint": 0.0, "m_length": 0.01, "m_gain": 1.0}]}]}}, "t.haps")
    >>> haps.texture.name, len(haps.texture.notes), haps.texture.loop, len(haps.vibration.notes)
    ('m_texture', 1, True, 0)
    """

    name: str
    notes: tuple[Note, ...]
    loop: bool
    muted: int  # melodies muted (not read)
    unrendered: tuple[str, ...]  # what its notes ask that is not rendered, in words


@dataclass(frozen=True)
class HapsFile:
    """A read ``.haps`` file: its three blocks, its units and description.

    Examples
    --------
    >>> haps = read_haps({"m_version": "5", "m_description": "a step", "m_texture": {"m_melodies": [{"m_notes": [
    ...     {"m_startingPoint": 0.0, "m_length": 0.01, "m_gain": 1.0}]}]}}, "step.haps")
    >>> haps.where, haps.description, haps.length_unit
    ('step.haps', 'a step', 7)
    """

    where: str
    description: str
    length_unit: int
    vibration: Block
    texture: Block
    stiffness: Block


def _object(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise TextureError(f"{where} must be an object")
    return value


def _list(value, where: str) -> list:
    if not isinstance(value, list) or len(value) > MAX_EVENTS:
        raise TextureError(f"{where} must be a list of at most {MAX_EVENTS:,} entries")
    return value


def _integer(value, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
            or value != int(value) or abs(value) > 1_000_000:
        raise TextureError(f"{where} must be a whole number, got {value!r}")
    return int(value)


class _Counter:
    def __init__(self, where: str) -> None:
        self.where, self.keyframes = where, 0

    def add(self, count: int) -> None:
        self.keyframes += count
        if self.keyframes > MAX_KEYFRAMES:
            raise TextureError(f"{self.where}: more than {MAX_KEYFRAMES:,} keyframes, more than any haptic "
                               "effect needs; simplify it")


def _keyframes(modulation, at: str, counter: _Counter, low: float, high: float, length: float):
    modulation = _object(modulation, at)
    items = _list(modulation.get("m_keyframes", []), f"{at}: m_keyframes")
    counter.add(len(items))
    positions, values, last = [], [], -math.inf
    for k, item in enumerate(items):
        item = _object(item, f"{at}: keyframe {k + 1}")
        position = number(item.get("m_time"), f"{at}: keyframe {k + 1} m_time", 0.0, MAX_POSITION)
        if position < last:
            raise TextureError(f"{at}: keyframe {k + 1}'s m_time {position:g} comes before the one before it")
        last = position
        positions.append(min(position, length))
        values.append(number(item.get("m_value"), f"{at}: keyframe {k + 1} m_value", low, high))
    strategy = modulation.get("m_extrapolationStrategy", 0)
    return tuple(positions), tuple(values), _integer(strategy, f"{at}: m_extrapolationStrategy") != 0


def _note(item, at: str, gain: float, counter: _Counter, unrendered: list[str]) -> Note:
    item = _object(item, at)
    start = number(item.get("m_startingPoint", 0.0), f"{at}: m_startingPoint", 0.0, MAX_POSITION)
    length = number(item.get("m_length", 0.0), f"{at}: m_length", 0.0, MAX_POSITION)
    gain *= number(item.get("m_gain", 1.0), f"{at}: m_gain", 0.0, 1e3)
    effect = _object(item.get("m_hapticEffect", {}), f"{at}: m_hapticEffect")
    underlying_hz = None
    if "m_underlyingSignal" in effect:
        signal = _object(effect["m_underlyingSignal"], f"{at}: m_underlyingSignal")
        gain *= number(signal.get("m_amplitude", 1.0), f"{at}: m_underlyingSignal m_amplitude", 0.0, 1e3)
        underlying_hz = number(signal.get("m_frequency", 0.0), f"{at}: m_underlyingSignal m_frequency", 0.0, 1e5)
        _integer(signal.get("m_signalType", 0), f"{at}: m_underlyingSignal m_signalType")
    positions = amplitudes = None
    if "m_amplitudeModulation" in effect:
        positions, amplitudes, extrapolated = _keyframes(effect["m_amplitudeModulation"],
                                                         f"{at}: m_amplitudeModulation", counter, 0.0, 1.0, length)
        if extrapolated:
            unrendered.append("extrapolation beyond a note's keyframes (held at the last keyframe's value)")
        if not positions:
            positions = amplitudes = None
    f_positions, frequencies = (), ()
    if "m_frequencyModulation" in effect:
        f_positions, frequencies, _ = _keyframes(effect["m_frequencyModulation"], f"{at}: m_frequencyModulation",
                                                 counter, 0.0, 1e5, length)
    return Note(start, length, gain, positions, amplitudes, f_positions, frequencies, underlying_hz)


def _block(document: dict, name: str, where: str, gain: float, counter: _Counter) -> Block:
    block = _object(document.get(name, {}), f"{where}: {name!r}")
    at = f"{where}: {name}"
    gain *= number(block.get("m_gain", 1.0), f"{at} m_gain", 0.0, 1e3)
    unrendered: list[str] = []
    if number(block.get("m_maximum", 1.0), f"{at} m_maximum", 0.0, 1e3) != 1.0:
        unrendered.append("m_maximum (a block's amplitudes are played as written)")
    loop = _integer(block.get("m_loop", 0), f"{at} m_loop") != 0
    notes, muted = [], 0
    for m, melody in enumerate(_list(block.get("m_melodies", []), f"{at} m_melodies")):
        melody = _object(melody, f"{at} melody {m + 1}")
        if _integer(melody.get("m_mute", 0), f"{at} melody {m + 1} m_mute"):
            muted += 1
            continue
        melody_gain = gain * number(melody.get("m_gain", 1.0), f"{at} melody {m + 1} m_gain", 0.0, 1e3)
        for n, item in enumerate(_list(melody.get("m_notes", []), f"{at} melody {m + 1} m_notes")):
            notes.append(_note(item, f"{at} melody {m + 1} note {n + 1}", melody_gain, counter, unrendered))
            if len(notes) > MAX_EVENTS:
                raise TextureError(f"{at}: more than {MAX_EVENTS:,} notes; simplify it")
    return Block(name, tuple(notes), loop, muted, tuple(dict.fromkeys(unrendered)))


def read_haps(document, where: str) -> HapsFile:
    """A :class:`HapsFile` from a ``.haps`` document (parsed JSON), every field checked.

    Parameters
    ----------
    document : dict
        The file's JSON.
    where : str
        The file's name, for messages.

    Returns
    -------
    HapsFile

    Raises
    ------
    TextureError
        One line: not a ``.haps`` object, a field of the wrong type, a number not finite or out of range,
        keyframes out of order, a time unit other than seconds, more notes or keyframes than any effect needs.

    Examples
    --------
    >>> haps = read_haps({"m_version": "5", "m_texture": {"m_melodies": [{"m_notes": [
    ...     {"m_startingPoint": 0.0, "m_length": 0.01, "m_gain": 1.0}]}]}}, "t.haps")
    >>> haps.texture.notes[0].length, haps.length_unit
    (0.01, 7)
    """
    document = _object(document, f"{where}: a .haps file")
    if not any(key in document for key in ("m_vibration", "m_texture", "m_stiffness")):
        raise TextureError(f"{where}: not a .haps file (no m_vibration, m_texture or m_stiffness block)")
    version = document.get("m_version", "5")
    if not isinstance(version, str | int | float) or isinstance(version, bool):
        raise TextureError(f"{where}: m_version must be a string, got {version!r}")
    time_unit = _integer(document.get("m_time_unit", 0), f"{where}: m_time_unit")
    if time_unit not in TIME_UNITS_S:
        raise TextureError(f"{where}: m_time_unit {time_unit} is not one ultraglide knows (0, seconds, the one "
                           "Haptic Composer writes)")
    length_unit = _integer(document.get("m_length_unit", 7), f"{where}: m_length_unit")
    description = document.get("m_description", "")
    if not isinstance(description, str):
        raise TextureError(f"{where}: m_description must be a string")
    gain = number(document.get("m_gain", 1.0), f"{where}: m_gain", 0.0, 1e3)
    counter = _Counter(where)
    blocks = {name: _block(document, name, where, gain, counter)
              for name in ("m_vibration", "m_texture", "m_stiffness")}
    return HapsFile(where, description[:200], length_unit, blocks["m_vibration"], blocks["m_texture"],
                    blocks["m_stiffness"])


def load_haps(path) -> HapsFile:
    """Read and check a ``.haps`` file (a regular file of at most 4 MB, JSON nested at most 64 deep).

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    HapsFile

    Raises
    ------
    TextureError
        One line naming the file: not a regular file, too large, not JSON, or what :func:`read_haps` refuses.

    Examples
    --------
    >>> import json, pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "Texture.haps"
    >>> _ = path.write_text(json.dumps({"m_version": "5", "m_texture": {"m_melodies": [{"m_notes": [
    ...     {"m_startingPoint": 0.0, "m_length": 0.01, "m_gain": 1.0}]}]}}))
    >>> load_haps(path).texture.notes[0].length
    0.01
    """
    from ultraglide.inputs import parse_json, read_input

    what = "Interhaptics .haps file"
    document = parse_json(read_input(path, what, TextureError), str(path), TextureError, what=what)
    return read_haps(document, str(path))


def _amplitude_at(note: Note, offsets: np.ndarray) -> np.ndarray:
    """A note's amplitude at ``offsets`` from its start (same unit as its positions); 0 outside the note."""
    inside = (offsets >= 0) & (offsets < note.length) if note.length > 0 else np.zeros(offsets.shape, bool)
    if note.positions is None:
        return np.where(inside, note.gain, 0.0)
    values = np.interp(offsets, note.positions, note.amplitudes)
    return np.where(inside, note.gain * values, 0.0)


def haps_texture(haps: HapsFile, width_mm: float | None = None,
                 mapping: TexelMapping = AMPLITUDE_IS_RATIO) -> tuple[Texture, list[str]]:
    """The texture block as a friction texture: a grating along x, constant across y.

    Parameters
    ----------
    haps : HapsFile
        A read file (:func:`load_haps`).
    width_mm : float, optional
        The texture's width, mm: the block's whole length (its last note's end) spans it. By default the file's
        length unit says (unit 7: metres).
    mapping : TexelMapping
        The amplitude (0..1) to friction ratio rule; by default the amplitude is the ratio.

    Returns
    -------
    (Texture, list of str)
        The texture (width × width mm; the grating holds every keyframe with 8 pixels to the closest two, at
        least 10 pixels per mm, at most 65 536 columns) and what of the file it does not render, in words.

    Raises
    ------
    TextureError
        One line: the texture block has no notes or no length, or the length unit is unknown and no width given.

    Examples
    --------
    >>> notes = [{"m_startingPoint": 0.0, "m_length": 0.0005, "m_gain": 1.0},
    ...          {"m_startingPoint": 0.0005, "m_length": 0.0005, "m_gain": 0.2}]
    >>> haps = read_haps({"m_texture": {"m_loop": 1, "m_melodies": [{"m_notes": notes}]}, "m_length_unit": 7},
    ...                  "step.haps")
    >>> texture, _ = haps_texture(haps, width_mm=2.0)  # the block's 1 mm spans the 2 mm given
    >>> texture.width_mm, float(texture.values[0, 0]), round(float(texture.values[0, -1]), 3)
    (2.0, 1.0, 0.2)
    """
    where, block = haps.where, haps.texture
    if not block.notes:
        raise TextureError(f"{where}: its m_texture block has no notes: no texture to import (a vibration is "
                           "read as effects: --effects FILE.haps)")
    length = max(note.start + note.length for note in block.notes)
    if not length > 0:
        raise TextureError(f"{where}: its texture's notes have no length: nothing to import")
    if width_mm is None:
        if haps.length_unit not in LENGTH_UNITS_MM:
            raise TextureError(f"{where}: m_length_unit {haps.length_unit} is not one ultraglide knows (7, "
                               "metres); give --width-mm W for the texture's length")
        width_mm = length * LENGTH_UNITS_MM[haps.length_unit]
    if not (0.1 <= width_mm <= 10_000.0):
        raise TextureError(f"{where}: its texture is {width_mm:g} mm long; ultraglide takes 0.1 to 10 000 mm "
                           "(give --width-mm W)")
    mm_per_unit = width_mm / length
    steps = [b - a for note in block.notes if note.positions is not None
             for a, b in zip(note.positions, note.positions[1:], strict=False) if b > a]
    steps += [note.length for note in block.notes if note.length > 0]
    finest_mm = min(steps) * mm_per_unit
    density = max(MIN_PX_PER_MM, FEATURE_PIXELS / finest_mm)
    cols = int(min(MAX_COLS, max(2, math.ceil(width_mm * density))))
    centres = (np.arange(cols) + 0.5) * (length / cols)  # file units
    amplitude = np.zeros(cols)
    for note in block.notes:
        amplitude += _amplitude_at(note, centres - note.start)
    np.clip(amplitude, 0.0, 1.0, out=amplitude)
    row = mapping.ratio(amplitude.astype(np.float32))
    values = np.repeat(row[None, :], ROWS, axis=0)
    name = Path(where).stem
    notes = []
    if cols == MAX_COLS and width_mm * density > MAX_COLS:
        notes.append(f"its finest keyframes ({finest_mm:g} mm apart) are finer than {MAX_COLS:,} columns hold: "
                     f"sampled at {width_mm / cols:.3g} mm")
    underlying = sorted({note.underlying_hz for note in block.notes if note.underlying_hz})
    if underlying:
        notes.append(f"the texture's underlying vibration ({', '.join(f'{hz:g}' for hz in underlying)} Hz under "
                     "its amplitude) is not rendered: a friction display renders the amplitude over distance")
    if any(note.frequencies for note in block.notes):
        notes.append("the texture's frequency modulation is not rendered")
    notes.extend(block.unrendered)
    if block.muted:
        notes.append(f"{block.muted} muted texture melod{'y' if block.muted == 1 else 'ies'} left out")
    if haps.vibration.notes:
        notes.append("its m_vibration block (over time) is not part of a texture: read it as effects with "
                     "--effects FILE.haps")
    if haps.stiffness.notes:
        notes.append("its m_stiffness block is not rendered on a friction display")
    texture = Texture(values, float(width_mm), float(width_mm), outside="tile" if block.loop else "clamp",
                      name=name, description=haps.description, source=f"Interhaptics .haps: {Path(where).name}")
    return texture, notes


def load_haps_texture(path, width_mm: float | None = None,
                      mapping: TexelMapping = AMPLITUDE_IS_RATIO) -> tuple[Texture, list[str]]:
    """:func:`haps_texture` of the file at ``path`` (:func:`load_haps`).

    Parameters
    ----------
    path : str or path-like
        The ``.haps`` file.
    width_mm : float, optional
        The texture's width, mm (default: from the file's length unit).
    mapping : TexelMapping
        The amplitude to friction ratio rule.

    Returns
    -------
    (Texture, list of str)
        The texture and what is not rendered, in words.

    Raises
    ------
    TextureError
        One line naming the file.

    Examples
    --------
    >>> import json, pathlib, tempfile
    >>> notes = [{"m_startingPoint": 0.0, "m_length": 0.0005, "m_gain": 1.0},
    ...          {"m_startingPoint": 0.0005, "m_length": 0.0005, "m_gain": 0.2}]
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "step.haps"
    >>> _ = path.write_text(json.dumps({"m_texture": {"m_loop": 1, "m_melodies": [{"m_notes": notes}]},
    ...                                 "m_length_unit": 7}))
    >>> texture, unrendered = load_haps_texture(path, width_mm=40)
    >>> texture.width_mm, float(texture.values[0, 0])
    (40.0, 1.0)
    """
    return haps_texture(load_haps(path), width_mm, mapping)


def read_haps_effects(document, where: str, full_depth: float = 1.0) -> Timeline:
    """A :class:`~ultraglide.textures.formats.timeline.Timeline` from a ``.haps`` document's vibration block.

    Parameters
    ----------
    document : dict
        The file's JSON.
    where : str
        The file's name, for messages.
    full_depth : float
        The friction drop an amplitude of 1 gives (0..1).

    Returns
    -------
    Timeline
        Its segments (modulations) and pulses (transients), and notes of what is not rendered.

    Raises
    ------
    TextureError
        One line, as :func:`read_haps`.

    Examples
    --------
    >>> timeline = read_haps_effects({"m_vibration": {"m_melodies": [{"m_notes": [
    ...     {"m_startingPoint": 0.5, "m_length": 0.022, "m_gain": 0.8}]}]}}, "tap.haps")
    >>> timeline.pulses[0].start_s, timeline.pulses[0].depth, timeline.pulses[0].length_s
    (0.5, 0.8, 0.02)
    """
    haps = read_haps(document, where)
    timeline = Timeline(where)
    block = haps.vibration
    for note in block.notes:
        depth = note.gain * full_depth
        if note.positions is None:
            timeline.pulses.append(Pulse(note.start, depth, min(max(note.length, PULSE_SHORTEST_S),
                                                                PULSE_LONGEST_S)))
            continue
        times = sorted({0.0, note.length, *note.positions, *(p for p in note.frequency_positions
                                                             if p < note.length)})
        times = [t for t in times if t <= note.length]
        if len(times) < 2:
            continue
        depths = [depth * interpolate(note.positions, note.amplitudes, t) for t in times]
        hz = []
        for a, b in zip(times, times[1:], strict=False):
            if note.frequencies:
                hz.append(timeline.frequency(interpolate(note.frequency_positions, note.frequencies, (a + b) / 2)))
            else:
                hz.append(timeline.frequency(note.underlying_hz) if note.underlying_hz else DEFAULT_VIBRATION_HZ)
        timeline.add_envelope(note.start, times, depths, hz)
    for text in block.unrendered:
        timeline.note(text)
    if block.muted:
        timeline.note(f"{block.muted} muted vibration melod{'y' if block.muted == 1 else 'ies'} left out")
    if not block.notes:
        timeline.note("its m_vibration block has no notes: no effect over time in it")
    if haps.texture.notes:
        timeline.note("its m_texture block is a texture over distance, not an effect over time: "
                      "`ultraglide texture import FILE.haps` reads it")
    if haps.stiffness.notes:
        timeline.note("its m_stiffness block is not rendered on a friction display")
    return timeline
