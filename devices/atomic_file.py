"""Files that appear whole or not at all: written to a temporary file beside the target, renamed into place.

This is the one implementation; ``ultraglide.apps.cli.files`` wraps it for the commands (and holds the
clean-up against stop signals). It lives here because the WAV recorder needs it and ``devices``
imports nothing else of ours.

Example::

    with AtomicFile("out.csv") as target:
        target.temporary.write_text("t_s\\n0\\n")   # out.csv appears only if this succeeds
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path


class AtomicFile:
    """A temporary path beside ``path``; :meth:`commit` renames it into place, :meth:`discard` removes it.

    As a context manager it commits when the block succeeds and discards on any exception
    (``KeyboardInterrupt`` included). Once committed or discarded it does nothing more."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        directory = self.path.parent if str(self.path.parent) else Path(".")
        handle, temporary = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=self.path.suffix, dir=directory)
        self.temporary = Path(temporary)
        try:
            os.close(handle)
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(temporary, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual mode
        except BaseException:
            self.discard()
            raise

    def commit(self) -> Path:
        """Rename the temporary file to the target; on failure the temporary file is removed."""
        try:
            os.replace(self.temporary, self.path)
        finally:
            self.discard()
        return self.path

    def discard(self) -> None:
        """Remove the temporary file if it is still there."""
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.temporary)

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self.commit()
        else:
            self.discard()


def write_failure(path: str | Path, written: str | Path, error: Exception) -> OSError:
    """An OSError that says why writing ``written`` (the temporary file behind ``path``) failed.

    libsndfile reports every failed write as "System error"; one more write to the file brings
    the system's own reason (no space left on device, file too large) to light."""
    try:
        with open(written, "ab") as stream:
            stream.write(bytes(1 << 16))
            stream.flush()
            os.fsync(stream.fileno())
    except OSError as reason:
        if reason.errno is not None:
            return OSError(reason.errno, reason.strerror, str(path))
    return OSError(errno.EIO, f"writing failed ({error})", str(path))
