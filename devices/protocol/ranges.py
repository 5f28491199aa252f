"""Every number a device reports, checked against what it can be before the host believes it.

A plate driver's HELLO_REPLY, TELEMETRY and SENSORS carry floats and integers that the host acts on: limits it
binds, amplitudes it shows and loops on, counters it adds up, rates and depths it paces by. A value that cannot
be true (NaN, a negative amplitude, a carrier outside the device's own declared range, a buffer deeper than the
device said it holds, a drive above its ceiling, an unknown state code) is a **device fault**: said once in
words, counted, and never believed. docs/protocol.md ("What the host believes") has the table of fields and
ranges this module enforces, each with its reason.

* :func:`hello_out_of_range`: a HELLO_REPLY's fields, as sentences; the handshake refuses such a device in one
  line (its limits and rates are what everything after is bound by).
* :func:`telemetry_out_of_range` and :func:`sensors_out_of_range`: a frame's fields, against the device's
  HELLO_REPLY; a frame with any value that cannot be is not taken (:class:`FieldCheck` counts and words them).
  :func:`clock_reply_out_of_range`: a CLOCK_REPLY's clock against the SENSORS frames read before it was asked.
  The u32 counters are checked by :mod:`ultraglide.devices.counter_check` (modular, with a plausibility bound).

Examples
--------
>>> from ultraglide.devices import protocol as p
>>> hello = p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "plate", 7.5, 1, 1000, 1)
>>> hello_out_of_range(hello)
[]
>>> bad = p.Telemetry(float("nan"), 25000.0, 0, True, 0, 0, 0, 0, 0, 0, 0, (0,) * 8)
>>> telemetry_out_of_range(bad, hello)
[('measured_um_pp', 'measured_um_pp = nan, outside 0..16 µm p-p')]
"""

from __future__ import annotations

import math
import threading

import numpy as np
from ultraglide.devices.protocol.reports import ClockReply, HelloReply, Sensors, Telemetry
from ultraglide.devices.protocol.spec import (
    FAULT_NAMES,
    FEATURE_AMPLITUDE_LOOP,
    FEATURE_BRAKING,
    FEATURE_CLOCK_STATED,
    FEATURE_FORCE_CORRECTION,
    LOOP_AMPLITUDE,
    LOOP_OPEN,
    MAX_CLOCK_LAG_MS,
    MAX_SETPOINTS_PER_FRAME,
    MIN_SENSOR_RATE_HZ,
    PLAYBACK_NAMES,
    SENSOR_AMPLITUDE,
    SENSOR_LATERAL_FORCE,
    SENSOR_NAMES,
    SENSOR_NORMAL_FORCE,
    SETPOINT_SCALE,
)

LOWEST_CARRIER_HZ = 1000.0  # a device's carrier range lies within this .. (profiles.LOWEST_HZ, with allow_audible)
HIGHEST_CARRIER_HZ = 100000.0  # ... this (profiles.HIGHEST_HZ)
MAX_FULL_SCALE_UM_PP = 100.0  # no glass plate moves 100 µm p-p at 20+ kHz (1.2e6 m/s² at 25 kHz): it would break
MAX_SETPOINT_RATE_HZ = 1_000_000  # no link carries more setpoints a second (16 Mbit/s of codes alone)
WATCHDOG_RANGE_MS = (20, 1000)  # docs/protocol.md, Constants: the device's watchdog MUST lie within
BUFFER_RANGE_MS = (50, 1000)  # ... and its buffer
MEASURED_CEILING = 2.0  # a measured amplitude above twice the device's largest drive cannot be: a resonator driven
# from any state overshoots its steady amplitude by less than that (a reversal of the drive's phase: 2x)
MAX_NORMAL_FORCE_N = 100.0  # a normal force beyond this would break the plate; a finger presses 0.1-5 N
MIN_NORMAL_FORCE_N = -5.0  # a force sensor's offset and noise read a little below zero, never 5 N below
MAX_LATERAL_FORCE_N = 100.0
KNOWN_FAULT_BITS = sum(FAULT_NAMES)  # bit 7 is reserved and stays 0; bits 8-15 mean nothing
KNOWN_SENSOR_BITS = SENSOR_AMPLITUDE | SENSOR_NORMAL_FORCE | SENSOR_LATERAL_FORCE
LOOP_MODES = (LOOP_OPEN, LOOP_AMPLITUDE)
SAMPLE_GAP_S = 1.0  # SENSORS may skip samples (a frame lost on the link) for up to this long, never go back
_WRAP = 1 << 32


def _number(name: str, value: float, low: float, high: float, unit: str) -> str | None:
    """None if ``value`` is a finite number within ``low..high``, else the sentence saying what it is not."""
    if isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and low <= value <= high:
        return None
    return f"{name} = {value:g}, outside {low:g}..{high:g} {unit}"


def hello_out_of_range(hello: HelloReply) -> list[str]:
    """What in a device's HELLO_REPLY cannot be true, one sentence a field (empty: all of it can).

    Parameters
    ----------
    hello : HelloReply
        The device's reply, as parsed (v2 or v3).

    Returns
    -------
    list of str
        ``"watchdog_ms = 5, outside 20..1000 ms"`` and the like.

    Examples
    --------
    >>> from ultraglide.devices import protocol as p
    >>> hello_out_of_range(p.HelloReply(2, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 5, 250, "x"))
    ['watchdog_ms = 5, outside 20..1000 ms']
    """
    said = []
    low_hz, high_hz = hello.carrier_min_hz, hello.carrier_max_hz
    said.append(_number("carrier_min_hz", low_hz, LOWEST_CARRIER_HZ, HIGHEST_CARRIER_HZ, "Hz"))
    said.append(_number("carrier_max_hz", high_hz, low_hz if math.isfinite(low_hz) else LOWEST_CARRIER_HZ,
                        HIGHEST_CARRIER_HZ, "Hz"))
    if said == [None, None]:
        said.append(_number("resonance_hz", hello.resonance_hz, low_hz, high_hz, "Hz (its own carrier range)"))
    said.append(_number("full_scale_um_pp", hello.full_scale_um_pp, 1e-6, MAX_FULL_SCALE_UM_PP, "µm p-p"))
    full_scale = hello.full_scale_um_pp if math.isfinite(hello.full_scale_um_pp) else MAX_FULL_SCALE_UM_PP
    said.append(_number("max_amplitude_um_pp", hello.max_amplitude_um_pp, 1e-6, full_scale,
                        "µm p-p (up to its full scale)"))
    said.append(_number("min_setpoint_rate_hz", hello.min_setpoint_rate_hz, 1, MAX_SETPOINT_RATE_HZ,
                        "setpoints a second"))
    said.append(_number("max_setpoint_rate_hz", hello.max_setpoint_rate_hz, max(1, hello.min_setpoint_rate_hz),
                        MAX_SETPOINT_RATE_HZ, "setpoints a second (from min_setpoint_rate_hz)"))
    said.append(_number("watchdog_ms", hello.watchdog_ms, *WATCHDOG_RANGE_MS, "ms"))
    said.append(_number("buffer_ms", hello.buffer_ms, *BUFFER_RANGE_MS, "ms"))
    if hello.version >= 3:
        limit = hello.max_amplitude_um_pp if math.isfinite(hello.max_amplitude_um_pp) else 0.0
        said.append(_number("max_drive_um_pp", hello.max_drive_um_pp, limit, full_scale,
                            "µm p-p (from max_amplitude_um_pp to full_scale_um_pp)"))
        if hello.sensors & ~KNOWN_SENSOR_BITS:
            said.append(f"sensors = {hello.sensors:#04x} has bits no sensor is defined for")
        if hello.sensors and hello.sensor_rate_hz < MIN_SENSOR_RATE_HZ:
            said.append(f"sensor_rate_hz = {hello.sensor_rate_hz} with sensors, below {MIN_SENSOR_RATE_HZ}")
        if not hello.sensors and hello.sensor_rate_hz:
            said.append(f"sensor_rate_hz = {hello.sensor_rate_hz} with no sensor (it must be 0)")
        if hello.features & FEATURE_BRAKING and not hello.features & FEATURE_AMPLITUDE_LOOP:
            said.append("features says braking without the amplitude loop it brakes with")
        if hello.features & FEATURE_FORCE_CORRECTION and not hello.sensors & SENSOR_NORMAL_FORCE:
            said.append("features says force correction without the normal force sensor it needs")
        if hello.features & FEATURE_CLOCK_STATED and not hello.sensors:
            said.append("features says it states its sensor clock (CLOCK) without a sensor to have one")
    return [sentence for sentence in said if sentence is not None]


def telemetry_out_of_range(telemetry: Telemetry, hello: HelloReply) -> list[tuple[str, str]]:
    """What in one TELEMETRY frame cannot be true, given the device's HELLO_REPLY: ``(field, sentence)`` pairs
    (empty: the frame can be believed). The u32 counters are :mod:`~ultraglide.devices.counter_check`'s.

    Parameters
    ----------
    telemetry : Telemetry
        The frame, as parsed.
    hello : HelloReply
        What the device said of itself at the handshake (already checked by :func:`hello_out_of_range`).

    Returns
    -------
    list of (str, str)
        The field's name and a sentence with its value and the range it should lie in.
    """
    t, said = telemetry, []
    ceiling = MEASURED_CEILING * max(hello.full_scale_um_pp, hello.max_drive_um_pp or 0.0)
    said.append(("measured_um_pp", _number("measured_um_pp", t.measured_um_pp, 0.0, ceiling, "µm p-p")))
    said.append(("carrier_hz", _number("carrier_hz", t.carrier_hz, hello.carrier_min_hz, hello.carrier_max_hz,
                                       "Hz (its own carrier range)")))
    if t.faults & ~KNOWN_FAULT_BITS:
        said.append(("faults", f"faults = {t.faults:#06x} has bits no fault is defined for"))
    if t.version >= 3:
        rate = t.stream_rate_hz
        if rate and not hello.min_setpoint_rate_hz <= rate <= hello.max_setpoint_rate_hz:
            said.append(("stream_rate_hz", f"stream_rate_hz = {rate}, outside its own {hello.min_setpoint_rate_hz}-"
                                           f"{hello.max_setpoint_rate_hz} (or 0: no stream)"))
        if not rate and t.expected_index:
            said.append(("expected_index", f"expected_index = {t.expected_index} with no stream (it must be 0)"))
        depth = math.ceil(hello.buffer_ms * (rate or hello.max_setpoint_rate_hz) / 1000.0) + MAX_SETPOINTS_PER_FRAME
        if t.buffered_setpoints > depth:
            said.append(("buffered_setpoints", f"buffered_setpoints = {t.buffered_setpoints}, more than its "
                                               f"{hello.buffer_ms} ms buffer holds ({depth} with a frame's slack)"))
        top = math.ceil(hello.max_drive_um_pp / hello.full_scale_um_pp * SETPOINT_SCALE) + 1
        if t.drive_code > top:
            said.append(("drive_code", f"drive_code = {t.drive_code}, above its drive ceiling "
                                       f"({hello.max_drive_um_pp:g} µm p-p of {hello.full_scale_um_pp:g}: {top})"))
        if t.playback not in PLAYBACK_NAMES:
            said.append(("playback", f"playback = {t.playback}, not a state (0-{max(PLAYBACK_NAMES)})"))
        if t.loop not in LOOP_MODES:
            said.append(("loop", f"loop = {t.loop}, not a loop mode (0 open, 1 amplitude)"))
    return [(name, sentence) for name, sentence in said if sentence is not None]


def sensors_out_of_range(sensors: Sensors, hello: HelloReply, expected_first: int | None = None) \
        -> list[tuple[str, str]]:
    """What in one SENSORS frame cannot be true, given the device's HELLO_REPLY and the sample number the
    previous frame leads to (``expected_first``; None for the first frame of a connection): ``(field, sentence)``
    pairs. A channel the device declared no sensor for must be NaN; one it declared, a finite number in range.

    Parameters
    ----------
    sensors : Sensors
        The frame, as parsed (its count already checked: 1 to 80 samples).
    hello : HelloReply
        What the device said of itself.
    expected_first : int, optional
        The previous frame's ``first_sample`` plus its count (mod 2**32).

    Returns
    -------
    list of (str, str)
        The field's name and a sentence.
    """
    said = []
    if not hello.sensors:
        said.append(("sensors", "a SENSORS frame from a device that declared no sensor"))
    ceiling = MEASURED_CEILING * max(hello.full_scale_um_pp, hello.max_drive_um_pp or 0.0)
    channels = (("amplitude_um_pp", SENSOR_AMPLITUDE, 0.0, ceiling, "µm p-p"),
                ("normal_force_n", SENSOR_NORMAL_FORCE, MIN_NORMAL_FORCE_N, MAX_NORMAL_FORCE_N, "N"),
                ("lateral_force_n", SENSOR_LATERAL_FORCE, -MAX_LATERAL_FORCE_N, MAX_LATERAL_FORCE_N, "N"))
    samples = sensors.samples
    for name, bit, low, high, unit in channels:
        values = np.asarray(samples[name], dtype=np.float64)
        if not hello.sensors & bit:
            if not np.all(np.isnan(values)):
                said.append((name, f"{name} = {values[~np.isnan(values)][0]:g} from a device without a "
                                   f"{SENSOR_NAMES[bit]} sensor (it must be NaN)"))
            continue
        bad = ~(np.isfinite(values) & (values >= low) & (values <= high))
        if bad.any():
            said.append((name, f"{_number(name, float(values[bad][0]), low, high, unit)}"))
    if expected_first is not None and hello.sensor_rate_hz:
        step = (sensors.first_sample - expected_first) % _WRAP
        if step > SAMPLE_GAP_S * hello.sensor_rate_hz:
            said.append(("first_sample", f"first_sample = {sensors.first_sample}, not the {expected_first} the "
                                         f"frame before leads to (nor a gap of up to {SAMPLE_GAP_S:g} s after it)"))
    return said


def clock_reply_out_of_range(reply: ClockReply, hello: HelloReply, sent_end: int | None, since_s: float) \
        -> list[tuple[str, str]]:
    """What in one CLOCK_REPLY cannot be true: its clock against the end of the last SENSORS frame read before the
    CLOCK request was sent (``sent_end``, that frame's ``first_sample`` plus its count; None: no frame yet, nothing
    to compare). The device had taken those samples before it took the request, so its clock is at most
    ``MAX_CLOCK_LAG_MS`` behind them; and it is no further ahead than the time since that frame was read
    (``since_s``) and a second (SENSORS' own allowance for a frame's delay).

    Parameters
    ----------
    reply : ClockReply
        The reply, as parsed.
    hello : HelloReply
        What the device said of itself (its ``sensor_rate_hz``).
    sent_end : int or None
        The sample number the last SENSORS frame read before the request leads to (mod 2**32).
    since_s : float
        Seconds from that frame's reading to the reply's.

    Returns
    -------
    list of (str, str)
        The field's name and a sentence (empty: believed).

    Examples
    --------
    >>> from ultraglide.devices import protocol as p
    >>> hello = p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "plate", 7.5, 1, 1000,
    ...                      p.FEATURE_CLOCK_STATED)
    >>> clock_reply_out_of_range(p.ClockReply(7, 1003, 0), hello, 1000, 0.01)
    []
    >>> clock_reply_out_of_range(p.ClockReply(7, 990, 0), hello, 1000, 0.01)
    [('sample', 'sample = 990.0, 10 samples behind the 1000 its SENSORS had reached (at most 1 ms: 1 sample)')]
    """
    if sent_end is None or not hello.sensor_rate_hz:
        return []
    ahead = (reply.sample - sent_end + _WRAP // 2) % _WRAP - _WRAP // 2 + reply.fraction / 65536.0
    lag = MAX_CLOCK_LAG_MS * hello.sensor_rate_hz / 1000.0
    most = hello.sensor_rate_hz * (SAMPLE_GAP_S + max(since_s, 0.0))
    if ahead < -lag:
        return [("sample", f"sample = {reply.samples:.1f}, {-ahead:g} samples behind the {sent_end} its SENSORS had "
                           f"reached (at most {MAX_CLOCK_LAG_MS} ms: {lag:g} sample{'s' if lag != 1 else ''})")]
    if ahead > most:
        return [("sample", f"sample = {reply.samples:.1f}, {ahead:g} samples ahead of the {sent_end} its SENSORS had "
                           f"reached {since_s:.3f} s before (at most {SAMPLE_GAP_S:g} s more)")]
    return []


class FieldCheck:
    """The device's values that could not be believed over a run: counted, each field's first said.

    Thread-safe (frames are checked on the reader thread, the report read on others).

    Examples
    --------
    >>> check = FieldCheck()
    >>> check.add("TELEMETRY", [("carrier_hz", "carrier_hz = 3e+04, not ...")], at_s=1.5)
    >>> check.count, check.words().startswith("the plate reported values that cannot be: TELEMETRY carrier_hz")
    (1, True)
    """

    def __init__(self):
        self._lock = threading.Lock()
        self.first: dict[str, tuple[str, float | None]] = {}  # "FRAME field": (sentence, when) of its first
        self.count = 0  # frames not believed
        self.by_field: dict[str, int] = {}

    def add(self, frame: str, faults: list[tuple[str, str]], at_s: float | None = None) -> None:
        """A ``frame`` (its kind's name) not believed for ``faults`` (``(field, sentence)`` pairs), ``at_s`` s into
        the run."""
        with self._lock:
            self.count += 1
            for field, sentence in faults:
                key = f"{frame} {field}"
                self.by_field[key] = self.by_field.get(key, 0) + 1
                self.first.setdefault(key, (sentence, at_s))

    def counts(self) -> dict[str, int]:
        """Frames not believed, by ``"FRAME field"``."""
        with self._lock:
            return dict(self.by_field)

    def words(self) -> str | None:
        """One sentence for the run's report, or None if every value could be believed."""
        with self._lock:
            if not self.first:
                return None
            said = "; ".join(f"{key} ({sentence}, {self.by_field[key]} in all)" for key, (sentence, _) in
                             list(self.first.items())[:4])
            more, count = len(self.first) - 4, self.count
        return (f"the plate reported values that cannot be: {said}{f'; {more} more fields' if more > 0 else ''}; "
                f"{count} frame{'s' if count != 1 else ''} not believed")

    def first_s(self) -> float:
        """When the first value that cannot be came (s into the run; 0 if unknown)."""
        with self._lock:
            times = [at for _, at in self.first.values() if at is not None]
        return min(times, default=0.0)
