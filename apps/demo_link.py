"""The demo's one contact with the renderer and the device.

:class:`DemoLink` has the verbs of ``ultraglide.render.engine.Engine`` (``start(config)``, ``touch``,
``set_texture``, ``set_model``, ``set_force``, ``pause``, ``status``, ``stop``), implemented here in
process with a :class:`~ultraglide.render.renderer.Renderer` pulled by a device, so that moving the
demo onto the engine is a change of this module alone. Everything heavy (the renderer, numba's
kernels) is imported in :meth:`DemoLink.start`, after the demo's first frame is on screen.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np

CHART_BLOCKS = 4096  # blocks of history kept for the chart (a 2 ms batch each: about 8 s)
TIMES_KEPT = 500  # block render times used for p50/p99


@dataclass(frozen=True)
class LinkConfig:
    """What the link starts with: a texture (a Texture), a model spec, a profile spec, a device URL."""

    texture: object
    model: str = "exponential"
    profile: str = "sim-plate"
    device: str = "sim"


@dataclass(frozen=True)
class LinkStatus:
    """A snapshot for the status line and the chart. Amplitudes µm p-p, times perf_counter s."""

    device: str
    state: str  # "running", "disconnected", "stopped"
    model: str
    texture: str
    force_n: float
    paused: bool
    blocks: int
    late_blocks: int
    underruns: int  # the sound card's, the plate driver's buffer underruns, or a paced sink's late blocks
    block_p50_us: float
    block_p99_us: float
    limited_pct: float  # of the control samples of the last second with the finger down
    limited_samples: int  # since the texture was last changed
    faults: tuple[str, ...]  # each fault the device reported over this run, with its count; errors
    limit_um_pp: float
    full_scale_um_pp: float
    measured_um_pp: float | None
    chart: np.ndarray = field(repr=False)  # rows of (t_s, target ratio, commanded µm p-p, plate µm p-p)


class _History:
    """Per-block figures in preallocated rings, written by the device's thread, read by the UI's."""

    def __init__(self, size: int = CHART_BLOCKS):
        self.rows = np.zeros((size, 4))  # t_s, ratio, commanded, plate
        self.samples = np.zeros((size, 2))  # finger-down samples, limited samples
        self.count = 0
        self.since = 0  # first block counted after the last reset

    def add(self, t_s, ratio, commanded, plate, down_samples, limited) -> None:
        i = self.count % len(self.rows)
        self.rows[i, 0], self.rows[i, 1], self.rows[i, 2], self.rows[i, 3] = t_s, ratio, commanded, plate
        self.samples[i, 0], self.samples[i, 1] = down_samples, limited
        self.count += 1  # published last: a reader never sees a half-written row as new

    def recent(self, after_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        count = self.count
        kept = min(count, len(self.rows) - 1, count - self.since)  # not the slot being written next
        order = (np.arange(count - kept, count)) % len(self.rows)
        rows, samples = self.rows[order], self.samples[order]
        if after_s is not None:
            keep = rows[:, 0] > after_s
            rows, samples = rows[keep], samples[keep]
        return rows, samples


class DemoLink:
    """The renderer and its device behind the engine's verbs. Call from the UI thread."""

    def __init__(self, renderer, device, config: LinkConfig, profile):
        self.renderer, self.device, self.config, self.profile = renderer, device, config, profile
        self.model_name = config.model
        self.history = _History()
        self.limited_total = 0
        self._clipped_before = 0
        self._stopped = False
        renderer.observers.append(self._observe)

    @classmethod
    def start(cls, config: LinkConfig) -> DemoLink:
        """Load the model and profile (bad specs raise here, before a device opens), open the device,
        build the renderer (which compiles or loads its kernels) and start the device pulling."""
        from ultraglide.apps.sources import source_for
        from ultraglide.devices.profiles import load_profile
        from ultraglide.devices.urls import open_device
        from ultraglide.render.calibration import load_model
        from ultraglide.render.renderer import Renderer, RenderSettings

        profile = load_profile(config.profile)
        model = load_model(config.model)
        device = open_device(config.device, profile)
        try:
            rate = device.rate_hz if device.signal == "audio" else 96000
            renderer = Renderer(config.texture, model, profile, RenderSettings(audio_rate_hz=rate))
            renderer.pause(True)  # at rest until a finger is on a texture
            link = cls(renderer, device, config, profile)
            device.start(source_for(device, renderer))
        except BaseException:
            device.stop()
            raise
        return link

    # ---- the device's thread ---------------------------------------------------------------------
    def _observe(self, block) -> None:
        """Runs on the device's thread for every block: a few scalar copies, no allocation."""
        clipped = self.renderer.counters.clipped_samples
        limited = clipped - self._clipped_before
        self._clipped_before = clipped
        down = len(block.ratio) if (block.down is True or np.all(block.down)) else 0
        self.history.add(block.time_s[-1], block.ratio[-1], block.amplitude_um_pp[-1], block.plate_um_pp[-1],
                         down, limited)

    # ---- the engine's verbs ----------------------------------------------------------------------
    def touch(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None = None, down: bool = True) -> None:
        """A touch report (perf_counter s, mm on the texture, N or None for the default); down=False lifts."""
        if not down:
            self.renderer.push(t_s, 0.0, 0.0, down=False)
            return
        self.renderer.push(t_s, x_mm, y_mm, force_n)

    def set_texture(self, texture) -> None:
        """Render another texture; the limited counters start again from zero."""
        self.renderer.set_texture(texture)
        self.history.since = self.history.count
        self.limited_total = self.renderer.counters.clipped_samples

    def set_model(self, spec: str) -> None:
        from ultraglide.render.calibration import load_model

        self.renderer.set_model(load_model(spec))
        self.model_name = spec

    def set_force(self, force_n: float) -> None:
        """The force assumed when the touch panel does not measure it, N."""
        self.renderer.set_default_force(force_n)

    def pause(self, flag: bool) -> None:
        self.renderer.pause(flag)

    def status(self, chart_span_s: float = 3.0, all_blocks: bool = False) -> LinkStatus:
        """What the device and the renderer are doing now, and the last ``chart_span_s`` of the chart.
        Block times are over the last 500 blocks, or every block the renderer keeps with ``all_blocks``."""
        renderer, counters = self.renderer, self.renderer.counters
        device = self.device.status()
        telemetry = getattr(self.device, "telemetry", None)
        rows, samples = self.history.recent()
        latest = rows[-1, 0] if len(rows) else 0.0
        last_second = rows[:, 0] > latest - 1.0
        down = samples[last_second, 0].sum()
        limited_pct = 100.0 * samples[last_second, 1].sum() / down if down else 0.0
        times = counters.render_times_s[:] if all_blocks else counters.render_times_s[-TIMES_KEPT:]
        p50, p99 = (np.percentile(times, [50, 99]) * 1e6) if times else (0.0, 0.0)
        counts = device.get("faults") if isinstance(device.get("faults"), dict) else {}  # plate drivers, by name
        underruns = device.get("underruns", counts.get("underrun", device.get("late_blocks", 0)))
        faults = [f"{name} ×{count}" for name, count in counts.items() if count] + list(device.get("errors", []))
        if self._stopped:
            state = "stopped"
        elif device.get("connected", True) is False:
            state = "disconnected"
        else:
            state = "running"
        return LinkStatus(
            device=device.get("device", self.config.device), state=state, model=self.model_name,
            texture=renderer.texture.name, force_n=renderer.default_force_n, paused=renderer.paused,
            blocks=self.history.count, late_blocks=counters.late_blocks, underruns=int(underruns),
            block_p50_us=float(p50), block_p99_us=float(p99), limited_pct=float(limited_pct),
            limited_samples=counters.clipped_samples - self.limited_total, faults=tuple(faults),
            limit_um_pp=self.profile.max_amplitude_um_pp, full_scale_um_pp=self.profile.full_scale_um_pp,
            measured_um_pp=None if telemetry is None else telemetry.measured_um_pp,
            chart=rows[rows[:, 0] > latest - chart_span_s])

    def stop(self) -> None:
        """Ramp the plate to rest and release the device; safe to call more than once."""
        if not self._stopped:
            self._stopped = True
            self.device.stop()


class LinkStarter:
    """Starts a :class:`DemoLink` on a thread so the window stays responsive while kernels load."""

    def __init__(self, config: LinkConfig):
        self.link: DemoLink | None = None
        self.error: BaseException | None = None
        self.ready = threading.Event()
        self.started_s = time.perf_counter()
        self._thread = threading.Thread(target=self._run, args=(config,), name="demo-link-start", daemon=True)
        self._thread.start()

    def _run(self, config: LinkConfig) -> None:
        try:
            self.link = DemoLink.start(config)
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
