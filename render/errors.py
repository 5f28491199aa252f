"""Errors of the signal path that a person can act on; the message says what to do.

The physics has its own, :class:`ultraglide.render.physics.errors.ModelError`."""

from ultraglide.errors import UltraglideError


class RenderError(UltraglideError, ValueError):
    """Settings or input that the renderer cannot honour; a ``ValueError`` too.

    Examples
    --------
    >>> from ultraglide.render.renderer import RenderSettings
    >>> RenderSettings(control_rate_hz=-1)
    Traceback (most recent call last):
    ...
    ultraglide.render.errors.RenderError: the control rate must be at least 10 kHz, got -1 Hz
    """
