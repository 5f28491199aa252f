"""Errors about textures that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError


class TextureError(UltraglideError, ValueError):
    """A texture, image or texture option that cannot be used."""
