"""Where a simulated plate is served: a symbolic link to its pseudo-terminal, placed and removed without
ever replacing anything that is not a link (a file or a device node of someone else's).

A link path is owned: a simulator that serves at a path it was given claims it first (:class:`LinkClaim`: an
exclusive ``flock`` on a hidden file beside it, ``.NAME.ultraglide-link``, held while it serves), so a second
simulator given the same path is refused in one line naming the first's process rather than taking the link
over; and a simulator removes the link only while it still leads to its own pseudo-terminal (``remove_link``'s
``target``). A simulator killed outright leaves its claim file but not its lock: the next one takes it over.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import tempfile

from ultraglide.devices.errors import DeviceError


def link_path_for(link_path: str | None, prefix: str) -> tuple[str, str | None]:
    """The path the link goes to, checked, and the directory made for it (None when the caller chose one):
    a new temporary directory when ``link_path`` is None."""
    own_dir = None
    if link_path is None:
        own_dir = tempfile.mkdtemp(prefix=prefix)
        link_path = os.path.join(own_dir, "plate")
    directory = os.path.dirname(os.path.abspath(link_path))
    if not os.path.isdir(directory):
        raise DeviceError(f"no directory {directory} for the plate's link {link_path}: create it or choose "
                          "another --link")
    if os.path.lexists(link_path) and not os.path.islink(link_path):  # never put a link over a file or device
        raise DeviceError(f"{link_path} exists and is not a link: the plate's link goes where there is nothing "
                          "or a link; choose another --link")
    return link_path, own_dir


def place_link(target: str, path: str) -> None:
    """``path`` becomes a link to ``target`` in one step (a link made beside it, renamed over it)."""
    temporary = path + ".new"
    if os.path.islink(temporary):  # a link of an earlier run; anything else there is not ours
        os.unlink(temporary)
    os.symlink(target, temporary)
    os.replace(temporary, path)


def remove_link(path: str, target: str | None = None) -> None:
    """Remove ``path`` if it is a link (anything else there is not ours) and, given ``target``, only while it leads
    there (a link someone put in its place since is theirs)."""
    with contextlib.suppress(FileNotFoundError):
        if os.path.islink(path) and (target is None or os.readlink(path) == target):
            os.unlink(path)


class LinkClaim:
    """This process's claim on a link path (see the module's docstring); :meth:`release` ends it.

    Raises :class:`DeviceError` (one line) when a live process holds the path."""

    def __init__(self, path: str):
        directory, name = os.path.split(os.path.abspath(path))
        self.lock_path = os.path.join(directory, f".{name}.ultraglide-link")
        try:
            self._fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        except OSError as error:
            raise DeviceError(f"cannot claim the plate's link {path} ({self.lock_path}: "
                              f"{(error.strerror or str(error)).lower()}); choose another --link") from None
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            holder = os.pread(self._fd, 32, 0).decode(errors="replace").strip() or "another"
            os.close(self._fd)
            if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise DeviceError(f"{path} is in use by a live simulated plate (process {holder}); stop it first or "
                                  "choose another --link") from None
            raise DeviceError(f"cannot claim the plate's link {path}: {(error.strerror or '').lower()}") from None
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, f"{os.getpid()}\n".encode(), 0)

    def release(self) -> None:
        """Give the path up (the claim file removed while still held, then closed). Idempotent."""
        if self._fd < 0:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.lock_path)
        os.close(self._fd)
        self._fd = -1
