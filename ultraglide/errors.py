"""The root of every error ultraglide raises for a person to act on, and the one line that describes one.

``except ultraglide.UltraglideError`` catches anything the library refused: a texture, a model, a
setting, a device, a file. Each package's errors derive from it and keep their older bases
(``ValueError`` for bad values, ``RuntimeError`` for devices), as python-soundfile added
``SoundFileError`` under its old bases, so callers that caught those still do.

This module imports nothing of ours: every package, ``devices`` and ``textures`` included, may import it.
"""

from __future__ import annotations

import errno


class UltraglideError(Exception):
    """Anything ultraglide refused; the message is one line that says what is wrong and what to do."""


_NO_ROOM = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


def describe(error: BaseException) -> str:
    """One line for an error a person can act on: OSErrors name the file and the reason (a full disk says that
    nothing was saved); other errors give their message's first line. Shared by the command and the engine
    process, which reports its errors to the app as text."""
    if isinstance(error, OSError) and error.strerror:
        where = f"{error.filename}: " if error.filename else ""
        advice = "; nothing was saved: free some space or write elsewhere" if error.errno in _NO_ROOM else ""
        return f"{where}{error.strerror.lower()}{advice}"
    return str(error).splitlines()[0] if str(error) else type(error).__name__
