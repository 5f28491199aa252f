"""Errors of the physics that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError


class ModelError(UltraglideError, ValueError):
    """A friction model, calibration or measurement file that cannot be used."""


class ForceRangeWarning(UltraglideError, UserWarning):
    """A model was asked about a force outside the range it was fitted on or holds on (said once per model)."""


class QuasiStaticWarning(UltraglideError, UserWarning):
    """The lateral analysis ran at a frequency where the ridges' inertia makes it an estimate."""
