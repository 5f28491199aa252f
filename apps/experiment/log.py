"""The session's files: a per-trial CSV written as the session goes, and its metadata as JSON.

Each trial's row is flushed and fsync'd before the next trial starts, so a session that stops (a
crash, a power cut, Esc) loses at most the trial under way; :func:`read_trials` reads the log back
for ``--resume`` (a half-written last line is dropped). ``session.json`` is rewritten whole
(a temporary file renamed) at the start and at the end.
"""

from __future__ import annotations

import csv
import os
import stat
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import atomic_path
from ultraglide.apps.cli.output import json_text

from ultraglide.experiment.columns import THRESHOLD_COLUMNS
from ultraglide.inputs import decode_text, parse_json, read_input

COLUMNS = tuple(THRESHOLD_COLUMNS)  # what each holds: ultraglide.experiment.columns, whence the docs
TRIALS, SESSION, RESULT = "trials.csv", "session.json", "result.json"
MAX_LOG_BYTES = 64 << 20  # about 150 bytes a trial: 400 000 trials


class TrialLog:
    """Appends rows to ``DIR/trials.csv``; a new file gets the header."""

    def __init__(self, directory: Path):
        self.path = Path(directory) / TRIALS
        descriptor = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK | os.O_CLOEXEC, 0o666)
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode):  # a pipe or a device is not a log (and a pipe would block)
            os.close(descriptor)
            raise UsageError(f"{self.path}: is not a regular file; a session's trials are logged to one")
        os.set_blocking(descriptor, True)
        new = info.st_size == 0
        columns = COLUMNS
        if not new:  # a resumed log keeps its own columns (one written before a column was added)
            with open(self.path, newline="", encoding="utf-8") as existing:
                columns = tuple(next(csv.reader(existing), COLUMNS)) or COLUMNS
        self._file = open(descriptor, "a", newline="", encoding="utf-8")  # noqa: SIM115 - open for the session
        self.columns = columns
        self._writer = csv.DictWriter(self._file, fieldnames=columns, lineterminator="\n")
        if new:
            self._writer.writeheader()
            self._sync()

    def _sync(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())

    def write(self, row: dict) -> None:
        self._writer.writerow({key: row.get(key, "") for key in self.columns})
        self._sync()

    def close(self) -> None:
        self._file.close()


def read_trials(directory: Path) -> list[dict]:
    """The logged trials, in order. A last line without its newline (the session stopped while writing
    it) is cut off the file, so appending continues cleanly."""
    path = Path(directory) / TRIALS
    if not os.path.lexists(path):
        return []
    data = read_input(path, "trial log", UsageError, max_bytes=MAX_LOG_BYTES)
    if b"\r" in data and b"\n" not in data:  # cut at its last newline, it would be emptied
        raise UsageError(f"{path}: its lines end in carriage returns only; it is not a trial log ultraglide wrote")
    if data and not data.endswith(b"\n"):
        data = data[:data.rfind(b"\n") + 1]
        with open(path, "r+b") as handle:
            handle.truncate(len(data))
    text = decode_text(data, str(path), "trial log", UsageError)
    try:
        rows = list(csv.DictReader(text.splitlines()))
    except csv.Error as problem:  # a cell longer than the csv module takes
        raise UsageError(f"{path}: not a session's trial log ({problem})") from None
    missing = [column for column in ("trial", "level", "response", "correct") if rows and column not in rows[0]]
    if missing:
        raise UsageError(f"{path}: no column {', '.join(missing)}; it is not a session's trial log")
    for number, row in enumerate(rows, start=1):
        if row.get("trial") != str(number) or None in row.values():
            raise UsageError(f"{path}: row {number} is not trial {number} of one session's log (or is short)")
    return rows


def write_json(path: Path, document: dict) -> None:
    with atomic_path(path) as temporary:
        temporary.write_text(json_text(document, indent=2) + "\n", encoding="utf-8")


def read_session(directory: Path) -> dict:
    path = Path(directory) / SESSION
    if not os.path.lexists(path):
        raise UsageError(f"--resume {directory}: no {SESSION} there; is it a session directory?")
    document = parse_json(read_input(path, "session file", UsageError), str(path), UsageError, what="session file")
    if not isinstance(document, dict) or not isinstance(document.get("config"), dict):
        raise UsageError(f"{path}: no session configuration in it; is it a session directory's {SESSION}?")
    return document
