"""Errors about hardware that a person can act on; the message says what to do."""

import errno


class DeviceError(RuntimeError):
    """A device, port, profile or device URL that cannot be used."""


_NO_ROOM = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


def describe(error: BaseException) -> str:
    """One line for an error a person can act on: OSErrors name the file and the reason, and a full
    disk says that nothing was saved. Shared by the commands and the engine process, which reports its
    errors to the app as text."""
    if isinstance(error, OSError) and error.strerror:
        where = f"{error.filename}: " if error.filename else ""
        advice = "; nothing was saved: free some space or write elsewhere" if error.errno in _NO_ROOM else ""
        return f"{where}{error.strerror.lower()}{advice}"
    return str(error).splitlines()[0] if str(error) else type(error).__name__
