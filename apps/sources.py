"""Adapters that let devices pull from a renderer without knowing it (devices.source.BlockSource)."""

from __future__ import annotations

import numpy as np
from ultraglide.render.renderer import Renderer


class ControlSource:
    """Amplitude setpoints (µm p-p) at the control rate, for plate drivers."""

    def __init__(self, renderer: Renderer):
        self.renderer = renderer
        self.last_block = None

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        block = self.renderer.control(n, now_s)
        self.last_block = block
        return block.drive_um_pp

    def request_stop(self) -> None:
        self.renderer.stop()

    @property
    def finished(self) -> bool:
        return self.renderer.finished


class AudioSource(ControlSource):
    """Modulated carrier at the audio rate, float32 in [-1, 1], for sound cards and WAV files."""

    def __init__(self, renderer: Renderer):
        super().__init__(renderer)
        renderer.observers.append(self._remember)

    def _remember(self, block) -> None:
        self.last_block = block

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        return self.renderer.audio(n, now_s)


def source_for(device, renderer: Renderer) -> ControlSource:
    return AudioSource(renderer) if device.signal == "audio" else ControlSource(renderer)
