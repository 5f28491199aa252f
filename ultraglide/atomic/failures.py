"""A failed write, in words: the system's reason where a library hid it."""

from __future__ import annotations

import errno
import os
from pathlib import Path

_WRITE_FAILURES = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS}


def _masked_write_failure(error: BaseException) -> OSError | None:
    """The OSError of a failed write (a full disk, a file too large) that ``error`` was raised while handling, if
    any: a library that cleans up after such a failure may fail again, and its second error hides the reason."""
    seen = error.__context__
    for _ in range(8):
        if seen is None:
            return None
        if isinstance(seen, OSError) and seen.errno in _WRITE_FAILURES:
            return seen
        seen = seen.__context__
    return None


def write_failure(path: str | Path, written: str | Path, error: Exception) -> OSError:
    """An OSError that says why writing ``written`` (the temporary file behind ``path``, or ``path`` itself)
    failed, naming ``path``.

    libsndfile reports every failed write as "System error"; one more write to the file brings the system's
    own reason (no space left on device, file too large) to light. A WAV cannot go to a pipe or a terminal
    (its header is written last); libsndfile says so in its own words, turned into ours."""
    if "pipe write" in str(error):
        return OSError(errno.ESPIPE, "a WAV file cannot be written to a pipe or a terminal (its header is "
                                     "written last); name a regular file", str(path))
    try:
        descriptor = os.open(written, os.O_WRONLY | os.O_APPEND | os.O_NONBLOCK | os.O_CLOEXEC | os.O_NOCTTY)
        try:
            os.write(descriptor, bytes(1 << 16))
            os.fsync(descriptor)
        finally:
            os.close(descriptor)
    except OSError as reason:
        if reason.errno is not None and reason.errno not in (errno.EINVAL, errno.EROFS, errno.ESPIPE):
            return OSError(reason.errno, reason.strerror, str(path))
    return OSError(errno.EIO, f"writing failed ({error})", str(path))
