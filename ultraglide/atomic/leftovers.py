"""Hidden temporary files: their names, and removing those a process killed outright left behind."""

from __future__ import annotations

import hashlib
import os
import re
import socket
import stat
from pathlib import Path

MARK = "ultraglide"


_HOST = hashlib.sha1(socket.gethostname().encode(errors="replace")).hexdigest()[:6]


_LEFTOVER = re.compile(rf"^\..*\.{MARK}-(?P<pid>[0-9]+)-(?P<host>[0-9a-f]{{6}})-[a-z0-9_]{{8}}(\.[^.]*)?$")


_CLOCK_SLACK_S = 2.0  # a process start time from /proc is good to the second


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
