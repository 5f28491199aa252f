"""Errors of the signal path that a person can act on; the message says what to do.

The physics has its own, :class:`ultraglide.render.physics.errors.ModelError`."""


class RenderError(ValueError):
    """Settings or input that the renderer cannot honour."""
