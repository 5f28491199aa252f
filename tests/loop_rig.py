"""The friction loop closed around a simulated finger in simulated time: no threads, no pty, no firmware.

Each millisecond the host renders 12 control samples of amplitude for the target ratio (through the loop's
inverse, or the model's for open loop); the plate plays them ``buffer_s`` later (the jitter buffer), its
amplitude following through a first-order lag ``plate_tau_s`` (as the firmware's amplitude loop makes it);
the real :class:`~ultraglide.devices.finger.SimulatedFinger` presses on it at 48 kHz; a sensor sample is the
mean over each millisecond (as the firmware makes it), ten to a SENSORS frame, which reaches the loop
``link_s`` later with the stream index that was playing. The finger's truth is what the errors are
measured against.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter
from ultraglide.devices.finger import FingerParams, ForceScript, SimulatedFinger
from ultraglide.devices.finger_log import FingerLog
from ultraglide.devices.force_sensors import ForceSensorParams
from ultraglide.render.engine.friction_loop import FrictionLoop, LoopSettings

FS = 48000
CONTROL_HZ = 12000
UP = FS // CONTROL_HZ


@dataclass
class RigRun:
    t_s: np.ndarray  # the plate's time of each truth row
    target: np.ndarray  # the target ratio played then
    truth: np.ndarray  # the finger's ratio
    amplitude_um_pp: np.ndarray  # the plate's
    commanded_um_pp: np.ndarray
    sliding: np.ndarray
    force_n: np.ndarray

    def rms_error(self, after_s: float = 0.0, reachable: np.ndarray | None = None) -> float:
        pick = (self.t_s >= after_s) & self.sliding & np.isfinite(self.target)
        if reachable is not None:
            pick &= reachable
        return float(np.sqrt(np.mean((self.truth[pick] - self.target[pick]) ** 2)))


def floored(law, floor: float):
    """A law with a floor: d + (1 - d) law."""
    return lambda a, f: floor + (1.0 - floor) * law(a, f)


class LoopRig:
    def __init__(self, host_model, finger_law, script: ForceScript | None = None, params: FingerParams | None = None,
                 sensors: ForceSensorParams | None = None, closed: bool = True, settings: LoopSettings | None = None,
                 limit_um_pp: float = 6.0, panel_force_n: float = 0.5, buffer_s: float = 0.010,
                 plate_tau_s: float = 0.0011, link_s: float = 0.002, panel_speed_mm_s: float | None = 100.0,
                 precompensate_s: float = 0.0):
        self.now = 0.0
        self.model = host_model
        self.loop = FrictionLoop(host_model, CONTROL_HZ, 1000.0, settings, clock=lambda: self.now) if closed else None
        if self.loop is not None:
            self.loop.panel_speed_mm_s = panel_speed_mm_s
        self.log = FingerLog(None, rate_hz=2000.0, clock_origin_s=0.0)
        self.finger = SimulatedFinger(finger_law, script or ForceScript.constant(0.5), params or FingerParams(),
                                      sensors or ForceSensorParams(), log=self.log)
        self.limit = limit_um_pp
        self.panel_force_n = panel_force_n
        self.delay_ms = int(round(buffer_s * 1000))
        self.alpha = math.exp(-1.0 / (FS * plate_tau_s)) if plate_tau_s > 0 else 0.0
        self.link_ms = int(round(link_s * 1000))
        self.plate = 0.0
        self.beta = math.exp(-1.0 / (CONTROL_HZ * precompensate_s)) if precompensate_s > 0 else 0.0
        self.modelled = 0.0  # the host's model of the plate's lag, for its pre-compensation
        self.queue: deque = deque()  # setpoints waiting in the jitter buffer (one block a ms)
        self.frames: deque = deque()  # SENSORS frames on the link: (deliver at ms, frame)
        self.pending = []  # sensor samples not yet framed
        self.sample = 0  # sensor samples taken
        self.index = 0  # stream index of the next setpoint rendered
        self.targets_played: list[np.ndarray] = []
        self.commanded: list[np.ndarray] = []
        self.fault = None  # a function(sample_number, (a, F, L)) -> (a, F, L) to break the sensors, or None
        self.silent_from_ms = None  # SENSORS stop reaching the host from this ms

    def run(self, target, duration_s: float) -> RigRun:
        """``target(t_s)``: the target ratio at the plate's times (an array function)."""
        ms_total = int(round(duration_s * 1000))
        for ms in range(ms_total):
            self.now = ms / 1000.0
            self._deliver(ms)
            t_play = (ms + self.delay_ms) / 1000.0 + np.arange(CONTROL_HZ // 1000) / CONTROL_HZ
            ratio = np.asarray(target(t_play), dtype=float)
            inverse = self.loop.inverse if self.loop is not None else self.model
            amplitude = inverse.amplitude_um_pp(ratio, self.panel_force_n, self.limit).amplitude_um_pp.copy()
            if self.beta:  # drive the inverse of the lag the host expects, within [0, limit]
                for i, y in enumerate(amplitude.tolist()):
                    d = min(max((y - self.beta * self.modelled) / (1.0 - self.beta), 0.0), self.limit)
                    self.modelled = self.beta * self.modelled + (1.0 - self.beta) * d
                    amplitude[i] = d
            if self.loop is not None:
                self.loop.record(ratio, True)
            self.queue.append((self.index, ratio, amplitude))
            self.index += len(ratio)
            if len(self.queue) > self.delay_ms:
                self._play(*self.queue.popleft(), ms)
        self.finger.close()
        rows = self.log.rows()
        played = np.concatenate(self.targets_played)
        t = rows[:, 0]
        start = self.delay_ms / 1000.0  # the first setpoint played
        at = np.clip(((t - start) * CONTROL_HZ).astype(int), 0, len(played) - 1)
        commanded = np.concatenate(self.commanded)
        return RigRun(t, played[at], rows[:, 3], rows[:, 1], commanded[at], rows[:, 4] > 0.5, rows[:, 2])

    def _play(self, index: int, ratio: np.ndarray, amplitude: np.ndarray, ms: int) -> None:
        self.targets_played.append(ratio)
        self.commanded.append(amplitude)
        drive = np.repeat(amplitude, UP)
        a = self.alpha
        plate, _ = lfilter([1.0 - a], [1.0, -a], drive, zi=[a * self.plate])
        self.plate = float(plate[-1])
        t0 = (ms - self.delay_ms) / 1000.0 + self.delay_ms / 1000.0
        normal, lateral = self.finger.forces(t0, plate)
        sample = (float(plate.mean()), float(normal.mean()), float(lateral.mean()))
        if self.fault is not None:
            sample = self.fault(self.sample, sample)
        self.pending.append((sample, index))
        self.sample += 1
        if len(self.pending) == 10:
            values = np.array([s for s, _ in self.pending])
            frame = (self.sample - 10, self.pending[0][1], values)
            self.frames.append((ms + self.link_ms, frame))
            self.pending = []

    def _deliver(self, ms: int) -> None:
        while self.frames and self.frames[0][0] <= ms:
            _, (first, index, values) = self.frames.popleft()
            if self.loop is not None and (self.silent_from_ms is None or ms < self.silent_from_ms):
                self.loop.take_sensors(first, index, values[:, 0], values[:, 1], values[:, 2], self.now)
