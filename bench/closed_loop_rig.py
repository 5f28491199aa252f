"""The host and the simulated plate in simulated time: the same parts as ``play`` on ``plate-sim``, no threads.

The engine's parts (the renderer on a swipe, the friction loop as its model, the output stage's limiter) and
the simulated plate's (the firmware core through its binding, the plate's physics, the simulated finger) are
joined by protocol v3's frames, each delivered ``link_s`` after it was sent (SETPOINTS every millisecond, as
the serial driver sends them on a 921 600 baud link). Time is the rig's: a millisecond is computed whatever
the machine's load, so the figures are those of the control, not of the machine's scheduling (a loaded
machine's underruns are ``play``'s and ``plate-sim``'s to report). Errors are measured as in the real-time
runs: each row of the finger's log lined up with the stream value the plate was playing (SENSORS).

    run = ClosedLoopRig(texture, speed_mm_s=100, closed=True).run(seconds=10)
    run.rms_error(after_s=2)
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.output.stage import output_stage
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.plate import PlateSimulator, PlateTruth
from ultraglide.render.engine.finger_setup import FingerConfig, build_finger, finger_law
from ultraglide.render.engine.friction_loop import FrictionLoop
from ultraglide.render.engine.loop_plate import AmplitudeLoopPlate
from ultraglide.render.engine.sources import EnvelopeSource
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.renderer import Renderer, RenderSettings

CONTROL_HZ = 12000
FRAME = 12  # setpoints a frame: one a millisecond
SENSOR_HZ = 1000.0


@dataclass
class RigRun:
    """Per row of the finger's log (its times from the plate's start): the truth and the stream value played."""

    t: np.ndarray
    ratio: np.ndarray  # the finger's
    amplitude: np.ndarray  # the plate's
    force: np.ndarray
    sliding: np.ndarray
    target: np.ndarray  # the texture's, for the value playing (NaN: none played)
    commanded: np.ndarray
    intended: np.ndarray  # the amplitude the model (or the loop) chose for the target, before the envelope
    down: np.ndarray
    floor: np.ndarray  # the lowest ratio the finger's law reaches within the limit then
    status: dict
    peak_um_pp: float
    drive_range_um_pp: tuple[float, float]  # the lowest (braking) and highest drive the plate received
    law_at_intended: np.ndarray  # the finger's ratio had the plate reached the intended amplitude at once
    index: np.ndarray | None = None  # the stream index playing (-1: none)
    targets: np.ndarray | None = None  # the texture's target of every stream index (NaN: none played)
    speed_mm_s: float = 100.0

    def loop_error(self, after_s: float = 2.0) -> float:
        """The ratio error of the amplitude the model or loop chose, as if the plate reached it at once: the
        friction loop's own part, without the plate's dynamics."""
        pick = self.pick(after_s)
        return float(np.sqrt(np.mean((self.law_at_intended[pick] - self.target[pick]) ** 2)))

    def pick(self, after_s: float, reachable: bool = False) -> np.ndarray:
        swiped = self.down & self.sliding & np.isfinite(self.target)
        if not swiped.any():
            return swiped
        chosen = swiped & (self.t >= self.t[swiped][0] + after_s) & (self.t < self.t[swiped][-1] - 0.05)
        return chosen & (self.target >= self.floor) if reachable else chosen

    def rms_error(self, after_s: float = 2.0, reachable: bool = False) -> float:
        pick = self.pick(after_s, reachable)
        return float(np.sqrt(np.mean((self.ratio[pick] - self.target[pick]) ** 2)))

    def planned_felt(self) -> np.ndarray:
        """Per row, the friction the plan means felt for the value playing (NaN where none): the swipe's targets
        through the published dynamics and the planner (render/planning.felt_over), at the finger's median floor
        within the limit, as the real-time bench judges a lagging finger."""
        from ultraglide.render.physics.dynamics import FrictionDynamics
        from ultraglide.render.planning import felt_over

        played = np.flatnonzero(np.isfinite(self.targets))
        felt = np.full(len(self.targets), np.nan)
        horizon = 2400  # beyond the planner's
        n = played[-1] - played[0] + 1 - horizon if len(played) else 0
        if n <= 0:
            return np.full(len(self.t), np.nan)
        swiped = self.pick(0.0)
        floor = float(np.median(self.floor[swiped])) if swiped.any() else 0.1
        _, planned = felt_over(FrictionDynamics(), self.targets[played[0]:played[-1] + 1], n, self.speed_mm_s, floor)
        felt[played[0]:played[0] + n] = planned
        return np.where(self.index >= 0, felt[np.clip(self.index, 0, len(felt) - 1)], np.nan)

    def planned_error(self, after_s: float = 2.0) -> float:
        """RMS of the finger's ratio against the friction the plan means felt (:meth:`planned_felt`)."""
        meant = self.planned_felt()
        pick = self.pick(after_s) & np.isfinite(meant)
        return float(np.sqrt(np.mean((self.ratio[pick] - meant[pick]) ** 2)))


class ClosedLoopRig:
    """See the module docstring. ``texture``: a Texture; ``finger``: its FingerConfig (default: the default finger
    without its lag, the static law the loop of issue 25 was built for; ``FingerConfig()`` for the lagging one);
    ``q``: the plate's real Q (None: the profile's); ``closed``: the friction loop on (and the amplitude loop);
    ``braking``: the firmware's amplitude loop may brake (an antiphase drive), else its drive only pushes;
    ``force_correction``: the loop's values sent with the force they were computed at (SETPOINTS_FORCE), which the
    firmware corrects to the force it measures as they play."""

    def __init__(self, texture, speed_mm_s: float = 100.0, closed: bool = True, finger: FingerConfig | None = None,
                 model: str = "stretched", profile: str = "sim-plate", q: float | None = None, link_s: float = 0.001,
                 force_n: float = 0.5, log_hz: float = 4000.0, start_mm=(2.0, 25.0), seconds: float = 10.0,
                 lead_s: float = 0.5, loop_tau_s: float | None = None, braking: bool = True,
                 force_correction: bool = True):
        self.profile = load_profile(profile)
        self.config = (finger or FingerConfig(dynamics=False)).with_log(None)
        self.finger = build_finger(self.config)
        from ultraglide.devices.sim.finger_log import FingerLog

        self.log = FingerLog(None, rate_hz=log_hz, clock_origin_s=0.0)
        self.finger.log = self.log
        truth = PlateTruth(self.profile.resonance_hz, q or self.profile.q)
        self.plate = PlateSimulator(self.profile, truth=truth, finger=self.finger, braking=braking)
        self.plate._started = self.plate._clock = 0.0  # the rig's clock: s from the plate's start
        self.finger.set_clock_origin(0.0)
        self.model = load_model(model)
        self.closed = closed
        self.force_correction = force_correction
        self.limit_fraction = self.profile.max_amplitude_um_pp / self.profile.full_scale_um_pp
        self.loop = FrictionLoop(self.model, CONTROL_HZ, clock=lambda: self.now) if closed else None
        seen = AmplitudeLoopPlate.of(self.profile, loop_tau_s) if closed else self.profile
        path = SwipePath("straight", speed_mm_s, seconds, start_mm, force_n=force_n)
        self.speed_mm_s = speed_mm_s
        self.lead_s = lead_s  # the plate runs this long before the swipe (the finger slides already)
        self.renderer = Renderer(texture, self.loop.inverse if closed else self.model, seen,
                                 RenderSettings(default_force_n=force_n), trajectory=path)
        self.stage = output_stage(EnvelopeSource(self.renderer), self.profile, "control", CONTROL_HZ)
        self.framer = p.SetpointFramer(CONTROL_HZ)
        self.decoder = p.FrameDecoder()
        self.link_ms = max(1, int(round(link_s * 1000)))
        self.now = 0.0
        self._seq = 0
        self._index = 0
        self._to_plate: deque = deque()
        self._to_host: deque = deque()
        self.targets: list[np.ndarray] = []
        self.commanded: list[np.ndarray] = []
        self.intended: list[np.ndarray] = []
        self.downs: list[np.ndarray] = []
        self.sensors: list[tuple[int, int]] = []  # (first sample, setpoint index) of each SENSORS frame
        self.hello: p.HelloReply | None = None

    def _send(self, kind: int, payload: bytes = b"", setpoints: np.ndarray | None = None, at_ms: int = 0,
              force: p.ForceReference | None = None) -> None:
        self._seq = (self._seq + 1) & 0xFFFF
        frame = self.framer.frame(self._seq, self._index, setpoints, force) if setpoints is not None else \
            p.encode_frame(kind, self._seq, payload)
        self._to_plate.append((at_ms + self.link_ms, frame))

    def _handshake(self) -> None:
        self._send(p.HELLO, p.hello_payload())
        if self.closed:
            self._send(p.SET_LOOP, p.set_loop_payload(1))
        self._send(p.SET_CARRIER, p.carrier_payload(self.profile.resonance_hz))
        self._send(p.ENABLE, p.enable_payload(True))

    def run(self, seconds: float) -> RigRun:
        """Play the swipe (``seconds`` long, after ``lead_s`` of the finger sliding on a resting plate)."""
        self._handshake()
        total_ms = int(round((seconds + self.lead_s) * 1000)) + 50
        lead_ms = int(round(self.lead_s * 1000))
        for ms in range(total_ms):
            self.now = ms / 1000.0
            while self._to_plate and self._to_plate[0][0] <= ms:
                for reply in self.plate.receive(self._to_plate.popleft()[1]):
                    self._to_host.append((ms + self.link_ms, reply))
            for reply in self.plate.advance(self.now):
                self._to_host.append((ms + self.link_ms, reply))
            while self._to_host and self._to_host[0][0] <= ms:
                self._take(self._to_host.popleft()[1])
            if ms >= lead_ms:
                drive = np.array(self.stage.pull(FRAME, self.now), dtype=float)
                block = self.renderer.last_block
                self.targets.append(np.array(block.ratio, dtype=float))
                self.commanded.append(drive)
                self.intended.append(np.array(block.target_um_pp, dtype=float))
                down = block.down  # one for the block (a swipe's) or one a sample
                self.downs.append(np.full(FRAME, down, dtype=bool) if np.ndim(down) == 0 else
                                  np.array(down, dtype=bool))
                if self.loop is not None:
                    self.loop.record(block.ratio, block.down, block.planned_ratio)
                    x, y = block.x_mm, block.y_mm
                    self.loop.panel_speed_mm_s = math.hypot(x[-1] - x[0], y[-1] - y[0]) * CONTROL_HZ / (FRAME - 1)
            else:
                drive = np.zeros(FRAME)
                if self.loop is not None:
                    self.loop.record(np.full(FRAME, np.nan), False)  # the stream's index runs from the start
                self.targets.append(np.full(FRAME, np.nan))
                self.commanded.append(drive)
                self.intended.append(drive)
                self.downs.append(np.zeros(FRAME, dtype=bool))
            self._send(p.SETPOINTS, setpoints=drive / self.profile.full_scale_um_pp, at_ms=ms,
                       force=self._force_reference() if ms >= lead_ms else None)
            self._index += FRAME
        self.finger.close()
        return self._result()

    def _force_reference(self) -> p.ForceReference | None:
        """SETPOINTS_FORCE's reference for the frame just rendered (None: plain SETPOINTS), as the serial writer
        makes it."""
        if not (self.closed and self.force_correction and self.hello is not None and self.hello.has_force_correction):
            return None
        reference = self.loop.inverse.force_reference
        return None if reference is None else p.ForceReference(reference[0], reference[1], self.limit_fraction)

    def _take(self, data: bytes) -> None:
        for frame in self.decoder.feed(data):
            if frame.kind == p.SENSORS:
                sensors = p.parse_sensors(frame.payload)
                self.sensors.append((sensors.first_sample, sensors.setpoint_index, len(sensors.samples)))
                if self.loop is not None:
                    self.loop.take_sensors_frame(sensors, self.now)
            elif frame.kind == p.HELLO_REPLY:
                self.hello = p.parse_hello_reply(frame.payload)

    def _result(self) -> RigRun:
        rows = self.log.rows()
        t, amplitude, force, ratio, sliding = rows.T
        targets, commanded = np.concatenate(self.targets), np.concatenate(self.commanded)
        intended = np.concatenate(self.intended)
        downs = np.concatenate(self.downs)
        starts, indices = [], []
        for first, index, count in self.sensors:
            if index == p.NOT_PLAYING:
                continue
            for k in range(count):
                starts.append((first + k) / SENSOR_HZ)
                indices.append(index + k * CONTROL_HZ / SENSOR_HZ)
        starts, indices = np.array(starts), np.array(indices)
        row = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
        known = (t >= starts[row]) & (t - starts[row] < 1.0 / SENSOR_HZ + 1e-9)
        index = (indices[row] + np.floor((t - starts[row]) * CONTROL_HZ)).astype(int)
        known &= (index >= 0) & (index < len(targets))
        index = np.clip(index, 0, len(targets) - 1)
        law = finger_law(self.config)
        scale = 1.0 + self.config.drift * np.sin(2 * math.pi * t / self.config.drift_period_s)
        floor = law(np.full(len(t), self.profile.max_amplitude_um_pp) / scale, np.maximum(force, 0.01))
        status = self.loop.status() if self.loop is not None else {}
        chosen = np.where(known, intended[index], 0.0)
        return RigRun(t, ratio, amplitude, force, sliding > 0.5, np.where(known, targets[index], np.nan),
                      np.where(known, commanded[index], np.nan), np.where(known, intended[index], np.nan),
                      known & downs[index], floor, status, self.plate.peak_um_pp, self.plate.drive_range_um_pp,
                      law(chosen / scale, np.maximum(force, 0.01)), np.where(known, index, -1),
                      np.where(downs, targets, np.nan), self.speed_mm_s)
