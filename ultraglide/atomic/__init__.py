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

This package imports nothing of ours but the root's other leaves: every package may use it. Its modules by job:
:mod:`.writer` (:class:`AtomicFile`), :mod:`.targets` (what a path is; the checks before any work),
:mod:`.failures` (a failed write in words), :mod:`.leftovers` (temporary files' names; removing leftovers).

Example::

    with AtomicFile("out.csv") as target:
        target.temporary.write_text("t_s\n0\n")   # out.csv appears only if this succeeds
"""

from __future__ import annotations

from ultraglide.atomic.failures import write_failure
from ultraglide.atomic.leftovers import MARK, remove_leftovers
from ultraglide.atomic.targets import (
    OutputRefused,
    check_output,
    check_output_folder,
    kind_of,
    release_checked,
    shared_folder_refusal,
)
from ultraglide.atomic.writer import AtomicFile

__all__ = ["AtomicFile", "OutputRefused", "check_output", "check_output_folder", "kind_of", "release_checked",
           "remove_leftovers", "shared_folder_refusal", "write_failure", "MARK"]
