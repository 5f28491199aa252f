"""The one atomic writer: a file appears whole or not at all, and nothing that is not a file is ever replaced.

What happens depends on what the target is, after following symbolic links to their end (a link stays a
link: the file it points to is what gets written):

============================  ===========================================================================
target                        what :class:`AtomicFile` does
============================  ===========================================================================
nothing, or a regular file    writes a hidden temporary file beside it and renames it over the target only
                              once complete (an existing file's permission bits are kept)
a character device            writes to it directly, as a shell's ``>`` would (``/dev/null``; ``/dev/full``
                              gives "no space left"); never renamed over, never truncated
a named pipe (FIFO)           writes to it directly when a program is reading it; refused when none is
                              (opening it would wait for a reader forever)
a directory                   refused: name a file
a block device (a disk)       refused: writing a file there would overwrite the disk
a socket                      refused: it is not written by opening it
============================  ===========================================================================

In a shared folder (sticky and world-writable: ``/tmp``), a target, a link on the way to it or a ``.part`` that
is another user's is refused whatever it is (:func:`shared_folder_refusal`): as root a rename would replace their
file, and their link could lead anywhere.

A refusal is an :class:`OutputRefused`, one line naming the file the person gave. Any failure while
writing names that file too, never the hidden temporary one.

:func:`check_output` (and :func:`check_output_folder` for a folder files are written into) refuses the same
targets before any work, with the option that named them, and a regular file whose folder is missing or takes
no new file (read-only, permissions); ``ultraglide``'s ``main`` calls it for every output option of every
command. A named pipe it finds read is held open until :class:`AtomicFile` writes it (or
:func:`release_checked`), so a reader that stops at its first end of file never sees one in between.

Temporary files are named ``.{stem}.ultraglide-{pid}-{host}-{random}{suffix}`` (``host``: six hex digits of
this machine's name). A process killed outright (SIGKILL, a power cut) leaves its temporary file behind;
each writer removes such leftovers from the folder it writes to: files of that form, of this user and this
machine, whose process is gone (or whose process id now belongs to a process started after the file was
last written).

This module imports nothing of ours but the root's other leaves: every package may use it.

Example::

    with AtomicFile("out.csv") as target:
        target.temporary.write_text("t_s\\n0\\n")   # out.csv appears only if this succeeds
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import re
import socket
import stat
import tempfile
from pathlib import Path

from ultraglide.errors import UltraglideError

MARK = "ultraglide"
_HOST = hashlib.sha1(socket.gethostname().encode(errors="replace")).hexdigest()[:6]
_LEFTOVER = re.compile(rf"^\..*\.{MARK}-(?P<pid>[0-9]+)-(?P<host>[0-9a-f]{{6}})-[a-z0-9_]{{8}}(\.[^.]*)?$")
_CLOCK_SLACK_S = 2.0  # a process start time from /proc is good to the second
# named pipes that check_output opened for writing (its path → the descriptor), taken by AtomicFile: a reader that
# stops at its first end of file (``cat``) never sees one between the check and the writing
_HELD_PIPES: dict[str, int] = {}


class OutputRefused(UltraglideError, ValueError):
    """An output path that is not a file ultraglide may write (a directory, a disk, a socket, a pipe that
    nobody reads); the message names the path."""


def kind_of(mode: int) -> str:
    """What a ``stat`` mode is, in words: regular file, directory, named pipe, character device ..."""
    for test, words in ((stat.S_ISREG, "regular file"), (stat.S_ISDIR, "directory"), (stat.S_ISFIFO, "named pipe"),
                        (stat.S_ISCHR, "character device"), (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket")):
        if test(mode):
            return words
    return "special file"


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


def check_output(path: str | Path, option: str, *, kind: str = "file", named: str | None = None) -> None:
    """Refuse now, before any work, an output that writing would refuse later: :class:`OutputRefused`, one line
    naming ``option`` (what the person typed: ``-o``, ``--plot``), the path, and what to do instead.

    ``kind``: ``file`` (anything :class:`AtomicFile` writes: a regular file, new or replaced, a character device
    or a named pipe a program reads), ``wav`` (the same but no pipe: a WAV's header is written last), ``log``
    (a file that grows beside it as ``NAME.part``, which must be nothing or a regular file) or ``link`` (a
    symbolic link placed there: nothing or a link may be there). A regular file's folder must exist and take a
    new file (one is made there and removed); a named pipe that a program reads is held open until written, so
    that a reader stopping at its first end of file never sees one in between. ``named``: how the person gave
    the path, when not as itself (``wav:PATH``)."""
    where = f"{option} {named or path}"
    real = _real(path, where)
    refusal = shared_folder_refusal(path, where, follow=kind != "link")
    if kind == "log" and refusal is None:
        part = real.with_name(real.name + ".part")
        refusal = shared_folder_refusal(part, f"{where}: its {part}")
    if refusal is not None:
        raise refusal
    if kind == "link":
        try:
            mode = os.lstat(path).st_mode
        except (OSError, ValueError):
            mode = None
        if mode is not None and not stat.S_ISLNK(mode):
            raise OutputRefused(f"{where}: is a {kind_of(mode)}, not a link; a link is placed only where there is "
                                "nothing or a link: name another path")
        _check_folder(Path(os.path.abspath(path)).parent, where)
        return
    info = _look(real, where)
    if info is not None and not stat.S_ISREG(info.st_mode):
        _check_special(real, info.st_mode, where, pipe=kind != "wav")
        return
    _check_folder(real.parent, where)
    if kind == "log":
        part = real.with_name(real.name + ".part")
        with contextlib.suppress(FileNotFoundError):
            mode = os.lstat(part).st_mode
            if not stat.S_ISREG(mode):
                raise OutputRefused(f"{where}: {part} is a {'link' if stat.S_ISLNK(mode) else kind_of(mode)}, where "
                                    "the log grows as it is written; remove it or name another file")


def check_output_folder(path: str | Path, option: str) -> None:
    """Refuse now an output folder (files are written into it; it and its parents are made if missing) that is
    not a folder or that cannot take a new file: :class:`OutputRefused`, one line naming ``option``."""
    where = f"{option} {path}"
    real = _real(path, where)
    info = _look(real, where)
    if info is not None and not stat.S_ISDIR(info.st_mode):
        raise OutputRefused(f"{where}: is a {kind_of(info.st_mode)}, not a folder; name a folder to write into")
    existing = real
    while info is None:  # made with its parents: the nearest that exists must take them
        existing = existing.parent
        info = _look(existing, where)
    if not stat.S_ISDIR(info.st_mode):
        raise OutputRefused(f"{where}: {existing} is a {kind_of(info.st_mode)}, not a folder; name a folder")
    _probe_folder(existing, where)


def shared_folder_refusal(path: str | Path, where: str, follow: bool = True) -> OutputRefused | None:
    """The refusal (one line naming ``where``) of a path that is another user's in a shared folder, else None.

    In a folder anyone may write that keeps each one's files their own (sticky and world-writable: ``/tmp``), what
    another user put there is theirs, and a path naming it is likely a trap: their file is not replaced (as root, a
    rename would replace it; as anyone else it fails only after the work), their link is not followed (to a file of
    ours, or /etc), their pipe or device is not written. Linux guards some opens there (``fs.protected_regular``,
    ``protected_symlinks``, ``protected_fifos``) only where they are switched on, and never a rename. ``follow``:
    walk a chain of links (each link and where it ends are checked), or look at ``path`` itself only."""
    me = os.geteuid()
    try:
        current = Path(os.path.abspath(path))
    except ValueError:  # a NUL byte: the path checks say so
        return None
    for _ in range(40):  # Linux follows at most 40 links
        try:
            info = os.lstat(current)
            folder = os.stat(current.parent)
        except (OSError, ValueError):
            return None  # nothing there (or unreachable): nothing of anyone's to replace
        shared = folder.st_mode & stat.S_ISVTX and folder.st_mode & stat.S_IWOTH
        if shared and info.st_uid != me:
            what = "link" if stat.S_ISLNK(info.st_mode) else kind_of(info.st_mode)
            return OutputRefused(f"{where}: is another user's {what} (uid {info.st_uid}) in the shared folder "
                                 f"{current.parent}; ultraglide leaves what is theirs alone: name a file of yours")
        if not (follow and stat.S_ISLNK(info.st_mode)):
            return None
        try:
            current = Path(os.path.abspath(current.parent / os.readlink(current)))
        except OSError:
            return None
    return None


def release_checked() -> None:
    """Close the named pipes :func:`check_output` held that nothing took (the command wrote them in another
    process, or stopped first): their readers see the end."""
    while _HELD_PIPES:
        os.close(_HELD_PIPES.popitem()[1])


def _real(path: str | Path, where: str) -> Path:
    """``path`` with its links and ``..`` followed; OutputRefused for a name no file can have (a NUL byte)."""
    try:
        return Path(os.path.realpath(path))
    except ValueError:
        raise OutputRefused(f"{where}: not a usable file name") from None


def _look(real: Path, where: str) -> os.stat_result | None:
    """``stat`` of ``real``, None when nothing is there; OutputRefused when it cannot be looked at."""
    try:
        return os.stat(real)
    except FileNotFoundError:
        return None
    except ValueError:  # a NUL byte
        raise OutputRefused(f"{where}: not a usable file name") from None
    except OSError as error:
        if error.errno == errno.ENOTDIR:
            return None  # a part of the path is a file: the folder check says which
        if error.errno == errno.ELOOP:
            raise OutputRefused(f"{where}: is a loop of symbolic links; name a regular file") from None
        raise OutputRefused(f"{where}: cannot be reached ({(error.strerror or str(error)).lower()}); "
                            "name a file you may write") from None


def _check_special(real: Path, mode: int, where: str, pipe: bool) -> None:
    """What is not a regular file: a character device opened and closed (written directly later), a named pipe
    with a reader held open, anything else refused."""
    kind = kind_of(mode)
    if stat.S_ISDIR(mode):
        raise OutputRefused(f"{where}: is a directory; name a file to write (in it, or elsewhere)")
    if stat.S_ISBLK(mode):
        raise OutputRefused(f"{where}: is a block device; writing a file there would overwrite the disk: name a "
                            "regular file")
    if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
        raise OutputRefused(f"{where}: is a {kind}; it is not written by opening it: name a regular file")
    if stat.S_ISFIFO(mode) and str(real) in _HELD_PIPES:
        return
    try:
        descriptor = os.open(real, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC | os.O_NOCTTY)
    except OSError as error:
        if error.errno == errno.ENXIO and stat.S_ISFIFO(mode):
            raise OutputRefused(f"{where}: is a named pipe that no program is reading; start the reader first, or "
                                "name a regular file") from None
        raise OutputRefused(f"{where}: is a {kind} that cannot be written ({(error.strerror or '').lower()}); "
                            "name a regular file") from None
    if stat.S_ISCHR(mode):
        os.close(descriptor)
    elif not pipe:
        os.close(descriptor)  # its reader sees an end, but nothing will be written to it anyway
        raise OutputRefused(f"{where}: is a named pipe; a WAV file cannot go through one (its header is written "
                            "last): name a regular file")
    else:
        _HELD_PIPES[str(real)] = descriptor


def _check_folder(folder: Path, where: str) -> None:
    """The folder a new file goes in: it exists, is a folder, and takes a new file."""
    try:
        info = os.stat(folder)
    except OSError as error:
        if isinstance(error, FileNotFoundError):
            raise OutputRefused(f"{where}: its folder {folder} does not exist; make it first, or write "
                                "elsewhere") from None
        if error.errno == errno.ENOTDIR:
            raise OutputRefused(f"{where}: a part of {folder} is a file, not a folder; name a file in a "
                                "folder") from None
        raise OutputRefused(f"{where}: its folder {folder} cannot be reached "
                            f"({(error.strerror or str(error)).lower()}); write elsewhere") from None
    if not stat.S_ISDIR(info.st_mode):
        raise OutputRefused(f"{where}: {folder} is a {kind_of(info.st_mode)}, not a folder; name a file in a "
                            "folder")
    _probe_folder(folder, where)


def _probe_folder(folder: Path, where: str) -> None:
    """Make a file in ``folder`` and remove it: the one sure test that the writing will be allowed there (a
    read-only file system, permissions, ACLs, root's own exceptions). Named as a leftover would be."""
    try:
        handle, probe = tempfile.mkstemp(prefix=f".probe.{MARK}-{os.getpid()}-{_HOST}-", dir=folder)
    except OSError as error:
        reason = {errno.EROFS: "it is on a read-only file system", errno.ENOSPC: "its disk is full",
                  errno.EDQUOT: "your disk quota is used up"}.get(error.errno, f"{(error.strerror or '').lower()}")
        raise OutputRefused(f"{where}: cannot write in its folder {folder} ({reason}); write elsewhere") from None
    os.close(handle)
    with contextlib.suppress(OSError):
        os.unlink(probe)


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


def remove_leftovers(directory: str | Path) -> list[Path]:
    """Remove the temporary files that killed ultraglide processes left in ``directory`` (see the module's
    docstring for which); returns those removed. Anything unreadable is left alone."""
    removed = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        match = _LEFTOVER.match(entry.name)
        if match is None or match["host"] != _HOST:
            continue
        try:
            info = entry.stat(follow_symlinks=False)
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.geteuid():
                continue
            if _alive_since(int(match["pid"]), info.st_mtime):
                continue
            os.unlink(entry.path)
            removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


def _alive_since(pid: int, written_at: float) -> bool:
    """Whether the process that wrote a file last at ``written_at`` (epoch seconds) may still be running: a
    process ``pid`` exists, is not a zombie, and (where /proc tells) started before that time."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    started = _start_time(pid)
    if started is None:
        return True
    state, started_at = started
    return state != "Z" and started_at <= written_at + _CLOCK_SLACK_S


def _start_time(pid: int) -> tuple[str, float] | None:
    """A process's state letter and its start (epoch seconds) from /proc; None where there is no /proc."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        boot_s = next(float(line.split()[1]) for line in Path("/proc/stat").read_text().splitlines()
                      if line.startswith("btime "))
        return fields[0], boot_s + int(fields[19]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def _umask() -> int:
    """This process's umask, read without changing it where /proc says it (other threads may be making files)."""
    with contextlib.suppress(OSError, ValueError, StopIteration):
        status = Path("/proc/self/status").read_text().splitlines()
        return int(next(line.split()[1] for line in status if line.startswith("Umask:")), 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


__all__ = ["AtomicFile", "OutputRefused", "check_output", "check_output_folder", "kind_of", "release_checked",
           "remove_leftovers", "shared_folder_refusal", "write_failure"]
