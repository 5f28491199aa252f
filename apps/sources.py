"""A renderer as the envelope source devices are started with, behind the device's output stage."""

from __future__ import annotations

import numpy as np
from ultraglide.devices.output_stage import OutputStage, output_stage
from ultraglide.render.renderer import Renderer


class EnvelopeSource:
    """The renderer's drive envelope, µm p-p at its control rate (a devices.source.BlockSource)."""

    def __init__(self, renderer: Renderer):
        self.renderer = renderer
        self.control_rate_hz = renderer.settings.control_rate_hz

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        return self.renderer.control(n, now_s).drive_um_pp

    def request_stop(self) -> None:
        self.renderer.stop()

    @property
    def finished(self) -> bool:
        return self.renderer.finished


def source_for(device, renderer: Renderer) -> OutputStage:
    """What to start ``device`` with: the renderer behind the limiter, as the device's signal. The device
    would wrap a bare envelope source the same way; built here, the app can read the limiter's counters."""
    carrier_hz = getattr(device, "carrier_hz", None) or renderer.carrier_hz
    return output_stage(EnvelopeSource(renderer), renderer.profile, device.signal, device.rate_hz, carrier_hz)


def offline_stage(renderer: Renderer) -> OutputStage:
    """The audio a plate would get from ``renderer`` at its own audio rate, for export."""
    return OutputStage(EnvelopeSource(renderer), renderer.profile, "audio", renderer.settings.audio_rate_hz,
                       renderer.carrier_hz)
