"""The friction loop on the host: the plate's sensors in, the renderer's inverse adapted, the loop's state out.

:class:`FrictionLoop` joins the estimator (:mod:`.friction_estimator`) and the controller
(:mod:`.friction_controller`) to a device's SENSORS and to the engine's block path:

* the **block path** renders with :attr:`FrictionLoop.inverse` as its friction model, and records what each
  control sample targeted (:meth:`FrictionLoop.record`: ratio, by the device's stream index) and the
  finger's speed as the touch panel says (:attr:`panel_speed_mm_s`);
* the **device's reader thread** hands each SENSORS frame to :meth:`FrictionLoop.take_sensors`: the estimator
  updates (sliding or not, mu0, the adapted scale), the fast correction integrates, and a new
  :class:`~.friction_controller.LoopCommand` replaces the one the block path reads;
* anyone reads :meth:`FrictionLoop.status` (a dict of plain values: the state in words, the measured and
  target ratio, the ratio error over the run, the adapted parameters).

With a host model that has friction dynamics the renderer plans (render/planning.py): it asks the inverse for the
planner's command, recorded beside the targets (:meth:`FrictionLoop.record`'s ``planned``), and what the finger is
meant to feel is that command through the dynamics. The fast correction then acts on the measured ratio against
that plan's felt ratio (through the same model of the force sensors), not against the model at the amplitude the
plate reached: the plan's 2 ms pulses ask the plate for swings it delivers late near the limit (its drive has
little headroom there), the finger then keeps more friction than planned, and only an error against the plan
sees it (issue 43: the lagging table finger's error at 0.8-0.95 N was mostly that, +0.03-0.07 on average).

The **ratio error** reported is the measured ratio minus the texture's target *for the setpoint the plate
was playing* (SENSORS' ``setpoint_index``), the target passed through the same model of the force sensors
as the estimator's prediction: it includes the plate's dynamics and the sensors' noise (5 mN at 0.2 N is
0.025 in ratio, per sample).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field

import numpy as np
from ultraglide.render.engine.friction_controller import (
    ClosedLoopInverse,
    ControllerSettings,
    FastCorrection,
    LoopCommand,
)
from ultraglide.render.engine.friction_estimator import EstimatorSettings, FrictionEstimator, SensorModel, nan_mean

RING = 1 << 15  # control samples of targets kept (2.7 s at 12 kHz): SENSORS come tens of ms after
NOT_PLAYING = 0xFFFFFFFF
ERROR_MEMORY_S = 0.5  # the error in the loop's words: rms over about this long


@dataclass(frozen=True)
class LoopSettings:
    """The estimator's and the controller's settings.

    Examples
    --------
    >>> settings = LoopSettings()
    >>> settings.controller.integral_time_s, settings.estimator.sensor_bandwidth_hz
    (0.15, 300.0)
    """

    estimator: EstimatorSettings = field(default_factory=EstimatorSettings)
    controller: ControllerSettings = field(default_factory=ControllerSettings)


class TargetRing:
    """The target ratio of each control sample sent, by stream index (NaN: the finger was up). The block path
    writes (no allocation); the reader thread reads indices a few tens of ms old.

    Examples
    --------
    Three targets sent with the finger down, one with it up; an index not yet sent reads NaN:

    >>> import numpy as np
    >>> ring = TargetRing(8)
    >>> ring.write(np.array([0.5, 0.6, 0.7]), True); ring.write(np.array([0.8]), False)
    >>> ring.read(np.array([0, 2, 3, 4])).tolist()
    [0.5, 0.7, nan, nan]
    """

    def __init__(self, capacity: int = RING):
        self.capacity = capacity
        self.ratio = np.full(capacity, np.nan)
        self.written = 0  # samples written: the next index

    def write(self, ratio: np.ndarray, down) -> None:
        """Write the target ratios of the next control samples sent, NaN where the finger is up; ``down``: one flag
        for the block or one per sample. No allocation for one flag (the block path).

        Parameters
        ----------
        ratio : numpy.ndarray
            Target ratios, one per value sent.
        down : bool or numpy.ndarray
            Whether the finger touches: one flag, or one per value.

        Examples
        --------
        Per-sample flags, and a write that wraps around the ring's end:

        >>> import numpy as np
        >>> ring = TargetRing(4)
        >>> ring.write(np.array([0.1, 0.2, 0.3]), np.array([True, False, True]))
        >>> ring.write(np.array([0.4, 0.5]), True)                     # indices 3 and 4: slots 3 and 0
        >>> ring.read(np.arange(5)).tolist()                            # index 0 overwritten: unknown
        [nan, nan, 0.3, 0.4, 0.5]
        """
        n = len(ratio)
        start = self.written % self.capacity
        first = min(n, self.capacity - start)
        self.ratio[start:start + first] = ratio[:first]
        if first < n:
            self.ratio[:n - first] = ratio[first:]
        if np.ndim(down) == 0:
            if not down:  # the finger up (or resting): no target, without allocating
                self.ratio[start:start + first] = np.nan
                self.ratio[:n - first] = np.nan
        elif not np.all(down):  # per sample for a recorded path
            up = ~np.asarray(down, dtype=bool)
            positions = (start + np.flatnonzero(up)) % self.capacity
            self.ratio[positions] = np.nan
        self.written += n

    def skip(self, n: int) -> None:
        """``n`` indices that carried no value of ours (a writer that skipped ahead): no target.

        Parameters
        ----------
        n : int
            Indices skipped.

        Examples
        --------
        >>> import numpy as np
        >>> ring = TargetRing(8)
        >>> ring.write(np.array([0.5]), True); ring.skip(2); ring.write(np.array([0.7]), True)
        >>> ring.read(np.arange(4)).tolist()
        [0.5, nan, nan, 0.7]
        """
        start = self.written % self.capacity
        first = min(n, self.capacity - start)
        self.ratio[start:start + first] = np.nan
        self.ratio[:min(n, self.capacity) - first] = np.nan
        self.written += n

    def read(self, indices: np.ndarray) -> np.ndarray:
        """Targets at these stream indices (NaN for those not written or already overwritten).

        Parameters
        ----------
        indices : numpy.ndarray
            Stream indices.

        Returns
        -------
        numpy.ndarray
            Target ratios (NaN: unknown, or the finger up).

        Examples
        --------
        >>> import numpy as np
        >>> ring = TargetRing(8)
        >>> ring.write(np.array([0.5, 0.6]), True)
        >>> ring.read(np.array([1, 0, 2])).tolist()
        [0.6, 0.5, nan]
        """
        indices = np.asarray(indices, dtype=np.int64)
        known = (indices >= max(0, self.written - self.capacity)) & (indices < self.written)
        out = np.full(len(indices), np.nan)
        out[known] = self.ratio[indices[known] % self.capacity]
        return out


class FrictionLoop:
    """See the module docstring. ``model``: the host's friction model; ``stream_rate_hz``: the device's setpoints a
    second (a ``serial:PATH?rate=N`` stream's N, not the control rate);
    ``sensor_rate_hz``: the device's sensor samples a second.

    Examples
    --------
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> loop = FrictionLoop(StretchedExponentialModel(), stream_rate_hz=12000.0, sensor_rate_hz=1000.0)
    >>> loop.words(), loop.inverse.name
    ('open loop: waiting for the sensors', 'stretched')
    """

    def __init__(self, model, stream_rate_hz: float = 12000.0, sensor_rate_hz: float = 1000.0,
                 settings: LoopSettings | None = None, capacity: int = 4096, clock=time.perf_counter):
        self.settings = settings or LoopSettings()
        self.stream_rate_hz = float(stream_rate_hz)
        self.sensor_rate_hz = float(sensor_rate_hz)
        self.inverse = ClosedLoopInverse(model, self.settings.controller, capacity, clock)
        self.estimator = FrictionEstimator(model, self.settings.estimator, sensor_rate_hz)
        self.correction = FastCorrection(self.settings.controller)
        self.targets = TargetRing()
        self.plans = TargetRing()  # the static ratio the inverse was asked for (the planner's command), by index
        self._decimated = np.zeros(capacity)  # record_control's per-value targets, made once
        self._decimated_down = np.zeros(capacity, dtype=bool)
        self._plan_decimated = np.zeros(capacity)  # the same for the planner's commands
        self.panel_speed_mm_s: float | None = None
        est = self.settings.estimator
        self._target_sensors = SensorModel(1, self.sensor_rate_hz, est.sensor_bandwidth_hz, est.sensor_delay_s)
        self._plan_sensors = SensorModel(1, self.sensor_rate_hz, est.sensor_bandwidth_hz, est.sensor_delay_s)
        self._plan_felt = 1.0  # the plan's felt ratio through the model's dynamics at the newest sample
        self._plan_fresh = True  # the plan's sensor model starts settled on its first value (a start, a gap)
        self._next_sample: int | None = None
        self._lock = threading.Lock()  # status against the reader thread: held for a copy of a few numbers
        self._error_sum = 0.0
        self._error_count = 0
        self._plan_error_sum = 0.0  # against the felt ratio the plan means (a model with friction dynamics)
        self._plan_error_count = 0
        self._recent_square = math.nan  # the error², averaged over about ERROR_MEMORY_S
        self._memory = math.exp(-1.0 / (ERROR_MEMORY_S * self.sensor_rate_hz))
        self.measured_ratio = math.nan  # the newest batch's, for a chart
        self.target_ratio = math.nan
        self.sensor_frames = 0
        self._following_since: float | None = None

    def __repr__(self) -> str:
        return f"FrictionLoop({self.estimator!r}, correction {self.correction.value:+.3f}, {self.words()!r})"

    def set_sensor_rate(self, sensor_rate_hz: float) -> None:
        """The device's sensor samples a second (from its handshake); the estimator starts over if it changed.

        Parameters
        ----------
        sensor_rate_hz : float
            Samples a second.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> loop = FrictionLoop(StretchedExponentialModel(), sensor_rate_hz=1000.0)
        >>> loop.set_sensor_rate(2000.0)
        >>> loop.sensor_rate_hz, loop.estimator.sensor_rate_hz          # the estimator made anew at that rate
        (2000.0, 2000.0)
        """
        if sensor_rate_hz > 0 and sensor_rate_hz != self.sensor_rate_hz:
            self.sensor_rate_hz = float(sensor_rate_hz)
            self._restart(self.estimator.model)

    def set_model(self, model) -> None:
        """Another host model: its inverse from the next block, its adaptation from scratch.

        Parameters
        ----------
        model : FrictionModel

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> loop = FrictionLoop(model, stream_rate_hz=12000.0, sensor_rate_hz=1000.0, clock=lambda: 1.0)
        >>> loop.panel_speed_mm_s = 100.0
        >>> amplitude, force = np.tile(np.linspace(0.0, 5.0, 100), 4), np.full(400, 0.5)   # 0.4 s of sensor samples
        >>> lateral = model.relative_friction(amplitude, 0.5) * force                     # the host model's friction
        >>> loop.take_sensors(0, NOT_PLAYING, amplitude, force, lateral, received_s=1.0)
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> loop.set_model(ExponentialModel())                            # its adaptation from scratch: open loop
        >>> loop.inverse.name, loop.words()
        ('exponential', 'open loop: waiting for the sensors')
        """
        self._restart(model)
        self.inverse.base = model
        self.inverse.name = model.name

    def _restart(self, model) -> None:
        est = self.settings.estimator
        self.estimator = FrictionEstimator(model, est, self.sensor_rate_hz)
        self.correction.reset()
        self._target_sensors = SensorModel(1, self.sensor_rate_hz, est.sensor_bandwidth_hz, est.sensor_delay_s)
        self._plan_sensors = SensorModel(1, self.sensor_rate_hz, est.sensor_bandwidth_hz, est.sensor_delay_s)
        self._plan_felt = 1.0
        self._plan_fresh = True
        self._next_sample = None
        self._memory = math.exp(-1.0 / (ERROR_MEMORY_S * self.sensor_rate_hz))
        self.inverse.command = LoopCommand()

    # ---- the block path ----
    def record(self, ratio: np.ndarray, down, planned: np.ndarray | None = None) -> None:
        """The target ratios of the values just handed to the device, in stream order (one per device value), and
        the static ratios the inverse was asked for (``planned``: the planner's command; None: the targets).

        Parameters
        ----------
        ratio : numpy.ndarray
            Target ratios, one per device value.
        down : bool or numpy.ndarray
        planned : numpy.ndarray, optional
            The ratios the model's inverse was asked for (a renderer that plans against friction dynamics).

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> loop = FrictionLoop(StretchedExponentialModel())
        >>> loop.record(np.array([0.5, 0.6]), True)
        >>> loop.targets.read(np.array([0, 1])).tolist()
        [0.5, 0.6]
        """
        self.targets.write(ratio, down)
        self.plans.write(ratio if planned is None else planned, down)

    def record_control(self, ratio: np.ndarray, down, decimation: int, planned: np.ndarray | None = None) -> None:
        """The target ratios of a block of control samples the device streams ``decimation`` times slower (a
        ``serial:PATH?rate=N`` below the control rate): each device value is the mean of ``decimation`` control
        samples, so its target is their targets' mean, and the finger counts as down for it only if down for all
        of them. Block path: no allocation for blocks up to the loop's capacity.

        Parameters
        ----------
        ratio : numpy.ndarray
            Target ratios, one per control sample.
        down : bool or numpy.ndarray
        decimation : int
            Control samples per device value.
        planned : numpy.ndarray, optional
            The ratios the model's inverse was asked for, one per control sample (None: the targets).

        Examples
        --------
        Two control samples per device value: each value's target is their mean:

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> loop = FrictionLoop(StretchedExponentialModel())
        >>> loop.record_control(np.array([0.4, 0.6, 0.8, 1.0]), True, 2)
        >>> loop.targets.read(np.array([0, 1])).round(9).tolist()
        [0.5, 0.9]
        """
        means, self._decimated = _means(ratio, decimation, self._decimated)
        downs = down
        if decimation > 1 and np.ndim(down) != 0:  # down for a device value only if down for all its samples
            n = len(means)
            if n > len(self._decimated_down):
                self._decimated_down = np.zeros(n, dtype=bool)
            downs = self._decimated_down[:n]
            np.logical_and.reduce(np.asarray(down)[:n * decimation].reshape(n, decimation), axis=1, out=downs)
        self.targets.write(means, downs)
        if planned is not None and planned is not ratio:
            means, self._plan_decimated = _means(planned, decimation, self._plan_decimated)
        self.plans.write(means, downs)

    def skip(self, n: int) -> None:
        """``n`` stream indices the device's writer skipped (no target for them).

        Parameters
        ----------
        n : int

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> loop = FrictionLoop(StretchedExponentialModel())
        >>> loop.skip(3); loop.record(np.array([0.5]), True)
        >>> loop.targets.read(np.array([2, 3])).tolist()
        [nan, 0.5]
        """
        self.targets.skip(n)
        self.plans.skip(n)

    # ---- the reader thread ----
    def take_sensors_frame(self, frame, received_s: float | None = None) -> None:
        """A decoded SENSORS frame (``devices.protocol.Sensors``), as a device's reader thread hands it over.

        Parameters
        ----------
        frame : Sensors
            A decoded SENSORS frame.
        received_s : float, optional
            perf_counter s.

        Examples
        --------
        A frame packed and parsed as the wire carries it (two samples: too few to say the finger slides):

        >>> from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> loop = FrictionLoop(StretchedExponentialModel(), clock=lambda: 1.0)
        >>> loop.take_sensors_frame(parse_sensors(sensors_payload(40, 480, sensor_samples([3.0, 3.2], [0.5, 0.6],
        ...                                                                               [0.2, 0.25]))), 1.0)
        >>> loop.sensor_frames, loop.words()
        (1, 'open loop: waiting for the finger to slide')
        """
        samples = frame.samples
        self.take_sensors(frame.first_sample, frame.setpoint_index, samples["amplitude_um_pp"],
                          samples["normal_force_n"], samples["lateral_force_n"], received_s)

    def take_sensors(self, first_sample: int, setpoint_index: int, amplitude_um_pp, normal_force_n, lateral_force_n,
                     received_s: float | None = None) -> None:
        """One SENSORS frame: consecutive samples from the device's sample ``first_sample``; ``setpoint_index``
        the stream index playing at the first (NOT_PLAYING: none); ``received_s`` perf_counter time.

        Parameters
        ----------
        first_sample : int
        setpoint_index : int
            The stream index playing at the first sample (``NOT_PLAYING``: none).
        amplitude_um_pp, normal_force_n, lateral_force_n : array_like
            Per sample: µm p-p, N, N.
        received_s : float, optional
            perf_counter s.

        Examples
        --------
        Sensors reading the host model's own friction while the finger slides at 100 mm/s: the loop follows:

        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> loop = FrictionLoop(model, stream_rate_hz=12000.0, sensor_rate_hz=1000.0, clock=lambda: 1.0)
        >>> loop.panel_speed_mm_s = 100.0
        >>> amplitude, force = np.tile(np.linspace(0.0, 5.0, 100), 4), np.full(400, 0.5)   # 0.4 s of sensor samples
        >>> lateral = model.relative_friction(amplitude, 0.5) * force                     # the host model's friction
        >>> loop.take_sensors(0, NOT_PLAYING, amplitude, force, lateral, received_s=1.0)
        >>> loop.words(), loop.inverse.command.following
        ('closed loop: following', True)
        """
        received_s = self.inverse.clock() if received_s is None else received_s
        n = len(amplitude_um_pp)
        if n == 0:
            return
        if self._next_sample is not None and first_sample != self._next_sample:
            self._target_sensors.reset(None)
            self._plan_fresh = True
        self._next_sample = first_sample + n
        batch = self.estimator.update(first_sample, amplitude_um_pp, normal_force_n, lateral_force_n,
                                      self.panel_speed_mm_s, self.correction.value)
        estimate = batch.estimate
        per_sample = self.stream_rate_hz / self.sensor_rate_hz
        meant = self._plan_meant(setpoint_index, n, per_sample)
        if estimate.sliding:
            # with friction dynamics, the plan's felt ratio is what the finger is meant to feel: the error against it
            # takes in what the plate's delivery of the plan's pulses costs (see the module docstring)
            intended = batch.intended_ratio if meant is None else np.where(np.isfinite(batch.intended_ratio), meant,
                                                                            np.nan)
            self.correction.update(batch.measured_ratio - intended, batch.sensitivity, n / self.sensor_rate_hz)
        targets = np.full(n, np.nan)
        if setpoint_index != NOT_PLAYING:
            indices = setpoint_index + np.round((np.arange(n) + 0.5) * per_sample).astype(np.int64)
            targets = self.targets.read(indices)
        seen = self._target_sensors(np.nan_to_num(targets, nan=1.0)[None, :])[0]
        seen[~np.isfinite(targets)] = np.nan
        errors = batch.measured_ratio - seen
        with self._lock:
            self.sensor_frames += 1
            valid = errors[np.isfinite(errors)]
            if len(valid):
                self._error_sum += float(np.dot(valid, valid))
                self._error_count += len(valid)
                for square in (valid * valid).tolist():
                    self._recent_square = square if math.isnan(self._recent_square) else \
                        self._memory * self._recent_square + (1.0 - self._memory) * square
            if meant is not None:
                from_plan = batch.measured_ratio - meant
                from_plan = from_plan[np.isfinite(from_plan)]
                self._plan_error_sum += float(np.dot(from_plan, from_plan))
                self._plan_error_count += len(from_plan)
            self.measured_ratio = estimate.measured_ratio
            self.target_ratio = nan_mean(seen) if np.isfinite(seen).any() else math.nan
        self._command(estimate, received_s)

    def _plan_meant(self, setpoint_index: int, n: int, per_sample: float) -> np.ndarray | None:
        """With a host model that has friction dynamics: the felt ratio the plan means for each of ``n`` sensor
        samples (the mean of the static ratios asked over each sample's values, through the model's dynamics at the
        finger's speed, then the host's model of the force sensors; NaN where no plan played); None for a static
        model."""
        dynamics = getattr(self.estimator.model, "dynamics", None)
        if dynamics is None:
            return None
        asked = np.full(n, np.nan)
        if setpoint_index != NOT_PLAYING:
            values = max(1, int(round(per_sample)))
            indices = (setpoint_index + np.round(np.arange(n) * per_sample).astype(np.int64)[:, None]
                       + np.arange(values)[None, :])
            read = self.plans.read(indices.reshape(-1)).reshape(n, values)
            known = np.isfinite(read).all(axis=1)
            asked[known] = read[known].mean(axis=1)
        played = np.isfinite(asked)
        speed = self.panel_speed_mm_s
        speed = speed if speed is not None and speed > 0 else dynamics.reference_speed_mm_s
        felt = dynamics.respond(np.where(played, asked, 1.0), self.sensor_rate_hz, speed, felt=self._plan_felt)
        self._plan_felt = float(felt[-1])
        timing = self.estimator.sensor_timing  # as identified: the plan seen as the estimator sees its prediction
        if timing != (self._plan_sensors.bandwidth_hz, self._plan_sensors.delay_s):
            self._plan_sensors.set(*timing)
        if self._plan_fresh:
            self._plan_sensors.reset(felt[:1])
            self._plan_fresh = False
        seen = self._plan_sensors(felt[None, :])[0]
        seen[~played] = np.nan
        return seen

    def _command(self, estimate, received_s: float) -> None:
        following = estimate.sliding
        if following and self._following_since is None:
            self._following_since = received_s
        elif not following:
            self._following_since = None
        scale = estimate.scale * (1.0 + self.correction.value)
        words = self._words(estimate)
        self.inverse.command = LoopCommand(following, scale, estimate.force_n if following else 0.5,
                                           self._following_since or 0.0, received_s, words)

    def _words(self, estimate) -> str:
        if estimate.sliding:
            error = math.sqrt(self._recent_square) if not math.isnan(self._recent_square) else math.nan
            return "closed loop: following" + ("" if math.isnan(error) else f", error {error:.2f}")
        state = estimate.state
        if state == "lifted":
            return "open loop: finger lifted"
        if state == "resting":
            return "open loop: finger resting"
        if state == "fault":
            return f"open loop: sensor fault ({estimate.reason})"
        return "open loop: waiting for the finger to slide"

    # ---- anyone ----
    def words(self) -> str:
        """The loop's state now, in words ("closed loop: following, error 0.03"; "open loop: finger resting").

        Returns
        -------
        str

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> FrictionLoop(StretchedExponentialModel()).words()
        'open loop: waiting for the sensors'
        """
        return self.inverse.following_now()[2]

    def status(self) -> dict:
        """Plain values for JSON and the status line.

        Returns
        -------
        dict
            Strict JSON values (None where unknown).

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> model = StretchedExponentialModel()
        >>> loop = FrictionLoop(model, stream_rate_hz=12000.0, sensor_rate_hz=1000.0, clock=lambda: 1.0)
        >>> loop.panel_speed_mm_s = 100.0
        >>> amplitude, force = np.tile(np.linspace(0.0, 5.0, 100), 4), np.full(400, 0.5)   # 0.4 s of sensor samples
        >>> lateral = model.relative_friction(amplitude, 0.5) * force                     # the host model's friction
        >>> loop.take_sensors(0, NOT_PLAYING, amplitude, force, lateral, received_s=1.0)
        >>> status = loop.status()
        >>> status["loop_state"], status["sensor_frames"], status["measured_force_n"], status["friction_error_rms"]
        ('following', 1, 0.5, None)
        """
        estimate = self.estimator.estimate
        following, command, words = self.inverse.following_now()
        with self._lock:
            rms = math.sqrt(self._error_sum / self._error_count) if self._error_count else None
            plan_rms = math.sqrt(self._plan_error_sum / self._plan_error_count) if self._plan_error_count else None
            recent = None if math.isnan(self._recent_square) else math.sqrt(self._recent_square)
            measured, target = self.measured_ratio, self.target_ratio
            frames = self.sensor_frames
        return {"loop": words, "loop_state": "following" if following else estimate.state,
                "friction_error_rms": _plain(rms), "friction_error_plan_rms": _plain(plan_rms),
                "friction_error_recent": _plain(recent),
                "measured_ratio": _plain(measured), "target_ratio_measured": _plain(target),
                "mu0": round(estimate.mu0, 4), "adapted_scale": round(estimate.scale, 4),
                "correction": round(self.correction.value, 4), "measured_force_n": _plain(estimate.force_n),
                "sensor_frames": frames, "loop_fallbacks": self.inverse.fallbacks,
                "loop_fallback_reasons": dict(self.inverse.fallback_reasons),
                "closed_loop_samples": self.inverse.closed_samples, "open_loop_samples": self.inverse.open_samples}


def _plain(value: float | None) -> float | None:
    """A JSON-safe number (None for NaN or missing), rounded."""
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), 5)


def _means(values: np.ndarray, decimation: int, buffer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The means of each ``decimation`` values (``values`` itself for 1), in ``buffer`` (grown if too short: made
    again only for a block longer than any before); the means and the buffer."""
    if decimation == 1:
        return values, buffer
    n = len(values) // decimation
    if n > len(buffer):
        buffer = np.zeros(n)
    means = buffer[:n]
    np.mean(values[:n * decimation].reshape(n, decimation), axis=1, out=means)
    return means, buffer
