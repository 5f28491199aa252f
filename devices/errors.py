"""Errors about hardware that a person can act on; the message says what to do."""


class DeviceError(RuntimeError):
    """A device, port, profile or device URL that cannot be used."""
