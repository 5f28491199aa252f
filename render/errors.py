"""Errors of the signal path that a person can act on; the message says what to do.

The physics has its own, :class:`ultraglide.render.physics.errors.ModelError`."""

from ultraglide.errors import UltraglideError


class RenderError(UltraglideError, ValueError):
    """Settings or input that the renderer cannot honour."""
