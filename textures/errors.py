"""Errors about textures that a person can act on; the message says what to do."""


class TextureError(ValueError):
    """A texture, image or texture option that cannot be used."""
