"""The atomic writer: a file appears whole or not at all."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from pathlib import Path

from ultraglide.atomic.failures import _masked_write_failure
from ultraglide.atomic.leftovers import _HOST, MARK, remove_leftovers
from ultraglide.atomic.targets import _HELD_PIPES, OutputRefused, kind_of, shared_folder_refusal
from ultraglide.errors import UltraglideError


class AtomicFile:
    """Where to write ``path`` (:attr:`temporary`) and how to finish: :meth:`commit` renames the temporary file
    into place, :meth:`discard` removes it. For a device or a pipe written directly, :attr:`temporary` is the
    target itself (:attr:`direct` is True) and both only release it.

    As a context manager it commits when the block succeeds and discards on any exception
    (``KeyboardInterrupt`` included), and an OSError from the block that names the temporary file (or no file)
    is raised again naming ``path``. Once committed or discarded it does nothing more.

    ``partial``: the temporary file is ``NAME.part`` beside the target, visible and of a fixed name, for a log
    written as it happens (a crash leaves its rows readable there); such a file is never taken for a leftover."""

    def __init__(self, path: str | Path, partial: bool = False):
        self.path = Path(path)
        self.partial = partial
        self.direct = False
        self._probe: int | None = None
        self._done = False
        refusal = shared_folder_refusal(self.path, str(self.path))
        if refusal is not None:
            raise refusal
        real = Path(os.path.realpath(self.path))
        try:
            info = os.stat(real)
        except FileNotFoundError:
            info = None
        except OSError as error:
            raise self._named(error) from None
        if info is not None and not stat.S_ISREG(info.st_mode):
            self._open_directly(real, info.st_mode)
            return
        self.target = real
        directory = real.parent
        remove_leftovers(directory)
        try:
            if partial:
                temporary = str(real.with_name(real.name + ".part"))
                refusal = shared_folder_refusal(temporary, f"{self.path}: its {temporary}")
                if refusal is not None:
                    raise refusal
                with contextlib.suppress(FileNotFoundError):
                    if not stat.S_ISREG(os.lstat(temporary).st_mode):
                        raise OutputRefused(f"{temporary}: is not a regular file; it cannot hold {self.path} as it "
                                            "grows")
                handle = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW | os.O_NONBLOCK
                                 | os.O_CLOEXEC, 0o600)
                if not stat.S_ISREG(os.fstat(handle).st_mode):
                    os.close(handle)
                    raise OutputRefused(f"{temporary}: is not a regular file; it cannot hold {self.path} as it grows")
            else:
                handle, temporary = tempfile.mkstemp(prefix=f".{real.stem}.{MARK}-{os.getpid()}-{_HOST}-",
                                                     suffix=real.suffix, dir=directory)
        except OSError as error:
            if error.errno == errno.ELOOP:  # O_NOFOLLOW: the .part is a link
                raise OutputRefused(f"{self.path}.part: is a link; it cannot hold {self.path} as it grows") from None
            raise self._named(error) from None
        self.temporary = Path(temporary)
        try:
            os.close(handle)
            os.chmod(temporary, stat.S_IMODE(info.st_mode) if info is not None else 0o666 & ~_umask())
        except BaseException:
            self.discard()
            raise

    def _open_directly(self, real: Path, mode: int) -> None:
        kind = kind_of(mode)
        if stat.S_ISDIR(mode):
            raise OutputRefused(f"{self.path}: is a directory; name a file to write")
        if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
            why = "writing a file there would overwrite the disk" if stat.S_ISBLK(mode) else "it is not a file"
            raise OutputRefused(f"{self.path}: is a {kind}; {why}: name a regular file")
        try:  # no O_CREAT, no O_TRUNC: a device or pipe is written, never made or emptied
            held = _HELD_PIPES.pop(str(real), None) if stat.S_ISFIFO(mode) else None
            self._probe = held if held is not None else os.open(real, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC
                                                                 | os.O_NOCTTY)
        except OSError as error:
            if error.errno == errno.ENXIO and stat.S_ISFIFO(mode):
                raise OutputRefused(f"{self.path}: is a named pipe that no program is reading; start the reader "
                                    "first, or name a regular file") from None
            raise self._named(error) from None
        # held open until the end, so a reader waiting on the pipe never sees it close between writers
        self.direct = True
        self.target = self.temporary = real

    def _named(self, error: OSError) -> OSError:
        return OSError(error.errno, error.strerror, str(self.path)) if error.errno else error

    def user_error(self, error: BaseException) -> BaseException:
        """``error`` as the person should see it: an OSError naming the temporary file (or no file) names
        ``path`` instead; a library's error raised while it cleaned up after a failed write (matplotlib's PDF
        writer on a full disk: ``zlib.error`` over the ``No space left on device``) is that write's OSError;
        anything else unchanged."""
        if not isinstance(error, OSError):
            error = _masked_write_failure(error) or error
        if not isinstance(error, OSError) or isinstance(error, UltraglideError) or error.errno is None:
            return error
        if error.filename is not None and str(error.filename) not in (str(self.temporary), str(self.target)):
            return error
        return OSError(error.errno, error.strerror, str(self.path))

    def commit(self) -> Path:
        """Put the written file in place (rename it over the target); on failure the temporary file goes."""
        if self._done:
            return self.path
        try:
            if not self.direct:
                with contextlib.suppress(FileNotFoundError):
                    now = os.lstat(self.target)
                    if not stat.S_ISREG(now.st_mode):  # it became something else while we wrote
                        raise OutputRefused(f"{self.path}: became a {kind_of(now.st_mode)} while it was being "
                                            "written; nothing was replaced")
                try:
                    os.replace(self.temporary, self.target)
                except OSError as error:
                    raise self._named(error) from None
        finally:
            self.discard()
        return self.path

    def discard(self) -> None:
        """Remove the temporary file if it is still there (a direct target is only released)."""
        self._done = True
        if self._probe is not None:
            probe, self._probe = self._probe, None
            os.close(probe)
        if not self.direct:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.temporary)

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self.commit()
            return
        self.discard()
        translated = self.user_error(value)
        if translated is not value:
            raise translated from None

    def __repr__(self) -> str:
        how = "directly" if self.direct else f"through {self.temporary.name}"
        return f"AtomicFile({str(self.path)!r}, written {how})"


def _umask() -> int:
    """This process's umask, read without changing it where /proc says it (other threads may be making files)."""
    with contextlib.suppress(OSError, ValueError, StopIteration):
        status = Path("/proc/self/status").read_text().splitlines()
        return int(next(line.split()[1] for line in status if line.startswith("Umask:")), 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
