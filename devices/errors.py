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
    ultraglide.devices.errors.CarrierError: carrier 30000 Hz is outside plate sim-plate's range 20000-28000 Hz
    >>> issubclass(DeviceError, RuntimeError)
    True
    """


class CarrierError(DeviceError):
    """A carrier frequency that cannot be used: outside the plate's range, or more than the sample rate can carry.
    The value to change is the user's (``--carrier-hz``, ``--rate``, a profile's carrier), so a command exits 2
    (input) on it. A :class:`DeviceError` too.

    Examples
    --------
    >>> from ultraglide.devices.output.carrier import check_carrier
    >>> check_carrier(25000.0, 44100)             # Hz: a 44.1 kHz rate cannot carry 25 kHz  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.devices.errors.CarrierError: a 25000 Hz carrier needs a sample rate of at least 62,500 Hz (got ...
    >>> issubclass(CarrierError, DeviceError)
    True
    """


__all__ = ["CarrierError", "DeviceError", "describe"]  # describe: kept here for older imports
