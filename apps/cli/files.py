"""Write files so that a reader never sees half of one: a temporary file renamed into place.

Every file a command writes goes through :func:`atomic_path` (the implementation is
``ultraglide.devices.atomic_file``, which the WAV recorder shares). The temporary file is removed on
any way out but success: an exception (a full disk, a file too large), Ctrl-C, SIGTERM or SIGHUP
(which ``ultraglide``'s ``main`` turns into exceptions); its removal is held against a second signal
(see :mod:`ultraglide.apps.cli.signals`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

from ultraglide.apps.cli.signals import held
from ultraglide.devices.atomic_file import AtomicFile


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` if the block succeeds.

    Whatever the block writes there must be complete (files closed, errors raised) when it ends."""
    target = AtomicFile(path)
    try:
        yield target.temporary
        with held():
            target.commit()
    except OSError as error:
        if error.errno is None or (error.filename is not None and str(error.filename) != str(target.temporary)):
            raise
        # a failed write names the hidden temporary file or nothing: name the file the person asked for
        raise OSError(error.errno, error.strerror, str(path)) from None
    finally:
        with held():
            target.discard()
