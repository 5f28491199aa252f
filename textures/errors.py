"""Errors about textures that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError


class TextureError(UltraglideError, ValueError):
    """A texture, image or texture option that cannot be used; a ``ValueError`` too.

    Examples
    --------
    >>> from ultraglide.textures.procedural import grating
    >>> grating(wavelength_mm=-1.0)
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: wavelength_mm must be a positive number, got -1.0
    """
