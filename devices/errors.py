"""Errors about hardware that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError, describe


class DeviceError(UltraglideError, RuntimeError):
    """A device, port, profile or device URL that cannot be used; a ``RuntimeError`` too.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> load_profile("sim-plate").check_carrier(30000.0)       # Hz, outside the plate's 20-28 kHz
    Traceback (most recent call last):
    ...
    ultraglide.devices.errors.DeviceError: carrier 30000 Hz is outside plate sim-plate's range 20000-28000 Hz
    >>> issubclass(DeviceError, RuntimeError)
    True
    """


__all__ = ["DeviceError", "describe"]  # describe: kept here for older imports
