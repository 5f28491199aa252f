"""The on-plate calibration's recording: the plan played to the plate, its SENSORS turned into measured points.

:class:`PlanSource` is the device's source: the plan's amplitude at each control sample. A step at zero
amplitude plays 5 nm instead: the host would otherwise rest an idle plate (ENABLE 0) and its measurement with
it; 5 nm changes no finger's friction measurably.

:class:`StepRecorder` takes the SENSORS frames (on the device's reader thread) and keeps their samples:
amplitude, normal force, lateral force. :meth:`StepRecorder.measurements` finds the steps in them by the
measured amplitude (steady runs while the finger slides: normal force at least ``min_force_n``, lateral force
a friction's) and turns them into points: each reduced step's mu over friction at rest (mu0: the zero runs
beside it, interpolated in time), at the step's measured amplitude and force. :attr:`StepRecorder.force_n` is
the press now, for the guide on the screen.
"""

from __future__ import annotations

import math
import threading

import numpy as np
from ultraglide.apps.calibration.plan import CalibrationPlan

KEEP_STREAMING_UM_PP = 0.005  # what a zero step plays: the stream goes on, the friction does not change
NOT_PLAYING = 0xFFFFFFFF
MIN_SAMPLES = 20  # a step with fewer sliding samples is left out (the finger lifted or stood still)
MIN_MU = 0.02  # below this the lateral force is not a sliding finger's friction
SETTLE_S = 0.03  # of each steady run, the first 30 ms are left out: the force sensors' lag, the press's
STEADY_UM_PP = 0.05  # a run is steady while its amplitude stays within this (or STEADY_SHARE) of its median
STEADY_SHARE = 0.03
ZERO_UM_PP = 0.05  # a run below this is at rest: its mu is friction at rest
REST_REACH_S = 2.0  # a reduced step takes friction at rest from zero runs at most this far away
MAX_SAMPLES = 3_600_000  # an hour of samples at 1 kHz
# a press's force is its mean to this (N): what a fingertip force sensor resolves (a lab's 6-axis cells resolve
# 1-3 mN). Finer digits are the press's wander and the sensors' noise, not the force asked: kept, they made a
# press of 0.5 N a calibration "fitted on 0.4999 N only", outside which 0.5 N itself was said to be extrapolated.
# The points, the CSV, the calibration's [fit] forces_n and the fit all hold this same value.
FORCE_RESOLUTION_N = 0.001


def _to_resolution(force_n: float) -> float:
    """A press's mean force (N) to :data:`FORCE_RESOLUTION_N`, as the float its decimal text reads back as."""
    return float(f"{round(force_n / FORCE_RESOLUTION_N) * FORCE_RESOLUTION_N:.3f}")


class PlanSource:
    """The plan as a device's source (``devices.source.BlockSource``): µm p-p at ``rate_hz``, then zeros."""

    def __init__(self, plan: CalibrationPlan, rate_hz: float):
        self.plan = plan
        self.control_rate_hz = float(rate_hz)
        self.samples = 0
        self._stopping = False
        self.end_samples = int(math.ceil(plan.duration_s * rate_hz))

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        t = (self.samples + np.arange(n)) / self.control_rate_hz
        self.samples += n
        values = self.plan.amplitude_at(t)
        if self._stopping:
            return np.zeros(n)
        inside = t < self.plan.duration_s
        return np.where(inside, np.maximum(values, KEEP_STREAMING_UM_PP), 0.0)

    @property
    def played_s(self) -> float:
        return self.samples / self.control_rate_hz

    def request_stop(self) -> None:
        self._stopping = True

    @property
    def finished(self) -> bool:
        return self._stopping or self.samples >= self.end_samples + int(0.1 * self.control_rate_hz)


class StepRecorder:
    """See the module docstring. ``stream_rate_hz``: the control rate; ``sensor_rate_hz``: the device's.

    The samples are kept as they come (the device's sample number, amplitude, forces); :meth:`points` finds the
    steps in them by the *measured* amplitude, not by the stream index: a plate that underruns (its buffer ran
    dry on a loaded host) holds its last value and says no index plays, and what it played is still measured.
    A step is a run of samples whose amplitude stays within ``STEADY_UM_PP`` (or ``STEADY_SHARE``) of its
    median, longer than ``MIN_SAMPLES`` once its first ``SETTLE_S`` is left out."""

    def __init__(self, plan: CalibrationPlan, stream_rate_hz: float, sensor_rate_hz: float = 1000.0,
                 min_force_n: float = 0.05):
        self.plan = plan
        self.steps = plan.steps()
        self.stream_rate_hz = float(stream_rate_hz)
        self.sensor_rate_hz = float(sensor_rate_hz)
        self.min_force_n = min_force_n
        self.frames = 0
        self.force_n = math.nan  # the press now, smoothed over about 50 ms
        self.sliding = False
        self._lock = threading.Lock()
        self._starts = np.array([s.start_s for s in self.steps])
        self._chunks: list[np.ndarray] = []  # rows of (sample number, amplitude, normal, lateral)
        self._kept = 0

    def take(self, frame, received_s: float | None = None) -> None:
        """A decoded SENSORS frame (``devices.protocol.Sensors``)."""
        samples = frame.samples
        a = np.asarray(samples["amplitude_um_pp"], dtype=float)
        force = np.asarray(samples["normal_force_n"], dtype=float)
        lateral = np.abs(np.asarray(samples["lateral_force_n"], dtype=float))
        n = len(a)
        if n == 0:
            return
        with self._lock:
            self.frames += 1
            finite = np.isfinite(force)
            if finite.any():
                latest = float(np.mean(force[finite][-5:]))
                self.force_n = latest if math.isnan(self.force_n) else 0.7 * self.force_n + 0.3 * latest
            mu = lateral / np.maximum(force, self.min_force_n)
            valid = np.isfinite(a) & finite & np.isfinite(lateral) & (force >= self.min_force_n) & (mu >= MIN_MU)
            self.sliding = bool(valid[-min(n, 5):].mean() > 0.5)
            if self._kept < MAX_SAMPLES:
                numbers = frame.first_sample + np.arange(n, dtype=float)
                self._chunks.append(np.column_stack((numbers, a, force, lateral)))
                self._kept += n

    def progress(self, played_s: float) -> tuple[int, float]:
        """(the force level now, the fraction of the plan played)."""
        index = max(int(np.searchsorted(self._starts, played_s, side="right")) - 1, 0)
        return self.steps[min(index, len(self.steps) - 1)].level, min(1.0, played_s / self.plan.duration_s)

    def segments(self, rest_settle_s: float = SETTLE_S) -> list[dict]:
        """The steady runs: each one's first and last sample number, mean amplitude (µm p-p), normal force (N) and
        mu, over its samples after the first ``SETTLE_S`` (a run at rest: after the first ``rest_settle_s``, where
        that is longer: a finger whose friction recovers slowly is still recovering at a rest's start)."""
        with self._lock:
            rows = np.concatenate(self._chunks) if self._chunks else np.zeros((0, 4))
        if not len(rows):
            return []
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
        number, a, force, lateral = rows.T
        mu = lateral / np.maximum(force, self.min_force_n)
        valid = (np.isfinite(a) & np.isfinite(force) & np.isfinite(lateral) & (force >= self.min_force_n)
                 & (mu >= MIN_MU))
        settle = int(round(SETTLE_S * self.sensor_rate_hz))
        rest_settle = max(settle, int(round(rest_settle_s * self.sensor_rate_hz)))
        found, start = [], 0
        for k in range(1, len(rows) + 1):
            end_here = k == len(rows) or not valid[k] or number[k] != number[k - 1] + 1 or \
                abs(a[k] - np.median(a[max(start, k - 20):k])) > max(STEADY_UM_PP, STEADY_SHARE * a[k - 1])
            if not end_here:
                continue
            skip = rest_settle if np.median(a[start:k]) < ZERO_UM_PP else settle
            steady = slice(start + skip, k)
            if valid[start] and k - start - skip >= MIN_SAMPLES and valid[steady].all():
                found.append({"first": number[start], "last": number[k - 1], "amplitude_um_pp": float(a[steady].mean()),
                              "force_n": float(force[steady].mean()), "mu": float(mu[steady].mean()),
                              "samples": k - start - skip})
            start = k
        return found

    def points(self, rest_settle_s: float = SETTLE_S) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """(amplitude µm p-p, relative friction, force N, press level) of each reduced step measured, and how many of
        the plan's reduced steps went unmeasured (the finger lifted or stood still, or no zero step beside it)."""
        segments = self.segments(rest_settle_s)
        zeros = [s for s in segments if s["amplitude_um_pp"] < ZERO_UM_PP]
        centre = np.array([(s["first"] + s["last"]) / 2 for s in zeros])
        rest = np.array([s["mu"] for s in zeros])
        amplitude, ratio, force, level = [], [], [], []
        forces = np.array(self.plan.forces_n)
        for s in segments:
            if s["amplitude_um_pp"] < ZERO_UM_PP:
                continue
            middle = (s["first"] + s["last"]) / 2
            near = np.abs(centre - middle) <= REST_REACH_S * self.sensor_rate_hz
            if not near.any():
                continue
            before, after = near & (centre < middle), near & (centre > middle)
            if before.any() and after.any():
                b, c = np.flatnonzero(before)[-1], np.flatnonzero(after)[0]
                share = (middle - centre[b]) / (centre[c] - centre[b])
                mu0 = rest[b] + share * (rest[c] - rest[b])
            else:
                mu0 = float(rest[np.flatnonzero(near)[np.argmin(np.abs(centre[near] - middle))]])
            amplitude.append(s["amplitude_um_pp"])
            ratio.append(s["mu"] / mu0)
            force.append(s["force_n"])
            level.append(int(np.argmin(np.abs(forces - s["force_n"]))))
        planned = sum(1 for step in self.steps if step.amplitude_um_pp > 0)
        return (np.array(amplitude), np.array(ratio), np.array(force), np.array(level, dtype=int),
                max(planned - len(amplitude), 0))

    def recording(self, lag, speed_mm_s: float, participant: str | None, source: str):
        """The samples kept, in order, as a ``render.physics.dynamics_fit.Recording`` (times from the first sample,
        s; gaps where samples were lost), with the force sensors' ``lag`` and the sliding speed (mm/s, NaN: unknown):
        what the friction's dynamics are fitted from and what ``calibrate --compare`` ranks models on in time."""
        from ultraglide.render.physics.dynamics_fit import Recording

        with self._lock:
            rows = np.concatenate(self._chunks) if self._chunks else np.zeros((0, 4))
        rows = rows[np.argsort(rows[:, 0], kind="stable")]
        if len(rows):
            rows = rows[np.concatenate(([True], np.diff(rows[:, 0]) > 0))]  # a sample sent twice is kept once
        number, a, force, lateral = rows.T
        t = (number - (number[0] if len(number) else 0.0)) / lag.rate_hz
        return Recording(t, a, force, lateral, lag, speed_mm_s, participant, source)

    def measurements(self, source: str, participant: str | None = None, rest_settle_s: float = SETTLE_S):
        """The points as ``render.physics.measurements.Measurements`` (ratios clipped into what a measurement file
        may hold), and the number of steps left out. The passes' points at one press and one planned amplitude
        are averaged into one (a measurement file holds each amplitude once at each force). Each point's force is
        its press's mean (the guide holds each press within ±25 %): the fit's cross-validation groups points by
        force, and a press is one force."""
        from ultraglide.render.physics.measurements import Measurements

        amplitude, ratio, force, level, missing = self.points(rest_settle_s)
        planned = self.plan.amplitudes_um_pp
        nearest = np.argmin(np.abs(amplitude[:, None] - planned[None, :]), axis=1) if len(amplitude) else level
        merged = {}
        for a, r, f, press, step in zip(amplitude, ratio, force, level, nearest, strict=True):
            merged.setdefault((int(press), int(step)), []).append((a, r, f))
        keys = sorted(merged)
        amplitude = np.array([np.mean([v[0] for v in merged[k]]) for k in keys])
        ratio = np.array([np.mean([v[1] for v in merged[k]]) for k in keys])
        force = np.array([np.mean([v[2] for v in merged[k]]) for k in keys])
        level = np.array([k[0] for k in keys], dtype=int)
        for value in np.unique(level):
            force[level == value] = _to_resolution(float(force[level == value].mean()))
        below = int(np.count_nonzero(ratio < 0.0))
        above = int(np.count_nonzero(ratio > 1.0))
        ratio = np.clip(ratio, 0.0, 1.2)
        people = None if participant is None else np.full(len(amplitude), str(participant))
        return Measurements(amplitude, ratio, force, source, people, below, above), missing
