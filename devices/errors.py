"""Errors about hardware that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError, describe


class DeviceError(UltraglideError, RuntimeError):
    """A device, port, profile or device URL that cannot be used."""


__all__ = ["DeviceError", "describe"]  # describe: kept here for older imports
