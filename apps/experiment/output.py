"""Where a live session's trials are felt: the real-time engine, or the renderer and device in process.

The window needs three verbs: ``touch`` (a finger report), ``show`` (the trial's texture: one per
trial) and ``stop``. With :mod:`ultraglide.render.engine` present, the engine process renders (the
texture crosses the engine's pipe in memory, as it was made); otherwise a renderer in this process
feeds the device (as ``ultraglide play`` does).
"""

from __future__ import annotations

from ultraglide.textures.texture import Texture


class EngineOutput:
    def __init__(self, device: str, profile: str, model: str, force_n: float, closed_loop: bool = False):
        from ultraglide.render.engine import Engine, EngineConfig

        self.engine = Engine.start(EngineConfig(texture="grating-1mm", model=model, profile=profile, device=device,
                                                default_force_n=force_n, closed_loop=closed_loop))
        self.engine.wait_ready(120)
        self.kind = "engine"
        self.touches = 0

    def touch(self, t_s: float, x_mm: float, y_mm: float, down: bool = True) -> None:
        """A finger report; EngineLost (exit status 7) once the engine's process died or froze (the device was made
        safe by its supervisor): a trial felt on nothing must not be answered and kept."""
        if self.engine.loss is not None:
            from ultraglide.render.engine import EngineLost

            raise EngineLost(self.engine.loss)
        self.engine.touch(t_s, x_mm, y_mm, None, down)
        self.touches += 1

    def show(self, texture: Texture, trial: int) -> None:
        # in memory: a 1600 × 600 trial pickled is some 4 MB and 5 ms, where a file cost 30 ms of CPU a trial
        # (a 16-bit PNG written, then read back by the engine) and quantised the texture to 16 bits
        self.engine.set_texture(texture)

    def trial_friction(self, since_s: float) -> dict:
        """What the trial played since ``since_s`` (:func:`trial_friction`)."""
        return trial_friction(self.engine, since_s)

    def stop(self) -> None:
        self.engine.stop()


def trial_friction(engine, since_s: float) -> dict:
    """What a trial played on ``engine`` since ``since_s`` (perf_counter s) while the finger touched: the mean target
    ratio, the mean friction ratio the plate's sensors measured (closed loop), the mean commanded amplitude (µm p-p),
    and the friction loop's state at the end, in words ("" without it)."""
    import numpy as np

    status = engine.status(30.0)
    history = status.history
    touched = (history.time_s >= since_s) & (history.down > 0)
    measured = history.measured_ratio[touched]
    measured = measured[np.isfinite(measured)]
    return {"target_ratio": float(history.target_ratio[touched].mean()) if touched.any() else None,
            "measured_ratio": float(measured.mean()) if len(measured) else None,
            "commanded_um_pp": float(history.commanded_um_pp[touched].mean()) if touched.any() else None,
            "loop": status.loop}


class LocalOutput:
    def __init__(self, device: str, profile: str, model: str, force_n: float):
        from ultraglide.devices.rig import load_plate
        from ultraglide.devices.urls import open_device
        from ultraglide.render.engine.realtime import threads_started_in_real_time
        from ultraglide.render.engine.sources import renderer_source
        from ultraglide.render.physics.calibration import load_model
        from ultraglide.render.renderer import Renderer, RenderSettings
        from ultraglide.textures.procedural import grating

        plate = load_plate(profile)
        friction = load_model(model)
        with threads_started_in_real_time():  # the device's threads (a simulated plate's, the stream's, on which
            self.device = open_device(device, plate)  # the renderer runs); this thread (the session's) stays ordinary
        try:
            rate = self.device.rate_hz if self.device.signal == "audio" else 96000
            self.renderer = Renderer(grating(1.0, (10.0, 10.0)), friction, plate,
                                     RenderSettings(audio_rate_hz=rate, default_force_n=force_n))
            with threads_started_in_real_time():
                self.device.start(renderer_source(self.device, self.renderer))
        except BaseException:
            self.device.stop()
            raise
        self.kind = "in-process renderer"
        self.touches = 0

    def touch(self, t_s: float, x_mm: float, y_mm: float, down: bool = True) -> None:
        self.renderer.push(t_s, x_mm, y_mm, None, down)
        self.touches += 1

    def show(self, texture: Texture, trial: int) -> None:
        self.renderer.set_texture(texture)

    def stop(self) -> None:
        self.device.stop()


def open_output(device: str, profile: str, model: str, force_n: float, closed_loop: bool = False):
    """The engine when this installation has it, else the renderer in process (open loop only)."""
    try:
        import ultraglide.render.engine  # noqa: F401
    except ImportError:
        if closed_loop:
            from ultraglide.apps.cli.errors import UsageError

            raise UsageError("the closed loop runs in the real-time engine, which this installation lacks") from None
        return LocalOutput(device, profile, model, force_n)
    return EngineOutput(device, profile, model, force_n, closed_loop)
