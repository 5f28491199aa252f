"""A renderer as the envelope source devices are started with, behind the device's output stage.
The adapters live in :mod:`ultraglide.api` (public); these names remain for the commands."""

from __future__ import annotations

from ultraglide.devices.output_stage import OutputStage
from ultraglide.render.renderer import Renderer

from ultraglide.api import EnvelopeSource, offline_stage, renderer_source


def source_for(device, renderer: Renderer) -> OutputStage:
    """What to start ``device`` with: the renderer behind the limiter, as the device's signal (the public
    :func:`ultraglide.api.renderer_source`; one path for the library and the commands)."""
    return renderer_source(device, renderer)


__all__ = ["EnvelopeSource", "offline_stage", "source_for"]
