"""A simulated plate that lies: fields of what it reports replaced on their way out, within the protocol's framing.

The simulator (:class:`~ultraglide.devices.sim.plate.PlateSimulator`, its firmware core) reports what is true of
its plate; a host must also hold against a device that does not. :class:`Lies` rewrites the frames a
:class:`~ultraglide.devices.sim.pty_plate.PtyPlate` sends: a HELLO_REPLY, TELEMETRY or SENSORS field given a
fixed value (each frame re-encoded whole, its seq kept, its CRC right), so the host reads a well-formed frame
that says what cannot be, or what does not follow what it was told. ``plate-sim --lie FRAME.FIELD=VALUE`` serves
one.

Examples
--------
>>> lies = Lies.parse(["telemetry.measured_um_pp=0.2", "hello.watchdog_ms=5"])
>>> lies
Lies(telemetry.measured_um_pp=0.2, hello.watchdog_ms=5)
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError

FRAMES = {"hello": (p.HELLO_REPLY, p.HelloReply), "telemetry": (p.TELEMETRY, p.Telemetry),
          "sensors": (p.SENSORS, None), "clock_reply": (p.CLOCK_REPLY, p.ClockReply)}
SENSOR_FIELDS = ("first_sample", "setpoint_index", "amplitude_um_pp", "normal_force_n", "lateral_force_n")


def _fields(frame: str) -> tuple[str, ...]:
    cls = FRAMES[frame][1]
    if cls is None:
        return SENSOR_FIELDS
    return tuple(f.name for f in dataclasses.fields(cls) if f.name not in ("version", "name"))


class Lies:
    """Fields replaced in the frames a simulated plate sends: ``{"telemetry.carrier_hz": 30000.0, ...}``."""

    def __init__(self, fields: dict[str, float]):
        self.fields = dict(fields)
        self._by_frame: dict[int, dict[str, float]] = {}
        for key, value in self.fields.items():
            frame, _, name = key.partition(".")
            if frame not in FRAMES or name not in _fields(frame):
                known = ", ".join(f"{f}.{n}" for f in FRAMES for n in _fields(f))
                raise DeviceError(f"no field {key!r} to lie about; known: {known}")
            self._by_frame.setdefault(FRAMES[frame][0], {})[name] = value

    @classmethod
    def parse(cls, specs) -> Lies:
        """From ``FRAME.FIELD=VALUE`` strings (the value a number: ``nan``, ``inf`` and ``-1`` included);
        DeviceError in one line for one that is not."""
        fields = {}
        for spec in specs:
            key, equals, text = str(spec).partition("=")
            try:
                value = float(text)
            except ValueError:
                value = None
            if not equals or value is None:
                raise DeviceError(f"--lie {spec!r}: give FRAME.FIELD=NUMBER, e.g. telemetry.measured_um_pp=0")
            fields[key.strip()] = value
        return cls(fields)

    def __repr__(self) -> str:
        return "Lies(" + ", ".join(f"{key}={value:g}" for key, value in self.fields.items()) + ")"

    def __bool__(self) -> bool:
        return bool(self.fields)

    def rewrite(self, frames: list[bytes]) -> list[bytes]:
        """The encoded frames with the lies told (frames of other kinds, and undecodable ones, as they were)."""
        told = []
        for encoded in frames:
            decoded = p.FrameDecoder().feed(encoded)
            lies = self._by_frame.get(decoded[0].kind) if len(decoded) == 1 else None
            if not lies:
                told.append(encoded)
                continue
            frame = decoded[0]
            told.append(p.encode_frame(frame.kind, frame.seq, self._payload(frame.kind, frame.payload, lies)))
        return told

    @staticmethod
    def _payload(kind: int, payload: bytes, lies: dict[str, float]) -> bytes:
        if kind == p.HELLO_REPLY:
            hello = p.parse_hello_reply(payload)
            return p.hello_reply_payload(dataclasses.replace(hello, **_typed(hello, lies)))
        if kind == p.TELEMETRY:
            telemetry = p.parse_telemetry(payload)
            return p.telemetry_payload(dataclasses.replace(telemetry, **_typed(telemetry, lies)), telemetry.version)
        if kind == p.CLOCK_REPLY:
            reply = p.parse_clock_reply(payload)
            return p.clock_reply_payload(dataclasses.replace(reply, **_typed(reply, lies)))
        sensors = p.parse_sensors(payload)
        samples = np.array(sensors.samples)
        for name in ("amplitude_um_pp", "normal_force_n", "lateral_force_n"):
            if name in lies:
                samples[name] = lies[name]
        first = int(lies.get("first_sample", sensors.first_sample))
        index = int(lies.get("setpoint_index", sensors.setpoint_index))
        return p.sensors_payload(first, index, samples)


def _typed(report, lies: dict[str, float]) -> dict:
    """The lies in each field's own type: integers for integer fields (a non-integer value cut)."""
    typed = {}
    for name, value in lies.items():
        current = getattr(report, name)
        if isinstance(current, bool):
            typed[name] = bool(value)
        elif (isinstance(current, int) or current is None) and math.isfinite(value):  # (None: an unstated code)
            typed[name] = int(value)
        else:
            typed[name] = float(value)
    return typed
