"""Apple AHAP (Core Haptics' JSON pattern) and Meta ``.haptic`` (Haptics Studio) files as friction effects.

AHAP: ``{"Version": 1.0, "Pattern": [...]}``, each entry an ``Event`` (``Time``, ``EventType``,
``EventDuration``, ``EventParameters`` of ``ParameterID``/``ParameterValue``), a ``ParameterCurve``
(``ParameterID``, ``Time``, ``ParameterCurveControlPoints`` of ``Time``/``ParameterValue``) or a ``Parameter``
(a dynamic parameter: ``ParameterID``, ``Time``, ``ParameterValue``).

- ``HapticContinuous``: a modulation over its duration, depth = ``HapticIntensity`` (times the
  ``HapticIntensityControl`` curves and parameters in force), frequency from ``HapticSharpness``
  (:func:`~ultraglide.textures.formats.timeline.sharpness_hz`); ``AttackTime`` and ``ReleaseTime`` ramp its depth
  in and out;
- ``HapticTransient``: a pulse of depth ``HapticIntensity`` whose length follows ``HapticSharpness``;
- not rendered, and said: audio events (sound), ``HapticSharpnessControl`` (a modulation's frequency is fixed
  per event), ``DecayTime`` and ``Sustain`` (Core Haptics' envelope beyond attack and release), other
  parameters.

Meta ``.haptic``: ``signals.continuous.envelopes.amplitude`` (breakpoints of ``time``, s, and ``amplitude``,
0..1, each with an optional ``emphasis`` of ``amplitude`` and ``frequency``) and ``...frequency`` (breakpoints
of ``time`` and ``frequency``, 0..1): the amplitude envelope is the depth of a modulation whose frequency, from
the frequency envelope at each stretch's middle, maps as sharpness does; an emphasis is a pulse on top.
"""

from __future__ import annotations

from ultraglide.textures.errors import TextureError
from ultraglide.textures.formats.timeline import (
    MAX_EVENTS,
    Pulse,
    Timeline,
    interpolate,
    number,
    pulse_length_s,
    sharpness_hz,
)

EVENT_PARAMETERS = ("HapticIntensity", "HapticSharpness", "AttackTime", "DecayTime", "ReleaseTime", "Sustain")


def _list(value, where: str) -> list:
    if not isinstance(value, list) or len(value) > MAX_EVENTS:
        raise TextureError(f"{where} must be a list of at most {MAX_EVENTS:,} entries")
    return value


def _object(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise TextureError(f"{where} must be an object")
    return value


def read_ahap(document, where: str, full_depth: float = 1.0) -> Timeline:
    """A :class:`~ultraglide.textures.formats.timeline.Timeline` from an AHAP document (parsed JSON).

    Parameters
    ----------
    document : dict
        The AHAP JSON.
    where : str
        The file's name, for messages.
    full_depth : float
        The friction drop an intensity of 1 gives (0..1).

    Returns
    -------
    Timeline
        Its segments and pulses, and notes of what is not rendered.

    Raises
    ------
    TextureError
        One line: not an AHAP pattern, a field of the wrong type, a number out of its range.

    Examples
    --------
    >>> timeline = read_ahap({"Version": 1.0, "Pattern": [{"Event": {"Time": 0.0, "EventType": "HapticTransient",
    ...     "EventParameters": [{"ParameterID": "HapticIntensity", "ParameterValue": 0.8}]}}]}, "tap.ahap")
    >>> timeline.pulses[0].depth
    0.8
    """
    document = _object(document, f"{where}: an AHAP file")
    timeline = Timeline(where)
    pattern = _list(document.get("Pattern"), f"{where}: 'Pattern'")
    events, controls = [], []  # controls: (time, value) of HapticIntensityControl, curves and steps
    for k, entry in enumerate(pattern):
        at = f"{where}: pattern entry {k + 1}"
        entry = _object(entry, at)
        if "Event" in entry:
            events.append((_object(entry["Event"], at), at))
        elif "ParameterCurve" in entry:
            curve = _object(entry["ParameterCurve"], at)
            kind = curve.get("ParameterID")
            start = number(curve.get("Time", 0.0), f"{at}: Time", 0.0, 3600.0)
            points = _list(curve.get("ParameterCurveControlPoints", []), f"{at}: ParameterCurveControlPoints")
            if kind == "HapticIntensityControl":
                for p, point in enumerate(points):
                    point = _object(point, f"{at}: control point {p + 1}")
                    controls.append((start + number(point.get("Time"), f"{at}: control point {p + 1} Time", 0, 3600),
                                     number(point.get("ParameterValue"), f"{at}: control point {p + 1} value", 0, 1)))
            else:
                timeline.note(f"parameter curves of {kind!r} are not rendered (a friction display renders "
                              "intensity; a modulation's frequency is fixed per event)")
        elif "Parameter" in entry:
            step = _object(entry["Parameter"], at)
            kind = step.get("ParameterID")
            if kind == "HapticIntensityControl":
                controls.append((number(step.get("Time", 0.0), f"{at}: Time", 0, 3600),
                                 number(step.get("ParameterValue"), f"{at}: ParameterValue", 0, 1)))
            else:
                timeline.note(f"dynamic parameters {kind!r} are not rendered")
        else:
            raise TextureError(f"{at}: an AHAP pattern entry is an Event, a ParameterCurve or a Parameter")
    controls.sort()
    control_times = [t for t, _ in controls]
    control_values = [v for _, v in controls]
    for event, at in events:
        _event(timeline, event, at, control_times, control_values, full_depth)
    return timeline


def _parameters(timeline: Timeline, event: dict, at: str) -> dict:
    values = {}
    for p, item in enumerate(_list(event.get("EventParameters", []), f"{at}: EventParameters")):
        item = _object(item, f"{at}: event parameter {p + 1}")
        kind = item.get("ParameterID")
        if kind not in EVENT_PARAMETERS:
            timeline.note(f"event parameter {kind!r} is not rendered")
            continue
        value = item.get("ParameterValue")
        if kind == "Sustain":
            if not isinstance(value, bool | int | float):
                raise TextureError(f"{at}: Sustain must be true or false")
            values[kind] = bool(value)
            continue
        values[kind] = number(value, f"{at}: {kind}", 0.0, 1.0 if kind.startswith("Haptic") else 60.0)
    return values


def _event(timeline: Timeline, event: dict, at: str, control_times, control_values, full_depth: float) -> None:
    kind = event.get("EventType")
    start = number(event.get("Time", 0.0), f"{at}: Time", 0.0, 3600.0)
    if kind in ("AudioCustom", "AudioContinuous"):
        timeline.note(f"{kind} events are sound: not rendered on a friction display")
        return
    if kind not in ("HapticTransient", "HapticContinuous"):
        raise TextureError(f"{at}: EventType {kind!r} is not one AHAP has (HapticTransient, HapticContinuous, "
                           "AudioCustom, AudioContinuous)")
    values = _parameters(timeline, event, at)
    intensity = values.get("HapticIntensity", 1.0) * full_depth
    sharpness = values.get("HapticSharpness", 0.5)
    if kind == "HapticTransient":
        depth = intensity * interpolate(control_times, control_values, start)
        timeline.pulses.append(Pulse(start, depth, pulse_length_s(sharpness)))
        return
    duration = number(event.get("EventDuration"), f"{at}: EventDuration", 0.0, 60.0)
    if duration <= 0:
        return
    if "DecayTime" in values or values.get("Sustain") is False:
        timeline.note("DecayTime and Sustain are not rendered (a continuous event keeps its depth between its "
                      "attack and its release)")
    attack = min(values.get("AttackTime", 0.0), duration)
    release = min(values.get("ReleaseTime", 0.0), duration - attack)
    times = {0.0, attack, duration - release, duration}
    times.update(t - start for t in control_times if start < t < start + duration)
    times = sorted(times)

    def shape(t: float) -> float:  # attack and release ramps
        if attack > 0 and t < attack:
            return t / attack
        if release > 0 and t > duration - release:
            return max(0.0, (duration - t) / release)
        return 1.0

    depths = [intensity * shape(t) * interpolate(control_times, control_values, start + t) for t in times]
    timeline.add_envelope(start, times, depths, [sharpness_hz(sharpness)] * (len(times) - 1))


def read_meta_haptic(document, where: str, full_depth: float = 1.0) -> Timeline:
    """A Timeline from a Meta Haptics Studio ``.haptic`` document (parsed JSON); see the module's text.

    Parameters
    ----------
    document : dict
        The ``.haptic`` JSON.
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
        One line: no amplitude envelope, breakpoints out of order, numbers out of range.

    Examples
    --------
    >>> doc = {"version": {"major": 1}, "signals": {"continuous": {"envelopes": {"amplitude": [
    ...     {"time": 0.0, "amplitude": 0.0}, {"time": 0.5, "amplitude": 1.0}]}}}}
    >>> read_meta_haptic(doc, "ramp.haptic").segments[0].depth1
    1.0
    """
    document = _object(document, f"{where}: a .haptic file")
    signals = _object(document.get("signals"), f"{where}: 'signals'")
    continuous = _object(signals.get("continuous"), f"{where}: 'signals.continuous'")
    envelopes = _object(continuous.get("envelopes"), f"{where}: 'signals.continuous.envelopes'")
    timeline = Timeline(where)
    amplitude = _breakpoints(envelopes.get("amplitude"), "amplitude", f"{where}: the amplitude envelope")
    frequency = _breakpoints(envelopes.get("frequency", []), "frequency", f"{where}: the frequency envelope")
    times = [t for t, _, _ in amplitude]
    depths = [a * full_depth for _, a, _ in amplitude]
    f_times, f_values = [t for t, _, _ in frequency], [v for _, v, _ in frequency]
    hz = [sharpness_hz(interpolate(f_times, f_values, (times[k] + times[k + 1]) / 2) if frequency else 0.5)
          for k in range(len(times) - 1)]
    timeline.add_envelope(0.0, times, depths, hz)
    for t, _, emphasis in amplitude:
        if emphasis is not None:
            timeline.pulses.append(Pulse(t, emphasis[0] * full_depth, pulse_length_s(emphasis[1])))
    for key in signals:
        if key != "continuous":
            timeline.note(f"the {key!r} signals are not rendered")
    return timeline


def _breakpoints(items, key: str, where: str) -> list[tuple[float, float, tuple[float, float] | None]]:
    items = _list(items, where)
    if key == "amplitude" and len(items) < 2:
        raise TextureError(f"{where} needs two breakpoints or more")
    out, last = [], -1.0
    for k, item in enumerate(items):
        item = _object(item, f"{where}, breakpoint {k + 1}")
        t = number(item.get("time"), f"{where}, breakpoint {k + 1} time", 0.0, 3600.0)
        if t < last:
            raise TextureError(f"{where}: breakpoint {k + 1}'s time {t:g} s comes before the one before it")
        last = t
        value = number(item.get(key), f"{where}, breakpoint {k + 1} {key}", 0.0, 1.0)
        emphasis = None
        if "emphasis" in item:
            e = _object(item["emphasis"], f"{where}, breakpoint {k + 1} emphasis")
            emphasis = (number(e.get("amplitude"), f"{where}, breakpoint {k + 1} emphasis amplitude", 0, 1),
                        number(e.get("frequency", 0.5), f"{where}, breakpoint {k + 1} emphasis frequency", 0, 1))
        out.append((t, value, emphasis))
    return out
