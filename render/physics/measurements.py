"""Measured friction points from CSV: ``amplitude_um_pp,relative_friction[,force_n][,speed_mm_s][,participant]``.

Lines starting with ``#`` are comments. Amplitudes are peak-to-peak; convert zero-to-peak data
(as many published fits are) by doubling before saving. ``participant`` is a number naming whose
finger each point is (for cross-validation across people): an id as experiments write it (``P01``), kept as text;
a number (``7``, ``7.0``) is the same id however it is written (:func:`participant_id`). ``speed_mm_s`` is the
finger's sliding speed while the point was measured (mm/s), where it was known: points at several speeds let
``calibrate`` fit the reduction's speed law (:mod:`~ultraglide.render.physics.speed_fit`).

Measurement noise is accepted within a stated tolerance: a ratio down to -0.05 (a tribometer's
noise about a finger that glides almost freely) is clipped to 0 and counted, and ratios up to 1.2
(noise about rest) are kept as measured and counted. A file that does not describe friction
reduction is refused with the reason: at rest (amplitudes up to 0.5 µm p-p) the ratio must be
near 1 (it is friction over friction at rest), and at each force it must fall with amplitude.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from ultraglide.render.physics.csv_table import Column, read_numeric_csv
from ultraglide.render.physics.errors import ModelError

AMPLITUDE = Column("amplitude_um_pp", 0.0, 100.0, "µm p-p")  # plates reach a few µm; 100 is no plate
NOISE_BELOW_ZERO = 0.05  # ratios down to -0.05 are noise about a finger that glides almost freely: clipped to 0
RELATIVE_FRICTION = Column("relative_friction", -NOISE_BELOW_ZERO, 1.2)  # above 1: noise about rest
FORCE = Column("force_n", 0.0, 50.0, "N", low_open=True)
SPEED = Column("speed_mm_s", 0.0, 2000.0, "mm/s", low_open=True)  # a sliding finger; the speed law holds above 2000
PARTICIPANT = "participant"  # whose finger: a text column, read apart from the numbers
MAX_ID_CHARS = 64
ID_PUNCTUATION = "-_."
REQUIRED_COLUMNS = (AMPLITUDE.name, RELATIVE_FRICTION.name)
MAX_ROWS = 100_000  # measured tables hold tens to thousands of points
MIN_STEP_UM = 0.001  # distinct amplitudes at one force closer than a nanometre are one measurement, or noise
REST_UM_PP = 0.5  # "at rest" below this, for the check below (Monnoyer's fitted law, as we evaluate it: 0.98)
REST_TOLERANCE = 0.15  # at rest the ratio must be within this of 1
MIN_FALL = 0.05  # at each force the ratio must fall by at least this over the amplitudes measured


@dataclass(frozen=True)
class Measurements:
    """Measured relative friction against amplitude (µm p-p), with the normal force (N) and the sliding speed
    (mm/s) if known.

    Examples
    --------
    >>> import numpy as np
    >>> data = Measurements(np.array([0.0, 2.0, 4.0]), np.array([1.0, 0.6, 0.2]), np.full(3, 0.5), source="by hand")
    >>> len(data), data.subset(np.array([True, False, True])).relative_friction.tolist(), data.noise_words()
    (3, [1.0, 0.2], '')
    """

    amplitude_um_pp: np.ndarray
    relative_friction: np.ndarray
    force_n: np.ndarray | None
    source: str
    participant: np.ndarray | None = None
    clipped_below_zero: int = 0  # ratios read below 0 (within the noise tolerance) and set to 0
    above_one: int = 0  # ratios above 1 (noise about rest), kept as measured
    speed_mm_s: np.ndarray | None = None  # the finger's sliding speed at each point, mm/s

    def __len__(self) -> int:
        return len(self.amplitude_um_pp)

    def subset(self, pick: np.ndarray) -> Measurements:
        """The points where ``pick`` (a boolean mask or indices) selects.

        Parameters
        ----------
        pick : numpy.ndarray
            A boolean mask, or indices.

        Returns
        -------
        Measurements

        Examples
        --------
        >>> import numpy as np
        >>> data = Measurements(np.array([0.0, 2.0, 4.0]), np.array([1.0, 0.6, 0.2]), np.full(3, 0.5), source="by hand")
        >>> picked = data.subset(np.array([0, 2]))
        >>> picked.amplitude_um_pp.tolist(), picked.force_n.tolist(), picked.source
        ([0.0, 4.0], [0.5, 0.5], 'by hand')
        """
        def take(column):
            return None if column is None else column[pick]
        return Measurements(self.amplitude_um_pp[pick], self.relative_friction[pick], take(self.force_n),
                            self.source, take(self.participant), speed_mm_s=take(self.speed_mm_s))

    def conditions(self) -> list[tuple[str, np.ndarray]]:
        """The points measured under one condition (a force, a sliding speed, or both, as the data name them), each
        with its words: where the ratio must fall with amplitude, and amplitudes be distinct.

        Returns
        -------
        list of (str, numpy.ndarray)
            `` at 0.5 N`` / `` at 0.5 N and 100 mm/s`` / ``""`` (one condition), and a boolean mask.

        Examples
        --------
        >>> import numpy as np
        >>> data = Measurements(np.zeros(3), np.ones(3), np.array([0.5, 0.5, 0.9]), "m",
        ...                     speed_mm_s=np.array([25.0, 100.0, 25.0]))
        >>> for words, mask in data.conditions():
        ...     print(repr(words), mask.tolist())
        ' at 0.5 N and 25 mm/s' [True, False, False]
        ' at 0.5 N and 100 mm/s' [False, True, False]
        ' at 0.9 N and 25 mm/s' [False, False, True]
        """
        forces = self.force_n if self.force_n is not None else np.zeros(len(self))
        speeds = self.speed_mm_s if self.speed_mm_s is not None else np.zeros(len(self))
        found = []
        for force in np.unique(forces):
            for speed in np.unique(speeds[forces == force]):
                parts = ([] if self.force_n is None else [f"{force:g} N"]) + \
                    ([] if self.speed_mm_s is None else [f"{speed:g} mm/s"])
                found.append((f" at {' and '.join(parts)}" if parts else "", (forces == force) & (speeds == speed)))
        return found

    def noise_words(self) -> str:
        """What the reading did with noisy ratios, in words ("" when nothing).

        Returns
        -------
        str

        Examples
        --------
        >>> import numpy as np
        >>> data = Measurements(np.array([0.0, 2.0]), np.array([1.0, 0.5]), None, "bench", above_one=1)
        >>> data.noise_words()
        '1 ratio(s) above 1 (noise about rest) kept as measured'
        """
        parts = []
        if self.clipped_below_zero:
            parts.append(f"{self.clipped_below_zero} ratio(s) below 0 (down to -{NOISE_BELOW_ZERO:g}, measurement "
                         "noise) clipped to 0")
        if self.above_one:
            parts.append(f"{self.above_one} ratio(s) above 1 (noise about rest) kept as measured")
        return "; ".join(parts)


def check_describes_reduction(data: Measurements, where: str) -> None:
    """Refuse points that do not describe friction reduction, with the reason: far from 1 at rest
    (not friction over friction at rest), or not falling with amplitude at some force (and speed).

    Parameters
    ----------
    data : Measurements
        The points.
    where : str
        What to name in the refusal (the file).

    Raises
    ------
    ModelError
        Far from 1 at rest, or not falling with amplitude at some force, in one line.

    Examples
    --------
    >>> import numpy as np
    >>> halved = Measurements(np.array([0.0, 2.0]), np.array([0.5, 0.4]), None, "bench.csv")
    >>> check_describes_reduction(halved, "bench.csv")                 # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: bench.csv: at rest (...) relative_friction is 0.5, not about 1: ...
    """
    for at, pick in data.conditions():
        amplitude, ratio = data.amplitude_um_pp[pick], data.relative_friction[pick]
        rest = amplitude <= REST_UM_PP
        if rest.any() and np.mean(ratio[rest]) < 1.0 - REST_TOLERANCE:
            raise ModelError(f"{where}: at rest (amplitudes up to {REST_UM_PP:g} µm p-p){at} relative_friction is "
                             f"{np.mean(ratio[rest]):.3g}, not about 1: it must be friction over friction at rest "
                             "(mu/mu0); divide by the value at rest")
        order = np.argsort(amplitude, kind="stable")
        third = max(1, len(order) // 3)
        first, last = np.mean(ratio[order[:third]]), np.mean(ratio[order[-third:]])
        if first - last < MIN_FALL:
            raise ModelError(f"{where}: relative_friction{at} does not fall with amplitude ({first:.3g} at the "
                             f"smallest amplitudes, {last:.3g} at the largest): the points do not describe friction "
                             "reduction; measure up to amplitudes where the finger glides")


def read_measurements(path: str | Path) -> Measurements:
    """Read and validate a measurement CSV: relative friction against amplitude, maybe per force.

    Columns ``amplitude_um_pp,relative_friction[,force_n][,speed_mm_s][,participant]``. Ranges: amplitude_um_pp
    0..100, relative_friction in [-0.05, 1.2] (below 0: noise, clipped to 0 and counted), force_n in
    (0, 50], speed_mm_s in (0, 2000], at most 100 000 rows. There must be two different amplitudes or more, at one
    force and speed never closer than 0.001 µm, and the points must describe friction reduction
    (:func:`check_describes_reduction`): a flat table says nothing about how friction falls, so it can
    neither be inverted nor fitted.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    Measurements
        The points (amplitudes µm p-p, ratios, forces N) and what was clipped.

    Raises
    ------
    ModelError
        The line at fault and what is wrong with it.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "m.csv"
    >>> _ = path.write_text("amplitude_um_pp,relative_friction\\n0,1.0\\n1,0.8\\n2,0.5\\n3,0.3\\n")
    >>> data = read_measurements(path)
    >>> data.amplitude_um_pp.tolist(), data.relative_friction.tolist()
    ([0.0, 1.0, 2.0, 3.0], [1.0, 0.8, 0.5, 0.3])
    """
    columns = read_numeric_csv(path, (AMPLITUDE, RELATIVE_FRICTION), (FORCE, SPEED), ModelError,
                               "measurement file", MAX_ROWS)
    amplitude = columns["amplitude_um_pp"]
    ratio = columns["relative_friction"]
    below, above = int(np.count_nonzero(ratio < 0.0)), int(np.count_nonzero(ratio > 1.0))
    ratio = np.maximum(ratio, 0.0)
    force = columns.get("force_n")
    if len(amplitude) < 2:
        raise ModelError(f"{path}: at least two data rows are needed, found {len(amplitude)}")
    if len(np.unique(amplitude)) < 2:
        raise ModelError(f"{path}: every row has the same amplitude; two different amplitudes or more are needed")
    if not np.min(ratio) < 1.0:
        raise ModelError(f"{path}: relative_friction never falls below 1: a flat table cannot be inverted or "
                         "fitted; measure at amplitudes where the finger glides")
    data = Measurements(amplitude, ratio, force, str(path), _participants(path, len(amplitude)), below, above,
                        columns.get("speed_mm_s"))
    for at, pick in data.conditions():
        distinct = np.unique(amplitude[pick])
        steps = np.diff(distinct)
        if len(steps) and steps.min() < MIN_STEP_UM:
            k = int(np.argmin(steps))
            raise ModelError(f"{path}: amplitudes {distinct[k]:g} and {distinct[k + 1]:g} µm{at} differ by less than "
                             f"{MIN_STEP_UM:g} µm, below any vibrometer's resolution; merge them")
    check_describes_reduction(data, str(path))
    return data


def participant_id(text) -> str:
    """A participant's id as ``calibrate`` and the measurement files keep it: letters, digits and ``-_.``, at most
    64 characters (``P01``, ``s-12``); a number is the same id however written (``7``, ``7.0``, ``07`` are ``7``),
    so files and commands of the numeric ids before keep matching. ValueError (one line) for anything else.

    Parameters
    ----------
    text : str or number

    Returns
    -------
    str

    Raises
    ------
    ValueError
        Anything else, in one line.

    Examples
    --------
    >>> participant_id("P01"), participant_id(7.0), participant_id("07")
    ('P01', '7', '7')
    >>> participant_id("a b")                                          # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: a participant id is 1 to 64 letters, digits, '-', '_' or '.' (e.g. P01), got 'a b'
    """
    value = str(text).strip()
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if math.isfinite(number):
        return f"{number:g}" if abs(number) < 1e15 else value
    if not 0 < len(value) <= MAX_ID_CHARS or not all(c.isalnum() or c in ID_PUNCTUATION for c in value):
        raise ValueError(f"a participant id is 1 to {MAX_ID_CHARS} letters, digits, '-', '_' or '.' (e.g. P01), "
                         f"got {value!r}")
    return value


def _participants(path: str | Path, rows: int) -> np.ndarray | None:
    """The file's participant column as ids (:func:`participant_id`), row for row with the numbers read before it
    (the same data lines: not blank, not a comment); None without the column."""
    with open(path, encoding="utf-8-sig", newline="") as handle:
        lines = [(number, line.split("#", 1)[0]) for number, line in enumerate(handle, 1)
                 if line.strip() and not line.strip().startswith("#")]
    names = [name.strip() for name in next(csv.reader([lines[0][1]]))]
    if PARTICIPANT not in names:
        return None
    column = names.index(PARTICIPANT)
    ids = []
    for number, line in lines[1:]:
        cells = next(csv.reader([line]), [])
        try:
            ids.append(participant_id(cells[column] if column < len(cells) else ""))
        except ValueError as problem:
            raise ModelError(f"{path}:{number}: {problem}") from None
    if len(ids) != rows:  # the numeric reader and this one disagree on the rows: never silently misalign
        raise ModelError(f"{path}: the participant column has {len(ids)} values for {rows} rows")
    return np.array(ids, dtype=str)
