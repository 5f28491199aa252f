"""What an output path is, and refusing before any work what may not be written (``check_output``)."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from pathlib import Path

from ultraglide.atomic.leftovers import _HOST, MARK
from ultraglide.errors import UltraglideError

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
