"""MPEG-I haptics (ISO/IEC 23090-31) interchange files, ``.hjif`` (JSON): written from a stroke, read as effects.

A ``.hjif`` holds ``perceptions`` (each with a ``perception_modality``: ``Friction``, ``Vibrotactile`` ...), each
of ``channels``, each of ``bands`` (``band_type``: ``Curve``, ``VectorialWave``, ``Transient``, ``WaveletWave``),
each of ``effects`` at a ``position`` (ticks of the file's ``timescale`` per second) with ``keyframes``
(``relative_position`` in ticks, ``amplitude_modulation``, ``frequency_modulation`` in Hz).

Writing (:func:`hjif_document`): a ``Friction`` perception of one channel, one ``Curve`` band (linear) whose
keyframes are the friction ratio (0..1, 1 = the plate at rest) over the stroke's time, one per tick; with
``drive``, a ``Vibrotactile`` perception too, its curve the drive's amplitude envelope over its largest value
(0..1). The ``timescale`` is :data:`TIMESCALE` ticks a second: 1 ms, a tenth of the plate's fastest response.

Reading (:func:`read_hjif`): into a :class:`~ultraglide.textures.formats.timeline.Timeline`:

- a ``Curve`` band of a ``Friction`` perception is a friction ratio: the drop is ``1 − ratio``;
  of any other perception, ``|amplitude|`` is the depth of the drop directly (no modulation);
- a ``VectorialWave`` band: ``|amplitude|`` is the depth of a modulation at the keyframes' frequency;
- a ``Transient`` band: each keyframe a pulse of depth ``|amplitude|`` (its frequency sets its length as a
  sharpness would, 50 → 300 Hz as dull → sharp);
- not rendered, and said: ``WaveletWave`` bands (coded vibration), ``Reference`` and ``Composite`` effects (the
  effect library), non-linear curve types (played as linear), channels beyond the first of a perception
  (mixed as a sum: said), perceptions of modalities a friction display has nothing for (temperature, force ...).
"""

from __future__ import annotations

import datetime

import numpy as np
from ultraglide.textures.errors import TextureError
from ultraglide.textures.formats.timeline import (
    MAX_EVENTS,
    SHARPNESS_HIGH_HZ,
    SHARPNESS_LOW_HZ,
    Pulse,
    Timeline,
    number,
    pulse_length_s,
)

TIMESCALE = 1000  # ticks per second
AVATAR_ID = 0  # unspecified: the file names no body model (the reference encoder's own choice for AHAP input)
VERSION = "2023"
RENDERED_MODALITIES = ("Friction", "Vibrotactile", "Vibration", "Vibrotactile Texture", "Texture", "Other")
MAX_KEYFRAMES = 4_000_000  # an hour at one per millisecond


def _keyframes(values: np.ndarray, rate_hz: float) -> tuple[list[dict], int]:
    """Keyframes of ``values`` (sample k at k / ``rate_hz`` s) resampled to one per tick, linear between samples."""
    duration_s = (len(values) - 1) / rate_hz
    ticks = max(2, int(duration_s * TIMESCALE) + 1)
    if ticks > MAX_KEYFRAMES:
        raise TextureError(f"a stroke of {duration_s:g} s is more than the {MAX_KEYFRAMES // TIMESCALE} s an .hjif "
                           "file of ours holds")
    times = np.arange(ticks) / TIMESCALE
    sampled = np.interp(times, np.arange(len(values)) / rate_hz, values)
    return [{"relative_position": int(k), "amplitude_modulation": round(float(v), 6)}
            for k, v in enumerate(sampled)], ticks


def _perception(number_: int, modality: str, description: str, values: np.ndarray, rate_hz: float) -> dict:
    keyframes, _ = _keyframes(values, rate_hz)
    return {
        "id": number_, "avatar_id": AVATAR_ID, "description": description, "perception_modality": modality,
        "reference_devices": [], "effect_library": [],
        "channels": [{
            "id": 0, "description": description, "gain": 1.0, "mixing_coefficient": 1.0, "body_part_mask": 0,
            "bands": [{"band_type": "Curve", "curve_type": "Linear", "lower_frequency_limit": 0,
                       "upper_frequency_limit": TIMESCALE // 2,
                       "effects": [{"effect_type": "Basis", "position": 0, "keyframes": keyframes}]}],
        }],
    }


def hjif_document(ratio: np.ndarray, rate_hz: float, description: str, drive: np.ndarray | None = None,
                  date: datetime.date | None = None) -> dict:
    """An MPEG-I haptics document of a rendered stroke.

    Parameters
    ----------
    ratio : numpy.ndarray
        The friction ratio (0..1) at each control sample (sample k at k / ``rate_hz`` s).
    rate_hz : float
        The samples' rate, Hz.
    description : str
        What the file holds, in words (the texture and the stroke).
    drive : numpy.ndarray, optional
        The drive's amplitude (µm peak-to-peak) at the same samples: written as a Vibrotactile perception, over
        its largest value.
    date : datetime.date, optional
        The file's date (default: today).

    Returns
    -------
    dict
        The ``.hjif`` JSON object.

    Raises
    ------
    TextureError
        Values that are not finite or not within 0..1, or a stroke too long.

    Example
    -------
    >>> doc = hjif_document(np.array([1.0, 0.5]), 1000.0, "a step")
    >>> doc["perceptions"][0]["perception_modality"]
    'Friction'
    """
    ratio = np.asarray(ratio, dtype=float)
    if ratio.ndim != 1 or len(ratio) < 1 or not np.all(np.isfinite(ratio)) or ratio.min() < 0 or ratio.max() > 1:
        raise TextureError("a friction signal for an .hjif file is finite ratios within 0..1")
    perceptions = [_perception(0, "Friction", f"friction ratio (1 = plate at rest) over time: {description}",
                               ratio, rate_hz)]
    if drive is not None:
        drive = np.asarray(drive, dtype=float)
        if drive.shape != ratio.shape or not np.all(np.isfinite(drive)) or drive.min() < 0:
            raise TextureError("the drive envelope must be finite amplitudes of 0 or more, one per ratio sample")
        top = float(drive.max())
        perceptions.append(_perception(1, "Vibrotactile", f"drive amplitude envelope over its largest, "
                                                          f"{top:.4g} µm p-p: {description}",
                                       drive / top if top > 0 else drive, rate_hz))
    return {
        "version": VERSION, "profile": "Main", "level": 1, "date": (date or datetime.date.today()).isoformat(),
        "description": description, "timescale": TIMESCALE,
        "avatars": [],
        "perceptions": perceptions, "syncs": [],
    }


# ---- reading --------------------------------------------------------------------------------------------------
def _items(value, where: str) -> list:
    if not isinstance(value, list) or len(value) > MAX_EVENTS:
        raise TextureError(f"{where} must be a list of at most {MAX_EVENTS:,}")
    return value


def _obj(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise TextureError(f"{where} must be an object")
    return value


def read_hjif(document, where: str, full_depth: float = 1.0) -> Timeline:
    """A Timeline from an ``.hjif`` document (parsed JSON); see the module's text for what maps to what.

    Parameters
    ----------
    document : dict
        The ``.hjif`` JSON.
    where : str
        The file's name, for messages.
    full_depth : float
        The friction drop an amplitude of 1 gives (0..1).

    Returns
    -------
    Timeline

    Raises
    ------
    TextureError
        One line: a missing or mistyped field, numbers out of range, too many keyframes.

    Example
    -------
    >>> doc = hjif_document(np.array([1.0, 0.5, 1.0]), 1000.0, "a dip")
    >>> round(max(s.depth1 for s in read_hjif(doc, "dip.hjif").segments), 3)
    0.5
    """
    document = _obj(document, f"{where}: an .hjif file")
    timescale = number(document.get("timescale", TIMESCALE), f"{where}: timescale", 1, 1e9)
    timeline = Timeline(where)
    total = 0
    for p, perception in enumerate(_items(document.get("perceptions"), f"{where}: 'perceptions'")):
        at = f"{where}: perception {p + 1}"
        perception = _obj(perception, at)
        modality = perception.get("perception_modality")
        if modality not in RENDERED_MODALITIES:
            timeline.note(f"{modality} perceptions are not rendered (a friction display has nothing for them)")
            continue
        if perception.get("effect_library"):
            timeline.note("the effect library (Reference and Composite effects) is not rendered")
        channels = _items(perception.get("channels"), f"{at}: 'channels'")
        if len(channels) > 1:
            timeline.note("a perception's channels beyond the first are mixed as a sum on the one friction display")
        for c, channel in enumerate(channels):
            channel = _obj(channel, f"{at}, channel {c + 1}")
            gain = number(channel.get("gain", 1.0), f"{at}, channel {c + 1}: gain", -1e3, 1e3)
            for b, band in enumerate(_items(channel.get("bands"), f"{at}, channel {c + 1}: 'bands'")):
                band_at = f"{at}, channel {c + 1}, band {b + 1}"
                total += _band(timeline, _obj(band, band_at), band_at, modality, gain * full_depth, timescale)
                if total > MAX_EVENTS:
                    raise TextureError(f"{where}: more than {MAX_EVENTS:,} keyframes, more than ultraglide plays as "
                                       "temporal effects")
    return timeline


def _band(timeline: Timeline, band: dict, at: str, modality: str, scale: float, timescale: float) -> int:
    kind = band.get("band_type")
    if kind == "WaveletWave":
        timeline.note("WaveletWave bands (coded vibration) are not rendered")
        return 0
    if kind not in ("Curve", "VectorialWave", "Transient"):
        raise TextureError(f"{at}: band_type {kind!r} is not one MPEG-I haptics has")
    if kind == "Curve" and band.get("curve_type", "Linear") != "Linear":
        timeline.note(f"{band.get('curve_type')!r} curves are played as linear between their keyframes")
    count = 0
    for e, effect in enumerate(_items(band.get("effects"), f"{at}: 'effects'")):
        effect_at = f"{at}, effect {e + 1}"
        effect = _obj(effect, effect_at)
        if effect.get("effect_type", "Basis") != "Basis":
            timeline.note("Reference and Composite effects (the effect library) are not rendered")
            continue
        start = number(effect.get("position", 0), f"{effect_at}: position", 0, 1e12) / timescale
        times, amplitudes, frequencies = [], [], []
        for k, keyframe in enumerate(_items(effect.get("keyframes", []), f"{effect_at}: 'keyframes'")):
            keyframe = _obj(keyframe, f"{effect_at}, keyframe {k + 1}")
            position = keyframe.get("relative_position", times[-1] * timescale if times else 0)
            time = number(position, f"{effect_at}, keyframe {k + 1}: relative_position", 0, 1e12) / timescale
            if times and time < times[-1]:
                raise TextureError(f"{effect_at}: keyframe {k + 1} comes before the one before it")
            default = amplitudes[-1] if amplitudes else 0.0
            amplitude = number(keyframe.get("amplitude_modulation", default),
                               f"{effect_at}, keyframe {k + 1}: amplitude_modulation", -1, 1)
            default = frequencies[-1] if frequencies else 0.0
            frequency = number(keyframe.get("frequency_modulation", default),
                               f"{effect_at}, keyframe {k + 1}: frequency_modulation", 0, 1e6)
            times.append(time)
            amplitudes.append(amplitude)
            frequencies.append(frequency)
        count += len(times)
        if kind == "Transient":
            for time, amplitude, frequency in zip(times, amplitudes, frequencies, strict=True):
                sharpness = (frequency - SHARPNESS_LOW_HZ) / (SHARPNESS_HIGH_HZ - SHARPNESS_LOW_HZ)
                timeline.pulses.append(Pulse(start + time, abs(amplitude) * scale, pulse_length_s(sharpness)))
        elif len(times) >= 2:
            if kind == "Curve" and modality == "Friction":
                depths = [(1.0 - a) * scale for a in amplitudes]
                hz = None
            else:
                depths = [abs(a) * scale for a in amplitudes]
                hz = None if kind == "Curve" else [timeline.frequency(f) for f in frequencies[:-1]]
            timeline.add_envelope(start, times, depths, hz)
    return count
