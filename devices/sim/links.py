"""Where a simulated plate is served: a symbolic link to its pseudo-terminal, placed and removed without
ever replacing anything that is not a link (a file or a device node of someone else's)."""

from __future__ import annotations

import contextlib
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


def remove_link(path: str) -> None:
    """Remove ``path`` if it is a link (anything else there is not ours)."""
    with contextlib.suppress(FileNotFoundError):
        if os.path.islink(path):
            os.unlink(path)
