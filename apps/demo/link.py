"""The demo's one contact with the renderer and the device: the real-time engine.

:class:`DemoLink` wraps :class:`ultraglide.render.engine.Engine` (the renderer and the device in their
own process, touches through shared memory) with what the demo's status line and chart need. The
engine's process is started after the first frame is on screen (:class:`LinkStarter`) and waited for on a
thread: it loads numba and the kernels while the window already responds. Touches made
before it is ready are not queued (a finger's old positions would be felt late): the demo draws them
and counts them as not felt, and says so on its status line.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from dataclasses import dataclass, field

import numpy as np
from ultraglide.devices.serial.run_report import RunReport
from ultraglide.render.physics.default_model import DEFAULT_MODEL

START_TIMEOUT_S = 120.0  # spawning the engine and compiling its kernels on a loaded machine


@dataclass(frozen=True)
class LinkConfig:
    """What the link starts with: a texture (a Texture or a name/file), a model spec, a profile spec, a device URL."""

    texture: object
    model: str = DEFAULT_MODEL
    profile: str = "sim-plate"
    device: str = "sim"
    closed_loop: bool = False
    finger: object = None  # a FingerConfig for the simulated plate's finger (render.engine.finger_setup)


@dataclass(frozen=True)
class LinkStatus:
    """A snapshot for the status line and the chart. Amplitudes µm p-p, times perf_counter s."""

    device: str
    state: str  # the engine's: starting, running, paused, stopping, stopped, failed; or disconnected
    model: str
    texture: str
    force_n: float
    paused: bool
    blocks: int
    late_blocks: int
    underruns: int  # the sound card's, the plate driver's buffer underruns, or a paced sink's late blocks
    block_p50_us: float  # over the engine's recent blocks (the last 4096)
    block_p99_us: float
    limited_pct: float  # of the control samples of the last second
    limited_samples: int  # since the texture was last changed
    faults: tuple[str, ...]  # each fault the device reported over this run, with its count; errors
    limit_um_pp: float
    full_scale_um_pp: float
    plate_measured: bool  # the chart's plate column is the device's measurement (else the renderer's model)
    words: str  # the engine's own line
    # rows of (t_s, target ratio, commanded µm p-p, plate µm p-p, measured ratio: NaN without the closed loop)
    chart: np.ndarray = field(repr=False)
    engine: object = field(repr=False, default=None)  # the engine's EngineStatus
    verdict: str = ""  # a plate driver's run so far, when not clean: "the plate was lost (exit status 4)"
    loop: str = ""  # the friction loop's state in words ("" without it)


class DemoLink:
    """The engine behind the demo's verbs. Call from the UI thread."""

    def __init__(self, engine, config: LinkConfig, profile):
        self.engine, self.config, self.profile = engine, config, profile
        self.model_name = config.model
        self.paused = True
        self._clipped_at_texture = 0
        self._texture_since_s = 0.0  # the engine's clock at the last change of texture
        self._stopped = False

    @staticmethod
    def launch(config: LinkConfig):
        """The engine's process started, loading its inputs (:meth:`Engine.launch`): give it to :meth:`start`."""
        from ultraglide.render.engine import Engine, EngineConfig

        return Engine.launch(EngineConfig(texture=config.texture, model=config.model, profile=config.profile,
                                          device=config.device, start_paused=True, closed_loop=config.closed_loop,
                                          finger=config.finger))

    @classmethod
    def start(cls, config: LinkConfig, launched=None) -> DemoLink:
        """Start the engine, or take the one ``launched`` for ``config`` (bad specs and devices raise here, one
        line), and wait until it renders."""
        from ultraglide.devices.rig import load_plate

        launched = launched if launched is not None else cls.launch(config)
        try:
            profile = load_plate(config.profile)
        except BaseException:
            launched.abandon()
            raise
        engine = launched.wait(START_TIMEOUT_S)
        try:
            engine.wait_ready(START_TIMEOUT_S)  # until the device has taken its first block
        except BaseException:
            engine.stop()
            raise
        return cls(engine, config, profile)

    # ---- the engine's verbs ----------------------------------------------------------------------
    def touch(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None = None, down: bool = True) -> bool:
        """A touch report (perf_counter s, mm on the texture, N or None for the default); down=False lifts.
        Never waits; False if the engine's ring was full and the report dropped."""
        return self.engine.touch(t_s, x_mm, y_mm, force_n, down)

    @property
    def loss(self):
        """None while the engine is well; else how it was lost (its process died or froze; the device was made safe
        by the engine's supervisor): ``loss.lines()``. The verbs then do nothing; the app offers a restart."""
        return self.engine.loss

    @contextlib.contextmanager
    def _unless_lost(self):
        from ultraglide.render.engine import EngineLost

        with contextlib.suppress(EngineLost):  # the app sees the loss on its next step (self.loss)
            yield

    def set_texture(self, texture) -> None:
        """Render another texture (a Texture); the limited count starts again from zero."""
        with self._unless_lost():
            self.engine.set_texture(texture)
            after = self.engine.status(0.0)
            self._clipped_at_texture = after.clipped_samples
            self._texture_since_s = after.history.time_s[-1] if len(after.history.time_s) else 0.0

    def set_model(self, spec: str) -> None:
        with self._unless_lost():
            self.engine.set_model(spec)
        self.model_name = spec

    def set_force(self, force_n: float) -> None:
        """The force assumed when the touch panel does not measure it, N."""
        with self._unless_lost():
            self.engine.set_force(force_n)

    def pause(self, flag: bool) -> None:
        """Ramp to rest (or back); a pipe round trip, so only sent when it changes."""
        if bool(flag) != self.paused:
            with self._unless_lost():
                self.engine.pause(bool(flag))
                self.paused = bool(flag)

    def status(self, chart_span_s: float = 3.0) -> LinkStatus:
        """What the engine and its device are doing now, and the last ``chart_span_s`` of the chart."""
        s = self.engine.status(max(chart_span_s, 1.0) + 0.1)
        history = s.history
        chart = np.column_stack((history.time_s, history.target_ratio, history.commanded_um_pp, history.plate_um_pp,
                                 history.measured_ratio))
        if len(chart):
            chart = chart[chart[:, 0] > chart[-1, 0] - chart_span_s]
        state = s.state
        if s.device_status.get("connected", True) is False:
            state = "disconnected"
        elif s.device_status.get("output") == "cut by the device":
            state = "cut off by the plate"
        report = RunReport.from_dict(s.device_status.get("report"))
        return LinkStatus(
            device=s.device, state=state, model=s.model or self.model_name, texture=s.texture,
            force_n=s.force_n, paused=s.state == "paused", blocks=s.blocks, late_blocks=s.late_blocks,
            underruns=s.underruns, block_p50_us=_or_zero(s.block_p50_us), block_p99_us=_or_zero(s.block_p99_us),
            limited_pct=self._limited_percent(s), limited_samples=s.clipped_samples - self._clipped_at_texture,
            faults=tuple(_fault_words(s)),
            limit_um_pp=float(s.device_status.get("limit_um_pp") or self.profile.max_amplitude_um_pp),
            full_scale_um_pp=self.profile.full_scale_um_pp,
            plate_measured="measured_um_pp" in s.device_status, words=s.words(priority=False), chart=chart, engine=s,
            verdict=report.verdict if report.exit_status else "", loop=s.loop)

    def _limited_percent(self, s) -> float:
        """Of the control samples of the last second on this texture, the share the plate's limit held, %."""
        history = s.history
        if not len(history.time_s):
            return 0.0
        keep = history.time_s > max(history.time_s[-1] - 1.0, self._texture_since_s)
        times, limited = history.time_s[keep], history.limited_samples[keep]
        if len(times) < 2:
            return 0.0
        samples = (times[-1] - times[0]) * self.engine.config.control_rate_hz
        return float(min(100.0, 100.0 * limited[1:].sum() / max(samples, 1.0)))

    def stop(self):
        """Ramp the plate to rest, rest the hardware, end the engine; returns its last EngineStatus."""
        if not self._stopped:
            self._stopped = True
            return self.engine.stop()
        return self.engine.final_status


def _or_zero(value: float | None) -> float:
    return 0.0 if value is None or not math.isfinite(value) else float(value)


def _fault_words(s) -> list[str]:
    """Each fault the device counted over the run with its count (plate drivers), else the engine's names."""
    counts = s.device_status.get("fault_counts") or s.device_status.get("faults")
    if isinstance(counts, dict):
        return ([f"{name} ×{count}" for name, count in counts.items() if count]
                + list(s.device_status.get("errors") or []))
    return list(s.faults)


class LinkStarter:
    """Starts a :class:`DemoLink` so the window stays responsive while the engine starts: the engine's process is
    started here, on the app's one thread (so it is forked, with what the app has imported, not spawned), and
    waited for on a thread of its own."""

    def __init__(self, config: LinkConfig):
        self.link: DemoLink | None = None
        self.error: BaseException | None = None
        self.ready = threading.Event()
        self.started_s = time.perf_counter()
        try:
            launched = DemoLink.launch(config)
        except Exception as error:  # noqa: BLE001 - raised on the UI thread by wait(), as a failed start is
            self.error = error
            self.ready.set()
            return
        self._thread = threading.Thread(target=self._run, args=(config, launched), name="demo-link-start",
                                        daemon=True)
        self._thread.start()

    def _run(self, config: LinkConfig, launched) -> None:
        try:
            self.link = DemoLink.start(config, launched)
        except BaseException as error:  # noqa: BLE001 - handed to the UI thread, which raises it
            self.error = error
        finally:
            self.ready.set()

    def wait(self, timeout_s: float | None = None) -> DemoLink | None:
        """The link once started (None on timeout); re-raises on this thread what starting raised."""
        self.ready.wait(timeout_s)
        if self.error is not None:
            raise self.error
        return self.link
