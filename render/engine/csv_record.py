"""A CSV file a run records as it goes, written by a thread of its own: the part both engine records share.

The file grows as ``FILE.part`` (:class:`ultraglide.atomic.AtomicFile`, never renamed over a non-file) and is
renamed to ``FILE`` when the record is closed, or removed when it is discarded; a write that fails keeps its
error as one line (:attr:`CsvRecord.error`) and nothing more is written. What a subclass brings: its columns,
its writer thread (how rows reach it, how it is stopped: :meth:`CsvRecord._stop_writer`) and its rows.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from ultraglide.atomic import AtomicFile


class CsvRecord:
    """The file of a record: ``FILE.part`` opened with its header line, rows appended, committed or discarded.

    Parameters
    ----------
    path : str or path-like
        The file the record becomes once closed; it grows as ``FILE.part`` meanwhile.
    columns : tuple of str
        The header's column names.

    Examples
    --------
    The envelope's record (:class:`~ultraglide.render.engine.envelope_record.EnvelopeRecord`) is one; discarded,
    nothing is left of it:

    >>> import pathlib, tempfile
    >>> from ultraglide.render.engine.envelope_record import EnvelopeRecord
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> record = EnvelopeRecord(folder / "envelope.csv")
    >>> isinstance(record, CsvRecord), record.part.name
    (True, 'envelope.csv.part')
    >>> record.discard(); sorted(p.name for p in folder.iterdir())
    []
    """

    def __init__(self, path: str | os.PathLike, columns: tuple[str, ...]):
        self.path = Path(path)
        self._target = AtomicFile(self.path, partial=True)  # FILE.part as it grows; never renamed over a non-file
        self.part = self._target.temporary
        self._handle = open(self.part, "w", encoding="utf-8", newline="")  # noqa: SIM115 - closed by close()
        self._handle.write(",".join(columns) + "\n")
        self.dropped = 0
        self.error: str | None = None

    def _write_rows(self, rows: np.ndarray, fmt: tuple[str, ...]) -> None:
        """Rows appended (the writer thread); a failure is kept in :attr:`error`."""
        text = io.StringIO()
        np.savetxt(text, rows, delimiter=",", fmt=fmt)
        try:
            self._handle.write(text.getvalue())
        except OSError as error:
            self.error = self._failure(error)

    def _failure(self, error: OSError) -> str:
        return f"{self.path}: {(error.strerror or str(error)).lower()}"

    def _stop_writer(self, finish: bool) -> None:
        """Stop the writer thread; with ``finish``, once everything taken so far is written."""
        raise NotImplementedError

    def close(self) -> str | None:
        """Write what is left, rename into place; the error in one line if the file could not be written (a full
        disk), and then nothing is left of it (no ``FILE.part``: a log with rows missing is no log).

        Returns
        -------
        str or None
            None once the file is in place; else what went wrong, in one line.

        Examples
        --------
        Closed with no rows, the file holds its header alone, read back by the csv module:

        >>> import csv, pathlib, tempfile
        >>> from ultraglide.render.engine.envelope_record import COLUMNS, EnvelopeRecord
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> print(EnvelopeRecord(folder / "envelope.csv").close())
        None
        >>> with open(folder / "envelope.csv", newline="") as handle:
        ...     tuple(next(csv.reader(handle))) == COLUMNS
        True
        >>> sorted(path.name for path in folder.iterdir())                  # no .part left
        ['envelope.csv']
        """
        self._stop_writer(finish=True)
        try:
            self._handle.close()
            if self.error is None:
                self._target.commit()
        except OSError as error:
            self.error = self.error or self._failure(error)
        if self.error is not None:
            self._target.discard()
        return self.error

    def discard(self) -> None:
        """Stop and remove the partial file: the run failed before it played.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> from ultraglide.render.engine.envelope_record import EnvelopeRecord
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> EnvelopeRecord(folder / "envelope.csv").discard()
        >>> list(folder.iterdir())
        []
        """
        self._stop_writer(finish=False)
        try:
            self._handle.close()
        finally:
            self._target.discard()
