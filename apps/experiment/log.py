"""The session's files: a per-trial CSV written as the session goes, and its metadata as JSON.

Each trial's row is flushed and fsync'd before the next trial starts, so a session that stops (a
crash, a power cut, Esc) loses at most the trial under way; :func:`read_trials` reads the log back
for ``--resume`` (a half-written last line is dropped). ``session.json`` is rewritten whole
(a temporary file renamed) at the start and at the end.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import atomic_path

COLUMNS = ("participant", "session", "trial", "condition", "level", "stimulus", "target", "response", "correct",
           "rt_s", "reversal", "break_before", "rendered_um_pp", "rendered_contrast", "time_utc")
TRIALS, SESSION, RESULT = "trials.csv", "session.json", "result.json"


class TrialLog:
    """Appends rows to ``DIR/trials.csv``; a new file gets the header."""

    def __init__(self, directory: Path):
        self.path = Path(directory) / TRIALS
        new = not self.path.exists() or self.path.stat().st_size == 0
        self._file = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115 - open for the session
        self._writer = csv.DictWriter(self._file, fieldnames=COLUMNS, lineterminator="\n")
        if new:
            self._writer.writeheader()
            self._sync()

    def _sync(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())

    def write(self, row: dict) -> None:
        self._writer.writerow({key: row.get(key, "") for key in COLUMNS})
        self._sync()

    def close(self) -> None:
        self._file.close()


def read_trials(directory: Path) -> list[dict]:
    """The logged trials, in order. A last line without its newline (the session stopped while writing
    it) is cut off the file, so appending continues cleanly."""
    path = Path(directory) / TRIALS
    if not path.exists():
        return []
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        data = data[:data.rfind(b"\n") + 1]
        with open(path, "r+b") as handle:
            handle.truncate(len(data))
    rows = list(csv.DictReader(data.decode("utf-8").splitlines()))
    for number, row in enumerate(rows, start=1):
        if row.get("trial") != str(number):
            raise UsageError(f"{path}: row {number} is trial {row.get('trial')!r}; the log is not one session's")
    return rows


def write_json(path: Path, document: dict) -> None:
    with atomic_path(path) as temporary:
        temporary.write_text(json.dumps(document, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")


def read_session(directory: Path) -> dict:
    path = Path(directory) / SESSION
    if not path.is_file():
        raise UsageError(f"--resume {directory}: no {SESSION} there; is it a session directory?")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise UsageError(f"{path} is not valid JSON ({error.msg} at line {error.lineno})") from None
