"""Errors of the physics that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError


class ModelError(UltraglideError, ValueError):
    """A friction model, calibration or measurement file that cannot be used."""
