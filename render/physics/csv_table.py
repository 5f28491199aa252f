"""Numeric CSV files with a header line and ``#`` comments, read in chunks with typed, ranged columns.

The numbers are parsed by numpy's compiled reader (``np.loadtxt``) a block of a quarter megabyte
at a time, so a file of any length is read in bounded memory at a few million rows a second.
Each column has a range; the first value outside it (NaN and infinities included), a cell that
is not a number, a short row, a line that is not text, or a missing header column is reported
as ``error(message)`` naming the file and line, in one line. Only the error path reads lines one
by one, and only within the block at fault.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ultraglide.inputs import open_input, some_of

BLOCK_BYTES = 1 << 18  # 256 KiB: as fast as larger blocks, a quarter of the memory
MAX_LINE_BYTES = 1 << 16  # no line of a numeric CSV is this long; a longer one is not such a file
BLANK_LINE = re.compile(r"^[ \t]+(?=\r?$)", re.MULTILINE)


@dataclass(frozen=True)
class Column:
    """A column's name and the range its values must lie in (``low`` excluded when ``low_open``).

    Examples
    --------
    >>> import numpy as np
    >>> force = Column("force_n", 0.0, 10.0, "N", low_open=True)
    >>> force.describe(), force.outside(np.array([0.0, 0.5, 11.0, np.nan])).tolist()
    ('more than 0 to 10 N', [True, False, True, True])
    """

    name: str
    low: float
    high: float
    unit: str = ""
    low_open: bool = False

    def describe(self) -> str:
        """The column's range in words with its unit: ``from 0 to 50 µm p-p`` or ``more than 0 to 10 N``.

        Returns
        -------
        str

        Examples
        --------
        >>> Column("amplitude_um_pp", 0.0, 50.0, "µm p-p").describe()
        'from 0 to 50 µm p-p'
        """
        unit = f" {self.unit}" if self.unit else ""
        low = f"more than {self.low:g}" if self.low_open else f"from {self.low:g}"
        return f"{low} to {self.high:g}{unit}"

    def outside(self, values: np.ndarray) -> np.ndarray:
        """True where a value is outside the range or not a number.

        Parameters
        ----------
        values : numpy.ndarray

        Returns
        -------
        numpy.ndarray
            bool, one per value.

        Examples
        --------
        >>> import numpy as np
        >>> Column("ratio", 0.0, 1.0).outside(np.array([0.0, 1.0, 1.5, np.inf])).tolist()
        [False, False, True, True]
        """
        above_low = values > self.low if self.low_open else values >= self.low
        return ~(above_low & (values <= self.high))


@dataclass(frozen=True)
class Block:
    r"""Rows of one block: ``values[name]`` arrays; ``line_of(k)`` is the file line of row k.

    Examples
    --------
    The rows of a block and the file lines they came from (a comment line is skipped):

    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "forces.csv"
    >>> _ = path.write_text("t_s,force_n\n0,0.5\n# pressed harder\n0.1,0.8\n")
    >>> table = NumericCsv(path, (Column("t_s", 0.0, 1e6), Column("force_n", 0.0, 10.0)), (), ValueError, "force file")
    >>> block = next(table.blocks())
    >>> len(block), block.values["force_n"].tolist(), [block.line_of(k) for k in range(len(block))]
    (2, [0.5, 0.8], [2, 4])
    """

    values: dict[str, np.ndarray]
    text: str
    first_line: int

    def __len__(self) -> int:
        return len(next(iter(self.values.values())))

    def line_of(self, row: int) -> int:
        r"""The file line number of data row ``row`` (counts lines; used only to report errors).

        Parameters
        ----------
        row : int
            The data row, from 0.

        Returns
        -------
        int
            The file line, from 1.

        Examples
        --------
        Comments and the header count as lines:

        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "forces.csv"
        >>> _ = path.write_text("# bench\nt_s,force_n\n0,0.5\n\n0.1,0.8\n")
        >>> block = next(NumericCsv(path, (Column("t_s", 0.0, 1e6), Column("force_n", 0.0, 10.0)), (), ValueError,
        ...                         "force file").blocks())
        >>> block.line_of(0), block.line_of(1)
        (3, 5)
        """
        seen = -1
        for offset, line in enumerate(self.text.split("\n")):
            if _is_data(line):
                seen += 1
                if seen == row:
                    return self.first_line + offset
        return self.first_line


def _is_data(line: str) -> bool:
    stripped = line.strip()
    return bool(stripped) and not stripped.startswith("#")


class NumericCsv:
    r"""A numeric CSV file whose header has been read and checked; :meth:`blocks` streams its rows.

    ``required`` columns must be in the header, ``optional`` ones may be; the header may hold other
    columns too, in any order. ``error`` is the exception type raised, ``what`` names the file's
    kind in messages ("trajectory file").

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "forces.csv"
    >>> _ = path.write_text("force_n,t_s,note\n0.5,0,1\n0.8,0.1,2\n")
    >>> table = NumericCsv(path, (Column("t_s", 0.0, 1e6),), (Column("force_n", 0.0, 10.0),), ValueError, "force file")
    >>> table.names, [block.values["t_s"].tolist() for block in table.blocks()]
    (['t_s', 'force_n'], [[0.0, 0.1]])
    >>> _ = path.write_text("t_s\n0\n")
    >>> NumericCsv(path, (Column("force_n", 0.0, 10.0),), (), ValueError, "force file")
    Traceback (most recent call last):
    ...
    ValueError: .../forces.csv:1: missing column force_n; the header must be force_n
    """

    def __init__(self, path: str | Path, required: tuple[Column, ...], optional: tuple[Column, ...],
                 error: type[Exception], what: str):
        self.path = Path(path)
        self.error = error
        self.what = what
        expected = ",".join(c.name for c in required) + "".join(f"[,{c.name}]" for c in optional)
        with self._open() as stream:
            header, self.header_line = self._header(stream, expected)
            self._data_offset = stream.tell()
        names = [name.strip() for name in self._cells(header, self.header_line)]
        duplicated = sorted({name for name in names if names.count(name) > 1 and name})
        if duplicated:
            self._fail(self.header_line, f"column {some_of(duplicated)} appears twice in the header")
        missing = [c.name for c in required if c.name not in names]
        if missing:
            self._fail(self.header_line, f"missing column {', '.join(missing)}; the header must be {expected}")
        self.columns = list(required) + [c for c in optional if c.name in names]
        self.header_width = len(names)
        self._index = [names.index(c.name) for c in self.columns]

    @property
    def names(self) -> list[str]:
        r"""The columns' names, in order.

        Examples
        --------
        The required columns, then the optional ones the file has:

        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "forces.csv"
        >>> _ = path.write_text("force_n,t_s\n0.5,0\n")
        >>> NumericCsv(path, (Column("t_s", 0.0, 1e6),), (Column("force_n", 0.0, 10.0), Column("x_mm", 0.0, 1e3)),
        ...            ValueError, "force file").names
        ['t_s', 'force_n']
        """
        return [c.name for c in self.columns]

    def _fail(self, line: int | None, message: str):
        where = f"{self.path}:{line}" if line else f"{self.path}"
        raise self.error(f"{where}: {message}")

    def _cells(self, line: str, number: int) -> list[str]:
        """The cells of one line (a comment after ``#`` dropped); what the csv module refuses, in one line."""
        try:
            return next(csv.reader([line.split("#", 1)[0]]), [])
        except csv.Error as problem:  # a carriage return inside the line (old Mac line ends), a NUL ...
            if "new-line" in str(problem):
                self._fail(number, "a carriage return inside a line: lines must end in \\n or \\r\\n (old Mac line "
                                   "ends?)")
            self._fail(number, f"not a CSV line ({problem})")

    def _open(self):
        """The file, opened only if it is a regular one (a pipe or a device is refused, never read)."""
        if not os.path.lexists(self.path):
            raise self.error(f"{self.path}: no such file (a {self.what} was expected)")
        return open_input(self.path, self.what, self.error)

    def _header(self, stream, expected: str) -> tuple[str, int]:
        number = 0
        while True:
            raw = stream.readline(MAX_LINE_BYTES + 1)
            number += 1
            if not raw:
                self._fail(None, f"no data; expected a header line {expected}")
            if len(raw) > MAX_LINE_BYTES:
                self._fail(number, f"line longer than {MAX_LINE_BYTES} bytes: not a {self.what} (a CSV file)")
            line = self._decode(raw, number)
            if number == 1:
                line = line.removeprefix("\ufeff")
            if _is_data(line):
                return line.strip(), number

    def _decode(self, raw: bytes, first_line: int) -> str:
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as problem:
            line = first_line + raw.count(b"\n", 0, problem.start)
            self._fail(line, f"not UTF-8 text: a {self.what} is a CSV file")

    def _raw_blocks(self) -> Iterator[tuple[bytes, int]]:
        """Whole lines in blocks of about BLOCK_BYTES, each with its first line number."""
        with self._open() as stream:
            stream.seek(self._data_offset)
            line = self.header_line + 1
            rest = b""
            while True:
                chunk = stream.read(BLOCK_BYTES)
                data = rest + chunk
                if not chunk:
                    if data:
                        yield data, line
                    return
                cut = data.rfind(b"\n") + 1
                if cut == 0:
                    if len(data) > MAX_LINE_BYTES:
                        self._fail(line, f"line longer than {MAX_LINE_BYTES} bytes: not a {self.what} (a CSV file)")
                    rest = data
                    continue
                rest = data[cut:]
                yield data[:cut], line
                line += data.count(b"\n", 0, cut)

    def blocks(self) -> Iterator[Block]:
        r"""The data rows, block by block, every value checked against its column's range.

        Returns
        -------
        iterator of Block

        Raises
        ------
        Exception
            The table's error class: a value out of range or not a number, a short row, naming the file and line.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "forces.csv"
        >>> _ = path.write_text("t_s,force_n\n0,0.5\n0.1,20\n")
        >>> table = NumericCsv(path, (Column("t_s", 0.0, 1e6), Column("force_n", 0.0, 10.0, "N")), (), ValueError,
        ...                    "force file")
        >>> list(table.blocks())
        Traceback (most recent call last):
        ...
        ValueError: ...forces.csv:3: ...
        """
        for raw, first_line in self._raw_blocks():
            text = self._decode(raw, first_line)
            if "\n " in text or "\n\t" in text or text.startswith((" ", "\t")):  # a fast test for the rare case
                text = BLANK_LINE.sub("", text)  # numpy reads a line of spaces as an empty cell
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # a block of comments only: "input contained no data"
                    table = np.loadtxt(io.StringIO(text), delimiter=",", comments="#", usecols=self._index,
                                       ndmin=2, dtype=np.float64, quotechar='"')
            except ValueError as problem:
                self._explain(text, first_line, problem)
            block = Block({c.name: table[:, k] for k, c in enumerate(self.columns)}, text, first_line)
            for column in self.columns:
                bad = np.flatnonzero(column.outside(block.values[column.name]))
                if len(bad):
                    value = block.values[column.name][bad[0]]
                    if not math.isfinite(value):
                        problem = "is not a finite number"
                    elif value < 0 <= column.low:
                        problem = "must not be negative"
                    else:
                        problem = "is out of range"
                    self._fail(block.line_of(int(bad[0])),
                               f"{column.name} {problem} ({value:g}); it must be {column.describe()}")
            yield block

    def _explain(self, text: str, first_line: int, problem: ValueError):
        """Find the line numpy refused and say what is wrong with it."""
        for offset, line in enumerate(text.split("\n")):
            if not _is_data(line):
                continue
            number = first_line + offset
            cells = self._cells(line, number)
            if len(cells) <= max(self._index):
                self._fail(number, f"expected {self.header_width} values, found {len(cells)}")
            for column, index in zip(self.columns, self._index, strict=True):
                cell = cells[index].strip()
                if not cell:
                    self._fail(number, f"{column.name} is empty")
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        np.loadtxt([cell], dtype=np.float64, ndmin=1)
                except ValueError:
                    self._fail(number, f"{column.name} is not a number: {cell[:40]!r}")
        self._fail(first_line, f"cannot read the numbers ({str(problem).splitlines()[0]})")


def read_numeric_csv(path: str | Path, required: tuple[Column, ...], optional: tuple[Column, ...],
                     error: type[Exception], what: str, max_rows: int) -> dict[str, np.ndarray]:
    r"""A whole (small) numeric CSV as arrays; more than ``max_rows`` data rows is an error.

    Long files are streamed with :meth:`NumericCsv.blocks` instead.

    Parameters
    ----------
    path : str or pathlib.Path
        The file: a header line, then rows of numbers; ``#`` starts a comment.
    required, optional : tuple of Column
        The columns the file must have and those it may have, each with its range and unit.
    error : type
        The exception raised for a bad file (an :class:`~ultraglide.UltraglideError`).
    what : str
        What the file is, in words, for the messages.
    max_rows : int
        The most data rows accepted.

    Returns
    -------
    dict of str to numpy.ndarray
        One float64 array a column present.

    Raises
    ------
    error
        A value out of range, a cell that is not a number, a short row, a missing column, or too many rows, in
        one line naming the file and line.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide.render.physics.errors import ModelError
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "points.csv"
    >>> _ = path.write_text("amplitude_um_pp,relative_friction\n# a comment\n0,1\n2.5,0.4\n")
    >>> columns = (Column("amplitude_um_pp", 0.0, 50.0, "µm p-p"), Column("relative_friction", 0.0, 1.5))
    >>> read_numeric_csv(path, columns, (), ModelError, "measurement file", 100)
    {'amplitude_um_pp': array([0. , 2.5]), 'relative_friction': array([1. , 0.4])}
    >>> _ = path.write_text("amplitude_um_pp,relative_friction\n0,1\n60,0.4\n")
    >>> read_numeric_csv(path, columns, (), ModelError, "measurement file", 100)
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: .../points.csv:3: amplitude_um_pp is out of range (60); it must be ...
    """
    table = NumericCsv(path, required, optional, error, what)
    parts: dict[str, list[np.ndarray]] = {name: [] for name in table.names}
    count = 0
    for block in table.blocks():
        count += len(block)
        if count > max_rows:
            raise error(f"{path}: more than {max_rows} rows; a {what} holds at most {max_rows}")
        for name in table.names:
            parts[name].append(block.values[name])
    return {name: np.concatenate(chunks) if chunks else np.zeros(0) for name, chunks in parts.items()}
