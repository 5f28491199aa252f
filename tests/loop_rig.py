"""The friction loop closed around a simulated finger in simulated time: no threads, no pty, no firmware.

Each millisecond the host renders 12 control samples of amplitude for the target ratio (through the loop's
inverse, or the model's for open loop); the plate plays them ``buffer_s`` later (the jitter buffer), its
amplitude following through a first-order lag ``plate_tau_s`` (as the firmware's amplitude loop makes it);
the real :class:`~ultraglide.devices.sim.finger.SimulatedFinger` presses on it at 48 kHz; a sensor sample is the
mean over each millisecond (as the firmware makes it), ten to a SENSORS frame, which reaches the loop
``link_s`` later with the stream index that was playing. The finger's truth is what the errors are
measured against.

Nothing the plate does reaches the host before its SENSORS frame does, so the plate plays the jitter buffer's
blocks ``BATCH_MS`` at a time, as soon as they are rendered, each frame stamped with the millisecond it would
have left at; and the host renders the milliseconds up to the next frame's arrival at once while its loop acts
alike through them: the same samples, frames and deliveries as one block a millisecond, a tenth of the calls.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from ultraglide.devices.output.kernels import first_order_filter
from ultraglide.devices.sim.finger import FingerParams, ForceScript, SimulatedFinger
from ultraglide.devices.sim.finger_log import FingerLog
from ultraglide.devices.sim.force_sensors import ForceSensorParams
from ultraglide.render.engine.friction_loop import FrictionLoop, LoopSettings
from ultraglide.render.physics.speed_law import scaled_inverse

FS = 48000
CONTROL_HZ = 12000
UP = FS // CONTROL_HZ
BATCH_MS = 10  # the plate plays this many blocks of the jitter buffer at once


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
                 precompensate_s: float = 0.0, dynamics=None, speed_law=None):
        self.now = 0.0
        self.model = host_model
        self.loop = FrictionLoop(host_model, CONTROL_HZ, 1000.0, settings, clock=lambda: self.now) if closed else None
        if self.loop is not None:
            self.loop.panel_speed_mm_s = panel_speed_mm_s
        self.log = FingerLog(None, rate_hz=2000.0, clock_origin_s=0.0)
        self.finger = SimulatedFinger(finger_law, script or ForceScript.constant(0.5), params or FingerParams(),
                                      sensors or ForceSensorParams(), log=self.log, dynamics=dynamics,
                                      speed_law=speed_law)
        # a host model with a settled speed law: its inverse scaled at the panel's speed, as the renderer does
        law = getattr(host_model, "speed_law", None)
        self.speed_scale = law.one_scale(panel_speed_mm_s) if law is not None and panel_speed_mm_s else 1.0
        self.limit = limit_um_pp
        self.panel_force_n = panel_force_n
        self.delay_ms = int(round(buffer_s * 1000))
        self.alpha = math.exp(-1.0 / (FS * plate_tau_s)) if plate_tau_s > 0 else 0.0
        self.link_ms = int(round(link_s * 1000))
        self.plate = 0.0
        self.beta = math.exp(-1.0 / (CONTROL_HZ * precompensate_s)) if precompensate_s > 0 else 0.0
        self.modelled = 0.0  # the host's model of the plate's lag, for its pre-compensation
        self.queue: deque = deque()  # blocks in the jitter buffer (one a ms) with the ms each plays at
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
        # blocks left in the jitter buffer by a previous run play first: one a ms, the buffer kept full
        left = len(self.queue)
        for position, (index, ratio, amplitude, _) in enumerate(list(self.queue)):
            self.queue[position] = (index, ratio, amplitude, position + self.delay_ms - left)
        within = np.arange(CONTROL_HZ // 1000) / CONTROL_HZ  # a block's times from its first
        ms = 0
        while ms < ms_total:
            self.now = ms / 1000.0
            self._deliver(ms)
            count = self._steady_ms(ms, ms_total)
            t_play = np.concatenate([(at + self.delay_ms) / 1000.0 + within for at in range(ms, ms + count)])
            ratio = np.asarray(target(t_play), dtype=float)
            inverse = self.loop.inverse if self.loop is not None else self.model
            amplitude = scaled_inverse(inverse, ratio, self.panel_force_n, self.limit,
                                       self.speed_scale).amplitude_um_pp.copy()
            if self.beta:  # drive the inverse of the lag the host expects, within [0, limit]
                beta, modelled, limit, driven = self.beta, self.modelled, self.limit, []
                for y in amplitude.tolist():
                    d = min(max((y - beta * modelled) / (1.0 - beta), 0.0), limit)
                    modelled = beta * modelled + (1.0 - beta) * d
                    driven.append(d)
                self.modelled = modelled
                amplitude = np.array(driven)
            if self.loop is not None:
                self.loop.record(ratio, True)
            per_ms = len(within)
            for k in range(count):
                # the buffer gives one block a ms once full: this one plays delay_ms after it was rendered (if this
                # run lasts that long)
                self.queue.append((self.index, ratio[k * per_ms:(k + 1) * per_ms],
                                   amplitude[k * per_ms:(k + 1) * per_ms], ms + k + self.delay_ms))
                self.index += per_ms
                if len(self.queue) >= BATCH_MS and self.queue[BATCH_MS - 1][3] < ms_total:
                    self._play([self.queue.popleft() for _ in range(BATCH_MS)])
            ms += count
        due = [block for block in self.queue if block[3] < ms_total]
        for _ in due:
            self.queue.popleft()
        if due:
            self._play(due)
        self.finger.close()
        rows = self.log.rows()
        played = np.concatenate(self.targets_played)
        t = rows[:, 0]
        start = self.delay_ms / 1000.0  # the first setpoint played
        at = np.clip(((t - start) * CONTROL_HZ).astype(int), 0, len(played) - 1)
        commanded = np.concatenate(self.commanded)
        return RigRun(t, played[at], rows[:, 3], rows[:, 1], commanded[at], rows[:, 4] > 0.5, rows[:, 2])

    def _steady_ms(self, ms: int, ms_total: int) -> int:
        """How many ms from ``ms`` on the host may render at once (up to ``BATCH_MS``): none of them sees a SENSORS
        frame arrive, and the loop's inverse acts alike through them (following or not throughout, not blending), so
        each block is what rendering it in its own ms makes; 1 otherwise."""
        count = min(BATCH_MS, ms_total - ms)
        arrives = self.frames[0][0] if self.frames else math.inf  # frames on the link, and the next one made:
        to_frame = 10 - len(self.pending)  # by the block that brings the pending samples to ten
        if len(self.queue) >= to_frame:
            arrives = min(arrives, self.queue[to_frame - 1][3] + max(self.link_ms, 1))
        count = min(count, arrives - ms)  # (a block rendered from now plays delay_ms later, its frame after that)
        if count > 1 and self.loop is not None:
            inverse = self.loop.inverse
            following, command, words = inverse.following_now(ms / 1000.0)
            last = inverse.following_now((ms + count - 1) / 1000.0)
            blend_s = inverse.settings.blend_s
            blending = following and blend_s > 0 and (ms / 1000.0 - command.since_s) / blend_s < 1.0
            if (following, words) != (last[0], last[2]) or blending:
                return 1
        return max(int(count), 1)

    def _play(self, blocks: list) -> None:
        """Consecutive blocks of the jitter buffer, (stream index, ratio, amplitude, the ms each plays at), through
        the plate, the finger and the sensors; each SENSORS frame stamped with when it reaches the host."""
        count = len(blocks)
        ratios = [ratio for _, ratio, _, _ in blocks]
        amplitudes = [amplitude for _, _, amplitude, _ in blocks]
        self.targets_played.extend(ratios)
        self.commanded.extend(amplitudes)
        drive = np.repeat(np.concatenate(amplitudes), UP)
        a = self.alpha
        plate, _ = first_order_filter([1.0 - a], [1.0, -a], drive, [a * self.plate])
        self.plate = float(plate[-1])
        first_ms = blocks[0][3]
        t0 = (first_ms - self.delay_ms) / 1000.0 + self.delay_ms / 1000.0
        normal, lateral = self.finger.forces(t0, plate)
        means = [row.tolist() for row in (plate.reshape(count, -1).mean(axis=1), normal.reshape(count, -1).mean(axis=1),
                                          lateral.reshape(count, -1).mean(axis=1))]
        for k, (index, _, _, ms) in enumerate(blocks):
            sample = (means[0][k], means[1][k], means[2][k])
            if self.fault is not None:
                sample = self.fault(self.sample, sample)
            self.pending.append((sample, index))
            self.sample += 1
            if len(self.pending) == 10:
                values = np.array([s for s, _ in self.pending])
                frame = (self.sample - 10, self.pending[0][1], values)
                # made as the ms's block played, after that ms's deliveries: the host has it from the next ms on
                self.frames.append((ms + max(self.link_ms, 1), frame))
                self.pending = []

    def _deliver(self, ms: int) -> None:
        while self.frames and self.frames[0][0] <= ms:
            _, (first, index, values) = self.frames.popleft()
            if self.loop is not None and (self.silent_from_ms is None or ms < self.silent_from_ms):
                self.loop.take_sensors(first, index, values[:, 0], values[:, 1], values[:, 2], self.now)
