"""MPEG-I haptics (ISO/IEC 23090-31) interchange files, ``.hjif`` (JSON): written from a stroke, read as effects.

A ``.hjif`` holds ``perceptions`` (each with a ``perception_modality``: ``Friction``, ``Vibrotactile`` ...), each
of ``channels``, each of ``bands`` (``band_type``: ``Curve``, ``VectorialWave``, ``Transient``, ``WaveletWave``),
each of ``effects`` at a ``position`` (ticks of the file's ``timescale`` per second) with ``keyframes``
(``relative_position`` in ticks, ``amplitude_modulation``, ``frequency_modulation`` in Hz).

Writing (:func:`hjif_document`): a ``Friction`` perception of one channel, one ``Curve`` band (linear) whose
keyframes are the friction ratio (0..1, 1 = the plate at rest) over the stroke's time, one per tick; with
``drive``, a ``Vibrotactile`` perception too, its curve the drive's amplitude envelope over its largest value
(0..1). The ``timescale`` is :data:`TIMESCALE` ticks a second: 1 ms, a tenth of the plate's fastest response.
Where the texture is spatial (its friction varies over it), a second ``Friction`` perception carries its spatial
signal (:func:`spatial_signal`): the texture's friction ratio over the distance the finger travelled along the
stroke (effects left out: they are temporal), positions in units of 10^``unit_exponent`` m
(:data:`SPATIAL_UNIT_EXPONENT`, 10 µm), a keyframe every :data:`SPATIAL_STEP` units. ISO/IEC 23090-31 makes
Friction, Stiffness and Vibrotactile Texture its spatial modalities (the reference software's
``IOStream::writeData`` codes their bands as spatial data) and gives a perception a ``unit_exponent`` (its
``Perception`` type, default −3); the spatial perception is the one of ours that states it.

Reading (:func:`read_hjif`): into a :class:`~ultraglide.textures.formats.timeline.Timeline`:

- a ``Curve`` band of a ``Friction`` perception is a friction ratio: the drop is ``1 − ratio``;
  of any other perception, ``|amplitude|`` is the depth of the drop directly (no modulation);
- a ``VectorialWave`` band: ``|amplitude|`` is the depth of a modulation at the keyframes' frequency;
- a ``Transient`` band: each keyframe a pulse of depth ``|amplitude|`` (its frequency sets its length as a
  sharpness would, 50 → 300 Hz as dull → sharp);
- a spatial perception (a ``Friction``, ``Stiffness`` or texture perception stating a ``unit_exponent``, as
  ultraglide writes one) is a signal over distance, not over time: not played as effects, and said
  (:func:`read_spatial_signal` reads it);
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
SPATIAL_UNIT_EXPONENT = -5  # the spatial signal's positions: units of 10^-5 m (10 µm)
SPATIAL_STEP = 2  # units between the spatial signal's keyframes: 20 µm, a fifth of a 0.1 mm texture pixel
SPATIAL_MODALITIES = ("Friction", "Stiffness", "Vibrotactile Texture", "Texture")


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


def _perception(number_: int, modality: str, description: str, values: np.ndarray, rate_hz: float,
                keyframes: list[dict] | None = None, upper_limit: int = TIMESCALE // 2) -> dict:
    if keyframes is None:
        keyframes, _ = _keyframes(values, rate_hz)
    return {
        "id": number_, "avatar_id": AVATAR_ID, "description": description, "perception_modality": modality,
        "reference_devices": [], "effect_library": [],
        "channels": [{
            "id": 0, "description": description, "gain": 1.0, "mixing_coefficient": 1.0, "body_part_mask": 0,
            "bands": [{"band_type": "Curve", "curve_type": "Linear", "lower_frequency_limit": 0,
                       "upper_frequency_limit": upper_limit,
                       "effects": [{"effect_type": "Basis", "position": 0, "keyframes": keyframes}]}],
        }],
    }


def spatial_signal(texture, x_mm, y_mm, down) -> tuple[np.ndarray, np.ndarray] | None:
    """The texture's friction ratio over the distance the finger travelled, a value every :data:`SPATIAL_STEP`
    units of 10^:data:`SPATIAL_UNIT_EXPONENT` m; None when the texture is uniform or the finger hardly moved.

    Parameters
    ----------
    texture : Texture
        The texture stroked (its map only: temporal effects are not part of its spatial signal).
    x_mm, y_mm : numpy.ndarray
        The finger's positions at each control sample, mm.
    down : numpy.ndarray
        Whether the finger touched at each sample; distance is counted only while it does.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray) or None
        Distances along the stroke (mm, from 0, evenly spaced) and the friction ratio there (0..1).

    Raises
    ------
    TextureError
        A stroke longer than an ``.hjif`` file of ours holds.

    Examples
    --------
    >>> from ultraglide.textures.texture import Texture
    >>> ramp = Texture(np.tile(np.linspace(0.05, 0.95, 10, dtype=np.float32), (2, 1)), 10.0, 2.0, outside="clamp")
    >>> d, r = spatial_signal(ramp, np.array([1.0, 9.0]), np.array([1.0, 1.0]), np.array([True, True]))
    >>> float(d[-1]), round(float(r[0]), 3), round(float(r[-1]), 3)
    (8.0, 0.1, 0.9)
    """
    from ultraglide.textures.sampling import Sampler

    x_mm, y_mm = np.asarray(x_mm, dtype=float), np.asarray(y_mm, dtype=float)
    down = np.asarray(down, dtype=bool)
    if float(np.ptp(texture.ratio_map())) == 0.0 or np.count_nonzero(down) < 2:
        return None
    # distance grows between consecutive samples the finger touched at both
    moved = np.hypot(np.diff(x_mm), np.diff(y_mm)) * (down[1:] & down[:-1])
    travelled = np.concatenate(([0.0], np.cumsum(moved)))
    keep = down & np.concatenate(([True], moved > 0))  # one sample per distance: np.interp needs them increasing
    step_mm = SPATIAL_STEP * 10.0 ** (SPATIAL_UNIT_EXPONENT + 3)
    if travelled[-1] < 2 * step_mm:
        return None
    count = int(travelled[-1] / step_mm) + 1
    if count > MAX_KEYFRAMES:
        raise TextureError(f"a stroke of {travelled[-1]:g} mm is more than the {MAX_KEYFRAMES * step_mm:g} mm an "
                           ".hjif file of ours holds")
    distance = np.arange(count) * step_mm
    along, x_at, y_at = travelled[keep], x_mm[keep], y_mm[keep]
    x, y = np.interp(distance, along, x_at), np.interp(distance, along, y_at)
    direction = (np.gradient(x), np.gradient(y)) if texture.kind == "gradient" else None
    ratio = Sampler(texture).ratio(x, y, step_mm, direction)
    return distance, np.clip(np.asarray(ratio, dtype=float), 0.0, 1.0)


def hjif_document(ratio: np.ndarray, rate_hz: float, description: str, drive: np.ndarray | None = None,
                  date: datetime.date | None = None, spatial: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
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
    spatial : (numpy.ndarray, numpy.ndarray), optional
        The texture's spatial signal (:func:`spatial_signal`): written as a Friction perception over distance.

    Returns
    -------
    dict
        The ``.hjif`` JSON object.

    Raises
    ------
    TextureError
        Values that are not finite or not within 0..1, or a stroke too long.

    Examples
    --------
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
    if spatial is not None:
        perceptions.append(_spatial_perception(len(perceptions), description, *spatial))
    return {
        "version": VERSION, "profile": "Main", "level": 1, "date": (date or datetime.date.today()).isoformat(),
        "description": description, "timescale": TIMESCALE,
        "avatars": [],
        "perceptions": perceptions, "syncs": [],
    }


def _spatial_perception(number_: int, description: str, distance_mm: np.ndarray, ratio: np.ndarray) -> dict:
    unit_mm = 10.0 ** (SPATIAL_UNIT_EXPONENT + 3)
    positions = np.rint(np.asarray(distance_mm, dtype=float) / unit_mm).astype(np.int64)
    if len(positions) < 2 or np.any(np.diff(positions) <= 0) or not np.all(np.isfinite(ratio)):
        raise TextureError("a spatial signal for an .hjif file is finite ratios at increasing distances")
    keyframes = [{"relative_position": int(p), "amplitude_modulation": round(float(v), 6)}
                 for p, v in zip(positions, ratio, strict=True)]
    perception = _perception(number_, "Friction", f"friction ratio (1 = plate at rest) over distance along the "
                                                  f"stroke, positions in units of 1e{SPATIAL_UNIT_EXPONENT} m: "
                                                  f"{description}", ratio, 0.0, keyframes,
                             upper_limit=int(1 / (2 * SPATIAL_STEP * 10.0 ** SPATIAL_UNIT_EXPONENT)))
    perception["unit_exponent"] = SPATIAL_UNIT_EXPONENT
    return perception


def read_spatial_signal(document, where: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The spatial signal of an ``.hjif`` document: its first spatial perception with a ``unit_exponent``.

    Parameters
    ----------
    document : dict
        The ``.hjif`` JSON.
    where : str
        The file's name, for messages.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray) or None
        Distances (mm: positions × 10^``unit_exponent`` m) and amplitudes (its first channel's first band's
        effects, keyframes placed from each effect's position), or None when the file has none.

    Raises
    ------
    TextureError
        One line: a mistyped field, a number out of range, keyframes out of order.

    Examples
    --------
    >>> doc = hjif_document(np.ones(2), 1000.0, "flat", spatial=(np.array([0.0, 0.02]), np.array([1.0, 0.5])))
    >>> read_spatial_signal(doc, "s.hjif")[0].tolist()
    [0.0, 0.02]
    """
    document = _obj(document, f"{where}: an .hjif file")
    for p, perception in enumerate(_items(document.get("perceptions"), f"{where}: 'perceptions'")):
        at = f"{where}: perception {p + 1}"
        perception = _obj(perception, at)
        if perception.get("perception_modality") not in SPATIAL_MODALITIES or "unit_exponent" not in perception:
            continue
        exponent = number(perception["unit_exponent"], f"{at}: unit_exponent", -128, 127)
        unit_mm = 10.0 ** (exponent + 3)
        channel = _obj(_items(perception.get("channels"), f"{at}: 'channels'")[0], f"{at}, channel 1")
        band = _obj(_items(channel.get("bands"), f"{at}, channel 1: 'bands'")[0], f"{at}, channel 1, band 1")
        positions, amplitudes = [], []
        for e, effect in enumerate(_items(band.get("effects"), f"{at}, band 1: 'effects'")):
            effect = _obj(effect, f"{at}, effect {e + 1}")
            start = number(effect.get("position", 0), f"{at}, effect {e + 1}: position", 0, 1e12)
            keyframes = effect.get("keyframes", [])
            if not isinstance(keyframes, list) or len(keyframes) > MAX_KEYFRAMES:
                raise TextureError(f"{at}, effect {e + 1}: 'keyframes' must be a list of at most {MAX_KEYFRAMES:,}")
            for k, keyframe in enumerate(keyframes):
                keyframe = _obj(keyframe, f"{at}, effect {e + 1}, keyframe {k + 1}")
                position = start + number(keyframe.get("relative_position"),
                                          f"{at}, effect {e + 1}, keyframe {k + 1}: relative_position", 0, 1e12)
                if positions and position < positions[-1]:
                    raise TextureError(f"{at}, effect {e + 1}: keyframe {k + 1} comes before the one before it")
                positions.append(position)
                amplitudes.append(number(keyframe.get("amplitude_modulation"),
                                         f"{at}, effect {e + 1}, keyframe {k + 1}: amplitude_modulation", -1, 1))
        return np.asarray(positions) * unit_mm, np.asarray(amplitudes)
    return None


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

    Examples
    --------
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
        if modality in SPATIAL_MODALITIES and "unit_exponent" in perception:
            timeline.note(f"a {modality} perception over distance (a spatial texture) is not an effect over time: "
                          "not played as effects")
            continue
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
