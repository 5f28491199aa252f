"""The finger's friction dynamics fitted from a calibration's recording: its steps' edges, in time.

An on-plate calibration (``ultraglide calibrate --device``) steps the plate's amplitude with a rest between
every two steps, and its force sensors sample the finger's friction at the device's sensor rate (1 kHz). Each
reduced step has two **edges**: the amplitude switched on (friction falls: the **onset**) and off (friction
comes back: the **recovery**). :class:`FrictionDynamics` models both as first-order lags; this module fits
their time constants to the edges' time courses.

What is measured is not the finger alone. Between the finger's friction and the numbers recorded lie

* the plate's own rise: the amplitude does not step, it rises over about a millisecond (the resonator, its
  amplitude loop). The recording's **measured amplitude** is used, not the plan's, and turned into the
  static ratio the fitted static model gives at each sample, so the rise is the plate's and not the finger's;
* the force sensors: a first-order low-pass (``bandwidth_hz``) and a pure delay (``delay_s``), stated by the
  device or the user (:class:`SensorLag`); the model of each edge passes through them, so their lag is not
  attributed to the finger;
* the device's averaging over each sensor period (a SENSORS sample is a period's mean): the model runs at
  ``UPSAMPLE`` times the sensor rate, each period's mean amplitude held over the period (which keeps each
  period's integral, so it adds no delay), and the result is read at each period's middle. (Interpolating the
  amplitude between the periods' middles instead was tried: 0.01 ms closer on a rising plate, 0.1 ms further
  on a hard step.)

An onset's window ends, and its recovery's edge begins, where the amplitude leaves its steady level (below
97 % of the step's median), not where it crosses zero: the plate's decay would otherwise put the start of a
recovery into the onset's window, modelled with the onset's time constant (that alone biased the onset by
half a millisecond on the simulated plate).

Every element of that chain is linear and time-invariant once the static ratio is computed, so the sensors'
filter and delay are applied once per edge and only the finger's lag is searched. For each edge and each
time constant on a grid (0 and ``GRID_POINTS`` values spaced evenly in log from 0.05 ms to 1 s) the edge's
modelled course y(t) is fitted to the measured mu(t) with a free level and a free height (mu ≈ m0 + m1 y: the
finger's friction at rest drifts, and the static model's level is not what is fitted here), and the residual
sum of squares kept. The time constant is the minimum of the summed curves over all edges of a kind,
refined by a parabola in log time; its uncertainty comes from resampling the **edges** (bootstrap: the
2.5th and 97.5th percentiles and the standard deviation of the resampled minima).

A time constant is **resolved** only when its bootstrap lower bound lies above what the samples and the
sensors can tell, :attr:`SensorLag.resolution_s`: one sensor period, or the sensors' own time constant where
that is longer. Below it the fit says the dynamics cannot be told from an instantaneous finger, and keeps the
published value (:data:`~ultraglide.render.physics.dynamics.ONSET_S`, ``RECOVERY_S``), saying so. A time
constant at the top of the grid or longer than a third of the edges' windows is not resolved either.

The recovery slows with the sliding speed v as (v_ref / v)^p. Its exponent p is fitted only when the
recovery edges were measured at speeds that span at least ``MIN_SPEED_SPAN`` (their slowest to fastest);
otherwise the assumed exponent is kept and the fit says so, and the recovery is stated at the speed it was
measured at (the reference speed becomes that speed). Without any known speed the recovery is reported but
not used (its speed unknown, the model could not place it).

:func:`compare_in_time` ranks static models against the same models with the fitted dynamics by held-out
error **in time**: folds of the reduced steps (each with both its edges) are held out in turn, the static
models and the dynamics fitted on the rest, and the ratio's time course predicted over each held-out step
(the measured amplitude through the model, through the finger's dynamics for a dynamic model, through the
sensors for both) and compared with the measured mu / mu0 (mu0: the rest runs beside the step).

The recording itself is a CSV (:class:`Recording`, :func:`read_recording`): ``t_s,amplitude_um_pp,
normal_force_n,lateral_force_n`` one row a sensor sample, under ``#`` lines that state the sensor rate, the
sensors' bandwidth and delay, the sliding speed and the participant.
"""

from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from scipy.signal import lfilter
from ultraglide.render.physics.dynamics import (
    ASSUMED_SPEED_EXPONENT,
    ONSET_RANGE_S,
    ONSET_S,
    RECOVERY_RANGE_S,
    RECOVERY_S,
    REFERENCE_SPEED_MM_S,
    REFERENCE_SPEED_RANGE_MM_S,
    SPEED_EXPONENT_RANGE,
    FrictionDynamics,
)
from ultraglide.render.physics.errors import ModelError

from ultraglide.inputs import decode_text, read_input, shown

if TYPE_CHECKING:
    from ultraglide.render.physics.measurements import Measurements
    from ultraglide.render.physics.model_base import FrictionModel

RECORDING_VERSION = 1
COLUMNS = ("t_s", "amplitude_um_pp", "normal_force_n", "lateral_force_n")
MAX_RECORDING_ROWS = 3_600_000  # an hour at 1 kHz
UPSAMPLE = 8  # the model of an edge runs at 8x the sensor rate
GRID_POINTS = 90  # time constants from GRID_LOW_S to GRID_HIGH_S, evenly in log, and 0
GRID_LOW_S = 5e-5
GRID_HIGH_S = 1.0
BOOTSTRAP = 400  # resamples of the edges
MIN_SPEED_SPAN = 1.5  # the recovery's speed exponent is fitted only over speeds spanning this ratio
MIN_FORCE_N = 0.05  # a lighter press is a lifted finger
MIN_MU = 0.02  # a rest whose mu is lower is no sliding finger's
ZERO_UM_PP = 0.05  # a plate below this amplitude is at rest
BEFORE_S = 0.015  # an edge's window starts this long before it
LONGEST_S = 0.3  # and lasts at most this long after it
MIN_AFTER_S = 0.04  # an edge with less after it is left out
MIN_CONTRAST = 0.03  # an edge whose static ratio changes less than this tells little: left out
STEADY_SHARE = 0.97  # a step's amplitude is steady down to this share of its median
REST_S = 0.04  # mu0 of a step: the last 40 ms of the rests beside it
EDGE_KINDS = ("onset", "recovery")


@dataclass(frozen=True)
class SensorLag:
    """The force sensors' lag and the device's sensor rate, as the fit models them.

    Parameters
    ----------
    rate_hz : float
        The sensor samples' rate, Hz (each sample a period's mean).
    bandwidth_hz : float
        The sensors' first-order bandwidth, Hz (0: none).
    delay_s : float
        Their pure delay, s.
    stated : str
        Where these come from, in words (e.g. "the simulated plate's sensors").

    Examples
    --------
    At 1 kHz with 300 Hz sensors the shortest time constant the fit can tell is a sample, 1 ms (the sensors'
    own, 1 / (2 pi 300 Hz) = 0.53 ms, is shorter); with 100 Hz sensors, 1.59 ms:

    >>> SensorLag(1000.0, 300.0, 0.001).resolution_s
    0.001
    >>> round(SensorLag(1000.0, 100.0, 0.001).resolution_s, 5)
    0.00159
    """

    rate_hz: float = 1000.0
    bandwidth_hz: float = 300.0
    delay_s: float = 0.001
    stated: str = "as given"

    def __post_init__(self) -> None:
        for name, value, low, high in (("sensor rate", self.rate_hz, 1.0, 48000.0),
                                       ("sensors' bandwidth", self.bandwidth_hz, 0.0, 20000.0),
                                       ("sensors' delay", self.delay_s, 0.0, 0.1)):
            if not (math.isfinite(value) and low <= value <= high):
                raise ModelError(f"the {name} must lie in {low:g}..{high:g}, got {value}")

    @property
    def resolution_s(self) -> float:
        """The shortest time constant the fit claims (s): one sample period or the sensors' time constant.

        Examples
        --------
        >>> SensorLag(500.0, 0.0, 0.0).resolution_s                  # a sample at 500 Hz, no filter
        0.002
        """
        own = 1.0 / (2.0 * math.pi * self.bandwidth_hz) if self.bandwidth_hz > 0 else 0.0
        return max(1.0 / self.rate_hz, own)

    def words(self) -> str:
        """The sensors in words: bandwidth, delay, rate and where they come from.

        Examples
        --------
        >>> SensorLag(1000.0, 300.0, 0.001, "as given").words()
        '300 Hz, 1 ms late, 1000 samples/s (as given)'
        """
        band = f"{self.bandwidth_hz:g} Hz" if self.bandwidth_hz else "unfiltered"
        return f"{band}, {1000 * self.delay_s:g} ms late, {self.rate_hz:g} samples/s ({self.stated})"


@dataclass(frozen=True)
class Recording:
    """A calibration's sensor samples: times (s from the first), measured amplitude (µm p-p), normal and lateral
    force (N), with the sensors' lag, the sliding speed (mm/s, NaN: unknown) and whose finger.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(4) / 1000.0
    >>> recording = Recording(t, np.array([0.0, 0.0, 2.0, 2.0]), np.full(4, 0.5), np.array([0.5, 0.5, 0.3, 0.3]),
    ...                       SensorLag(), 100.0, "P01", "by hand")
    >>> text = recording.text()
    >>> text.splitlines()[:2]
    ['# ultraglide_recording = 1', '# sensor_rate_hz = 1000']
    >>> back = recording_from_text(text, "by hand")
    >>> back.speed_mm_s, back.participant, back.lateral_force_n.tolist()
    (100.0, 'P01', [0.5, 0.5, 0.3, 0.3])
    """

    t_s: np.ndarray
    amplitude_um_pp: np.ndarray
    normal_force_n: np.ndarray
    lateral_force_n: np.ndarray
    lag: SensorLag
    speed_mm_s: float = math.nan
    participant: str | None = None
    source: str = "a recording"

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def sample_numbers(self) -> np.ndarray:
        """Each sample's number from the first (gaps where samples were lost).

        Examples
        --------
        >>> recording = Recording(np.array([0.0, 0.001, 0.003]), np.zeros(3), np.full(3, 0.5), np.full(3, 0.4),
        ...                       SensorLag())
        >>> recording.sample_numbers.tolist()                          # the third sample's predecessor was lost
        [0, 1, 3]
        """
        return np.rint(self.t_s * self.lag.rate_hz).astype(np.int64)

    def text(self) -> str:
        """The recording as its CSV file's text (see :func:`read_recording`).

        Examples
        --------
        >>> text = example_recording(steps=1).text()
        >>> text.splitlines()[7], text.splitlines()[8]
        ('t_s,amplitude_um_pp,normal_force_n,lateral_force_n', '0.000000,0.00000,0.500000,0.400000')
        """
        return "\n".join(self._header()) + "\n" + "".join(f"{row}\n" for row in self._rows())

    def write(self, path: str | Path) -> None:
        """Write the recording's CSV to ``path`` (a file of ours: give an atomic write's temporary), row by row.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> recording = example_recording(steps=1)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "rec.csv"
        >>> recording.write(path)
        >>> path.read_text() == recording.text(), len(read_recording(path))
        (True, 600)
        """
        with open(path, "w", encoding="utf-8") as handle:
            handle.write("\n".join(self._header()) + "\n")
            for row in self._rows():
                handle.write(row + "\n")

    def _rows(self):
        table = np.column_stack((self.t_s, self.amplitude_um_pp, self.normal_force_n, self.lateral_force_n))
        for start in range(0, len(table), 10_000):  # in chunks: an hour's samples never held as text at once
            yield from (f"{t:.6f},{a:.5f},{n:.6f},{lat:.6f}" for t, a, n, lat in table[start:start + 10_000])

    def _header(self) -> list[str]:
        speed = "unknown" if math.isnan(self.speed_mm_s) else f"{self.speed_mm_s:g}"
        lines = [f"# ultraglide_recording = {RECORDING_VERSION}", f"# sensor_rate_hz = {self.lag.rate_hz:g}",
                 f"# sensor_bandwidth_hz = {self.lag.bandwidth_hz:g}", f"# sensor_delay_s = {self.lag.delay_s:g}",
                 f"# sensors = {self.lag.stated}", f"# sliding_speed_mm_s = {speed}"]
        if self.participant is not None:
            lines.append(f"# participant = {self.participant}")
        lines.append(",".join(COLUMNS))
        return lines


def read_recording(path: str | Path) -> Recording:
    """A calibration's recording from its CSV (``CAL-recording.csv``, written beside ``CAL.csv``).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    Recording

    Raises
    ------
    ModelError
        What is wrong with the file, in one line (its line number where a row is wrong).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "rec.csv"
    >>> _ = path.write_text("# ultraglide_recording = 1\\n# sensor_rate_hz = 1000\\nt_s,amplitude_um_pp\\n")
    >>> read_recording(path)                                         # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: ...: the header must be t_s,amplitude_um_pp,normal_force_n,...
    """
    data = read_input(path, "recording", ModelError)
    return recording_from_text(decode_text(data, str(path), "recording (CSV)", ModelError), str(path))


def is_recording(path: str | Path) -> bool:
    """Whether a file starts as a calibration's recording does (its first line ``# ultraglide_recording``).

    Parameters
    ----------
    path : str or pathlib.Path
        The file (one that cannot be read is not a recording).

    Returns
    -------
    bool

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "rec.csv"
    >>> _ = path.write_text(example_recording(steps=1).text())
    >>> is_recording(path), is_recording(path.with_name("missing.csv"))
    (True, False)
    """
    try:  # only a regular file is looked into: a named pipe would wait for a writer (the reader refuses it)
        if not stat.S_ISREG(os.stat(path).st_mode):
            return False
        with open(path, "rb") as handle:
            return handle.read(40).startswith(b"# ultraglide_recording")
    except OSError:
        return False


def recording_from_text(text: str, where: str) -> Recording:
    """The typed reading of a recording's text (see :func:`read_recording`).

    Parameters
    ----------
    text : str
        The file's text.
    where : str
        What to name in a refusal (the file).

    Returns
    -------
    Recording

    Raises
    ------
    ModelError
        Not a recording of this version, a missing or out-of-range ``#`` line, a bad row (by its line number),
        times not increasing.

    Examples
    --------
    >>> recording_from_text("t_s,amplitude_um_pp,normal_force_n,lateral_force_n\\n", "rec.csv")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: rec.csv: not an ultraglide recording of version 1 ...
    """
    lines = text.splitlines()
    meta, body_start = {}, None
    for number, line in enumerate(lines):
        if line.startswith("#"):
            key, equals, value = line[1:].partition("=")
            if equals:
                meta[key.strip()] = value.strip()
            continue
        body_start = number
        break
    if meta.get("ultraglide_recording") != str(RECORDING_VERSION):
        raise ModelError(f"{where}: not an ultraglide recording of version {RECORDING_VERSION} (an on-plate "
                         "calibration writes one beside its CAL.csv)")
    if body_start is None or [c.strip() for c in lines[body_start].split(",")] != list(COLUMNS):
        raise ModelError(f"{where}: the header must be {','.join(COLUMNS)}")
    rows = lines[body_start + 1:]
    if len(rows) > MAX_RECORDING_ROWS:
        raise ModelError(f"{where}: more than {MAX_RECORDING_ROWS} samples; a calibration records far fewer")

    def number(key, low, high, default=None):
        text = meta.get(key)
        if text is None:
            if default is not None:
                return default
            raise ModelError(f"{where}: the line '# {key} = ...' is missing")
        if text == "unknown" and key == "sliding_speed_mm_s":
            return math.nan
        try:
            value = float(text)
        except ValueError:
            raise ModelError(f"{where}: {key} must be a number, got {shown(text[:40])}") from None
        if not (math.isfinite(value) and low <= value <= high):
            raise ModelError(f"{where}: {key} must lie in {low:g}..{high:g}, got {value:g}")
        return value

    lag = SensorLag(number("sensor_rate_hz", 1.0, 48000.0), number("sensor_bandwidth_hz", 0.0, 20000.0),
                    number("sensor_delay_s", 0.0, 0.1), meta.get("sensors", "as the recording states")[:200])
    speed = number("sliding_speed_mm_s", 0.0, 2000.0)
    try:  # the whole table at once; row by row only to name a bad row
        table = np.loadtxt(rows, delimiter=",", ndmin=2) if rows else np.zeros((0, 4))
        if table.shape[1] != 4:
            raise ValueError
    except ValueError:
        for k, row in enumerate(rows):
            parts = row.split(",")
            try:
                if len(parts) != 4:
                    raise ValueError
                [float(part) for part in parts]
            except ValueError:
                raise ModelError(f"{where}, line {body_start + k + 2}: four numbers expected, got "
                                 f"{shown(row[:60])}") from None
        raise ModelError(f"{where}: four numbers a row expected") from None
    t, a, normal, lateral = table.T
    if len(t) and (not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0) or t[0] < 0):
        raise ModelError(f"{where}: t_s must be finite, from 0 s, and strictly increasing")
    if np.any(np.abs(table[:, 1:][np.isfinite(table[:, 1:])]) > 1000.0):
        raise ModelError(f"{where}: an amplitude or force beyond 1000 (µm p-p, N): not a plate's sensors")
    participant = meta.get("participant")
    return Recording(t, a, normal, lateral, lag, speed, participant[:64] if participant else None, where)


@dataclass(frozen=True)
class Edge:
    """One edge of a reduced step: its kind (``onset``, ``recovery``), its window's samples (``first`` to ``stop``
    in the recording, the edge at ``at``), the press (N), the sliding speed (mm/s, NaN: unknown), the reduced
    step it belongs to (``step``) and that step's friction at rest (``mu0``).

    Examples
    --------
    The example recording's first step switches on at 250 ms and off at 350 ms; each window starts 15 ms before:

    >>> step = find_steps(example_recording())[0]
    >>> (step.onset.first, step.onset.at, step.onset.stop), (step.recovery.first, step.recovery.at)
    ((235, 250, 350), (335, 350))
    """

    kind: str
    first: int
    at: int
    stop: int
    force_n: float
    speed_mm_s: float
    step: int
    mu0: float


@dataclass(frozen=True)
class ReducedStep:
    """A reduced step with its two edges: its steady part's mean amplitude (µm p-p), force (N) and mu, and mu0.

    Examples
    --------
    >>> step = find_steps(example_recording())[0]
    >>> round(step.amplitude_um_pp, 3), round(step.force_n, 3), round(step.mu0, 3)
    (1.0, 0.5, 0.8)
    """

    number: int
    onset: Edge
    recovery: Edge
    amplitude_um_pp: float
    force_n: float
    mu: float
    mu0: float


def find_steps(recording: Recording, settle_s: float = 0.03) -> list[ReducedStep]:
    """The reduced steps of a recording with both edges whole: a rest, a step, a rest, the finger sliding (normal
    force at least 0.05 N, mu at rest at least 0.02) through every sample, no sample lost.

    Parameters
    ----------
    recording : Recording
        The samples.
    settle_s : float
        Of a step's steady part, the first ``settle_s`` after its onset are left out of its level (s).

    Returns
    -------
    list of ReducedStep
        In time order.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(600) / 1000.0
    >>> a = np.where((t >= 0.2) & (t < 0.4), 3.0, 0.0)
    >>> mu = np.where(a > 0, 0.4, 0.8)
    >>> recording = Recording(t, a, np.full(600, 0.5), 0.5 * mu, SensorLag(), 100.0)
    >>> [(s.onset.at, s.recovery.at, round(s.mu / s.mu0, 3)) for s in find_steps(recording)]
    [(200, 400, 0.5)]
    """
    rate = recording.lag.rate_hz
    numbers = recording.sample_numbers
    a, normal, lateral = recording.amplitude_um_pp, recording.normal_force_n, recording.lateral_force_n
    with np.errstate(invalid="ignore", divide="ignore"):
        mu = lateral / normal
    valid = np.isfinite(a) & np.isfinite(normal) & np.isfinite(lateral) & (normal >= MIN_FORCE_N)
    on = a >= ZERO_UM_PP
    breaks = np.flatnonzero((np.diff(numbers) != 1) | ~valid[1:] | ~valid[:-1]) + 1  # runs split where data fail
    changes = np.flatnonzero(on[1:] != on[:-1]) + 1
    bounds = np.unique(np.concatenate(([0], changes, breaks, [len(a)])))
    runs = [(int(s), int(e)) for s, e in zip(bounds[:-1], bounds[1:], strict=True) if valid[s]]
    before, rest_n = int(round(BEFORE_S * rate)), max(int(round(REST_S * rate)), 1)
    longest, min_after, settle = int(round(LONGEST_S * rate)), int(round(MIN_AFTER_S * rate)), int(settle_s * rate)
    steps = []
    for k in range(1, len(runs) - 1):
        (r0, r1), (s0, s1), (q0, q1) = runs[k - 1], runs[k], runs[k + 1]
        if not (on[s0] and not on[r0] and not on[q0] and r1 == s0 and s1 == q0):
            continue
        if r1 - r0 < max(before, rest_n) or s1 - s0 < max(min_after, settle + 10) or q1 - q0 < min_after:
            continue
        rest_before, rest_after = mu[r1 - rest_n:r1].mean(), mu[max(q0, q1 - rest_n):q1].mean()
        if min(rest_before, rest_after) < MIN_MU:
            continue
        # the plate starts to fall before it crosses ZERO_UM_PP: the onset's window ends, and the recovery's edge
        # is, where it leaves its steady level (an onset modelled into the recovery's start would be slowed by it)
        steady = np.flatnonzero(a[s0:s1] >= STEADY_SHARE * np.median(a[s0:s1]))
        fall = s0 + int(steady[-1]) + 1
        if fall - s0 < max(min_after, settle + 10) or fall - before < s0:
            continue
        force = float(normal[r1 - before:min(q1, q0 + longest)].mean())
        mu0 = 0.5 * (rest_before + rest_after)
        number = len(steps)
        speed = recording.speed_mm_s
        onset = Edge("onset", s0 - before, s0, min(fall, s0 + longest), force, speed, number, mu0)
        recovery = Edge("recovery", fall - before, fall, min(q1, fall + longest), force, speed, number, mu0)
        steps.append(ReducedStep(number, onset, recovery, float(a[s0 + settle:fall].mean()), force,
                                 float(mu[s0 + settle:fall].mean()), float(mu0)))
    return steps


def example_recording(onset_s: float = 0.005, recovery_s: float = 0.030, steps: int = 6) -> Recording:
    """A small synthetic recording for examples: ``steps`` reduced steps of 100 ms (1-4 µm p-p) between rests of
    250 ms, at 0.5 N and 100 mm/s, the finger's ratio (the exponential law) through :class:`FrictionDynamics` at
    8 kHz (``onset_s``, ``recovery_s`` at 100 mm/s), read as 1 ms means by sensors without lag (mu0 0.8).

    Parameters
    ----------
    onset_s, recovery_s : float
        The finger's time constants (s); both 0: an instantaneous finger.
    steps : int
        How many reduced steps.

    Returns
    -------
    Recording

    Examples
    --------
    >>> recording = example_recording()
    >>> len(recording), recording.lag.words()
    (2350, 'unfiltered, 0 ms late, 1000 samples/s (none: an example)')
    """
    from ultraglide.render.physics.empirical_models import ExponentialModel

    up, ms = 8, 250 + 350 * steps
    t = np.arange(ms * up) / (1000.0 * up)
    amplitude = np.zeros_like(t)
    for k in range(steps):
        amplitude[(t >= 0.25 + 0.35 * k) & (t < 0.35 + 0.35 * k)] = 1.0 + 3.0 * k / max(steps - 1, 1)
    static = ExponentialModel().relative_friction(amplitude, 0.5)
    felt = static if onset_s == recovery_s == 0 else \
        FrictionDynamics(onset_s, recovery_s, 100.0, ASSUMED_SPEED_EXPONENT).respond(static, 1000.0 * up, 100.0)
    mu = 0.8 * felt.reshape(-1, up).mean(axis=1)
    return Recording(np.arange(ms) / 1000.0, amplitude.reshape(-1, up).mean(axis=1), np.full(ms, 0.5), 0.5 * mu,
                     SensorLag(1000.0, 0.0, 0.0, "none: an example"), 100.0, "P01", "an example")


def _grid() -> np.ndarray:
    return np.concatenate(([0.0], np.geomspace(GRID_LOW_S, GRID_HIGH_S, GRID_POINTS)))


def _held(values: np.ndarray, up: int) -> np.ndarray:
    return np.repeat(values, up)


def _sensors(x: np.ndarray, lag: SensorLag, rate_hz: float) -> np.ndarray:
    """The sensors' low-pass then delay on a signal at ``rate_hz``, settled on its first value before it."""
    y = x
    if lag.bandwidth_hz > 0:
        alpha = math.exp(-2.0 * math.pi * lag.bandwidth_hz / rate_hz)
        y, _ = lfilter([1.0 - alpha], [1.0, -alpha], x, zi=[alpha * x[0]])
    shift = int(round(lag.delay_s * rate_hz))
    if shift:
        y = np.concatenate((np.full(min(shift, len(y)), y[0]), y[:max(len(y) - shift, 0)]))
    return y


def _lag(x: np.ndarray, tau_s: float, rate_hz: float) -> np.ndarray:
    """A first-order lag with time constant ``tau_s`` (0: none), each value held a period (exact for steps)."""
    if tau_s <= 0:
        return x
    keep = math.exp(-1.0 / (tau_s * rate_hz))
    y, _ = lfilter([1.0 - keep], [1.0, -keep], x, zi=[keep * x[0]])
    return y


@njit(cache=True, nogil=True)
def _lag_courses(x, keeps, up, out):
    """out[k, i]: ``x`` through a first-order lag keeping ``keeps[k]`` a sample (settled on x[0]), read at the
    middle of each period of ``up`` samples."""
    for k in range(keeps.shape[0]):
        keep = keeps[k]
        y = x[0]
        for j in range(x.shape[0]):
            y = keep * y + (1.0 - keep) * x[j]
            if j % up == up // 2 - 1:
                out[k, j // up] = y


def _middles(up_signal: np.ndarray, up: int) -> np.ndarray:
    """Each sensor period's middle of a signal at ``up`` times the sensor rate (the value after its half)."""
    return up_signal[up // 2 - 1::up]


def edge_course(static_ratio: np.ndarray, tau_s: float, lag: SensorLag, up: int = UPSAMPLE) -> np.ndarray:
    """What the sensors read of an edge: the static ratio (one a sensor sample, each a period's mean) through a
    first-order lag of ``tau_s`` (s) and the sensors (:class:`SensorLag`), read at each period's middle.

    Parameters
    ----------
    static_ratio : array of float
        The static model's ratio at the measured amplitude, one a sensor sample.
    tau_s : float
        The finger's time constant over the edge (s; 0: instantaneous).
    lag : SensorLag
        The sensors and the sensor rate.
    up : int
        The model's oversampling.

    Returns
    -------
    numpy.ndarray
        The modelled reading, one a sensor sample, settled before the first.

    Examples
    --------
    A step from 1 to 0 at sample 10, read at 1 kHz by sensors 1 ms late and without filter, through a 5 ms lag:
    at the middle of sample 10 + 1 + k the ratio has fallen to exp(-(k + 0.5) / 5):

    >>> import numpy as np
    >>> course = edge_course(np.r_[np.ones(10), np.zeros(30)], 0.005, SensorLag(1000.0, 0.0, 0.001))
    >>> bool(np.allclose(course[11:14], np.exp(-(np.arange(3) + 0.5) / 5.0), atol=1e-12))
    True
    >>> float(course[10])
    1.0
    """
    rate = lag.rate_hz * up
    held = _held(np.asarray(static_ratio, dtype=float), up)
    return _middles(_lag(_sensors(held, lag, rate), tau_s, rate), up)


def _static_up(amplitude: np.ndarray, force_n: float, model: FrictionModel, up: int = UPSAMPLE) -> np.ndarray:
    """The static ratio at ``up`` times the sensor rate: each period's mean amplitude held over the period (which
    keeps each period's integral, so it adds no delay), through the static model at ``force_n``."""
    a = _held(np.asarray(amplitude, dtype=float), up)
    return np.asarray(model.relative_friction(a, force_n), dtype=float)


def _edge_curve(mu: np.ndarray, static: np.ndarray, lag: SensorLag, grid: np.ndarray) -> tuple[np.ndarray, float]:
    """The residual sum of squares of mu ≈ m0 + m1 y_tau over the grid, and the static ratio's change (the static
    ratio given at ``UPSAMPLE`` times the sensor rate)."""
    rate = lag.rate_hz * UPSAMPLE
    first, last = static[: max(len(static) // 20, 3)].mean(), static[-max(len(static) // 10, 5):].mean()
    contrast = float(last - first)
    unit = (static - first) / contrast if contrast else np.zeros_like(static)
    sensed = _sensors(unit, lag, rate)
    keeps = np.array([math.exp(-1.0 / (tau * rate)) if tau > 0 else 0.0 for tau in grid])
    courses = np.empty((len(grid), len(mu)))
    _lag_courses(sensed, keeps, UPSAMPLE, courses)  # y_tau read at each period's middle, every tau at once
    centred = mu - mu.mean()
    courses -= courses.mean(axis=1, keepdims=True)
    variance = np.einsum("ij,ij->i", courses, courses)
    projection = courses @ centred
    explained = np.divide(projection ** 2, variance, out=np.zeros(len(grid)), where=variance > 0)
    curve = float(centred @ centred) - explained
    return curve, contrast


def _minimum(curve: np.ndarray, grid: np.ndarray) -> float:
    """The grid's minimum of a curve, refined by a parabola through it and its neighbours in log time."""
    k = int(np.argmin(curve))
    if k == 0:
        return 0.0
    if k == 1 or k == len(grid) - 1:
        return float(grid[k])
    x = np.log(grid[k - 1:k + 2])
    y = curve[k - 1:k + 2]
    denominator = (y[0] - 2 * y[1] + y[2])
    if denominator <= 0:
        return float(grid[k])
    shift = 0.5 * (y[0] - y[2]) / denominator  # in grid steps
    return float(np.exp(x[1] + shift * (x[2] - x[1])))


@dataclass(frozen=True)
class TimeConstant:
    """A fitted time constant (s) of one kind of edge: the value, its bootstrap 95 % interval and standard
    deviation over ``edges`` edges, whether the data resolve it, and the value kept (``used_s``) with why.

    Examples
    --------
    >>> recording = example_recording()
    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> onset = fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20).onset
    >>> onset.kind, onset.edges, onset.resolved, abs(onset.used_s - 0.005) < 1e-4       # 5 ms within 0.1 ms
    ('onset', 6, True, True)
    """

    kind: str
    fitted_s: float
    low_s: float
    high_s: float
    stderr_s: float
    edges: int
    resolved: bool
    used_s: float
    note: str
    speed_mm_s: float = math.nan

    def words(self) -> str:
        """The fit in words (the note): the value, its interval, and whether it is used.

        Examples
        --------
        >>> from ultraglide.render.physics.empirical_models import ExponentialModel
        >>> recording = example_recording()
        >>> fit = fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20)
        >>> fit.onset.words().endswith("fitted on the plate")
        True
        """
        return self.note


@dataclass(frozen=True)
class DynamicsFit:
    """The dynamics fitted from a recording: the onset's and the recovery's :class:`TimeConstant`, the speed
    exponent with its note, the sensors assumed, and the :class:`FrictionDynamics` to use (None: the data resolve
    neither time constant: the finger cannot be told from an instantaneous one).

    Examples
    --------
    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> recording = example_recording(onset_s=0.0, recovery_s=0.0)   # an instantaneous finger
    >>> fit = fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20)
    >>> fit.fitted, fit.onset.resolved, fit.recovery.resolved
    (False, False, False)
    """

    onset: TimeConstant
    recovery: TimeConstant
    speed_exponent: float
    speed_exponent_note: str
    reference_speed_mm_s: float
    lag: SensorLag
    dynamics: FrictionDynamics | None
    notes: list[str] = field(default_factory=list)

    @property
    def fitted(self) -> bool:
        """Whether any time constant was resolved (the calibration then has dynamics).

        Examples
        --------
        >>> from ultraglide.render.physics.empirical_models import ExponentialModel
        >>> recording = example_recording()
        >>> fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20).fitted
        True
        """
        return self.dynamics is not None

    def words(self) -> list[str]:
        """Lines for people: each time constant, the speed law, the sensors, and what is used.

        Examples
        --------
        >>> from ultraglide.render.physics.empirical_models import ExponentialModel
        >>> recording = example_recording(onset_s=0.0, recovery_s=0.0)
        >>> lines = fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20).words()
        >>> lines[-1].startswith("the finger's friction cannot be told apart from instantaneous")
        True
        """
        lines = [self.onset.note, self.recovery.note, self.speed_exponent_note,
                 f"force sensors modelled: {self.lag.words()}"]
        if self.dynamics is None:
            lines.append("the finger's friction cannot be told apart from instantaneous at this sampling: no "
                         "dynamics written (dynamic:CAL.toml would add the published ones)")
        return lines + self.notes

    def summary(self) -> dict:
        """Strict-JSON-ready: the time constants (s), intervals, edges, resolved, the exponent and notes.

        Examples
        --------
        >>> import json
        >>> from ultraglide.render.physics.empirical_models import ExponentialModel
        >>> recording = example_recording()
        >>> summary = fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=20).summary()
        >>> summary["written"], summary["onset"]["edges"], json.loads(json.dumps(summary, allow_nan=False)) == summary
        (True, 6, True)
        """
        def one(tc: TimeConstant) -> dict:
            return {"fitted_s": _finite(tc.fitted_s), "low_s": _finite(tc.low_s), "high_s": _finite(tc.high_s),
                    "stderr_s": _finite(tc.stderr_s), "edges": tc.edges, "resolved": tc.resolved,
                    "used_s": tc.used_s, "speed_mm_s": _finite(tc.speed_mm_s), "note": tc.note}
        return {"onset": one(self.onset), "recovery": one(self.recovery), "speed_exponent": self.speed_exponent,
                "speed_exponent_note": self.speed_exponent_note,
                "reference_speed_mm_s": self.reference_speed_mm_s, "sensors": self.lag.words(),
                "written": self.dynamics is not None, "resolution_s": self.lag.resolution_s, "notes": list(self.notes)}


def _finite(value: float):
    return None if value is None or not math.isfinite(value) else float(value)


def _edge_data(recording: Recording, edge: Edge, model: FrictionModel) -> tuple[np.ndarray, np.ndarray]:
    window = slice(edge.first, edge.stop)
    mu = recording.lateral_force_n[window] / recording.normal_force_n[window]
    return mu, _static_up(recording.amplitude_um_pp[window], edge.force_n, model)


def edge_curves(recording: Recording, edges: list[Edge],
                model: FrictionModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each edge's residual sum of squares over the grid of time constants.

    Parameters
    ----------
    recording : Recording
        The samples and the sensors.
    edges : list of Edge
        The edges (:func:`find_steps`).
    model : FrictionModel
        The static model whose ratio at the measured amplitude shapes the edges (its level does not matter).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The curves (edges x grid), the grid (s; 0, then 0.05 ms to 1 s evenly in log), and each edge's change
        of static ratio.

    Examples
    --------
    The example's onsets (5 ms) have their least residual on the grid next to 5 ms:

    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> recording = example_recording()
    >>> curves, grid, contrasts = edge_curves(recording, [s.onset for s in find_steps(recording)], ExponentialModel())
    >>> curves.shape, bool(np.all(contrasts < 0))
    ((6, 91), True)
    >>> bool(np.all(np.abs(np.log(grid[curves.argmin(axis=1)] / 0.005)) < 0.06))
    True
    """
    grid = _grid()
    curves, contrasts = [], []
    for edge in edges:
        mu, static = _edge_data(recording, edge, model)
        curve, contrast = _edge_curve(mu, static, recording.lag, grid)
        curves.append(curve)
        contrasts.append(contrast)
    return (np.array(curves).reshape(len(edges), len(grid)), grid, np.array(contrasts))


def fit_time_constant(curves: np.ndarray, grid: np.ndarray, kind: str, lag: SensorLag, window_s: float,
                      speed_mm_s: float = math.nan, samples: int = BOOTSTRAP, seed: int = 0) -> TimeConstant:
    """One kind's time constant from its edges' residual curves (edges x grid), with its bootstrap over edges.

    Parameters
    ----------
    curves : numpy.ndarray
        One residual curve an edge over ``grid`` (s).
    grid : numpy.ndarray
        The time constants tried (s), 0 first.
    kind : str
        ``onset`` or ``recovery``.
    lag : SensorLag
        The sensors (their resolution bounds what is claimed).
    window_s : float
        The edges' shortest window after the edge (s): a time constant longer than a third of it is not resolved.
    speed_mm_s : float
        The sliding speed of these edges (mm/s; NaN: unknown), for the words.
    samples : int
        Bootstrap resamples of the edges.
    seed : int
        The bootstrap's seed.

    Returns
    -------
    TimeConstant

    Examples
    --------
    Three edges whose curves all have their minimum at the grid's 5 ms: fitted 5 ms, no spread:

    >>> import numpy as np
    >>> grid = np.array([0.0, 0.001, 0.0025, 0.005, 0.01, 0.02])
    >>> curves = np.tile((np.log(np.maximum(grid, 1e-4) / 0.005)) ** 2, (3, 1))
    >>> tc = fit_time_constant(curves, grid, "onset", SensorLag(), 0.2)
    >>> round(tc.fitted_s, 6), tc.resolved, round(tc.stderr_s, 9)
    (0.005, True, 0.0)
    """
    published = ONSET_S if kind == "onset" else RECOVERY_S
    allowed = ONSET_RANGE_S if kind == "onset" else RECOVERY_RANGE_S
    name = "onset (friction falling)" if kind == "onset" else "recovery (friction returning)"
    at = "" if math.isnan(speed_mm_s) else f" at {speed_mm_s:g} mm/s"
    n = len(curves)
    if n == 0:
        return TimeConstant(kind, math.nan, math.nan, math.nan, math.nan, 0, False, published,
                            f"{name}: no edge measured whole; the published {1000 * published:g} ms kept", speed_mm_s)
    fitted = _minimum(curves.sum(axis=0), grid)
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(n, np.full(n, 1.0 / n), size=samples) if samples else np.ones((0, n))
    boot = np.array([_minimum(c, grid) for c in counts @ curves]) if samples else np.array([fitted])
    low, high = (float(v) for v in np.percentile(boot, [2.5, 97.5]))
    stderr = float(np.std(boot))
    floor = lag.resolution_s
    ceiling = min(window_s / 3.0, float(grid[-2]))
    interval = f"95 % {1000 * low:.3g}-{1000 * high:.3g} ms over {n} edges"
    if low <= floor:
        note = (f"{name}{at}: {1000 * fitted:.3g} ms ({interval}): cannot be told from instantaneous, shorter than "
                f"the {1000 * floor:.3g} ms the samples and the sensors can tell; the published {1000 * published:g} "
                "ms kept")
        resolved = False
    elif high >= ceiling:
        note = (f"{name}{at}: {1000 * fitted:.3g} ms ({interval}): longer than the steps can show (a third of "
                f"{1000 * window_s:.0f} ms); the published {1000 * published:g} ms kept")
        resolved = False
    elif not allowed[0] <= fitted <= allowed[1]:
        note = (f"{name}{at}: {1000 * fitted:.3g} ms ({interval}) lies outside the model's range "
                f"{1000 * allowed[0]:g}-{1000 * allowed[1]:g} ms; the published {1000 * published:g} ms kept")
        resolved = False
    else:
        note = f"{name}{at}: {1000 * fitted:.3g} ± {1000 * stderr:.2g} ms ({interval}), fitted on the plate"
        resolved = True
    return TimeConstant(kind, fitted, low, high, stderr, n, resolved, fitted if resolved else published, note,
                        speed_mm_s)


def _speed_law(curves: np.ndarray, grid: np.ndarray, speeds: np.ndarray) -> tuple[float, float, float]:
    """(exponent, recovery at the reference speed s, reference speed mm/s) minimising the summed residuals with
    each edge's time constant tau_ref (v_ref / v)^p, the reference the speeds' geometric mean."""
    reference = float(np.exp(np.mean(np.log(speeds))))
    log_grid = np.log(grid[1:])
    best = (math.inf, ASSUMED_SPEED_EXPONENT, math.nan)
    shifts = np.log(reference / speeds)
    for p in np.arange(SPEED_EXPONENT_RANGE[0], SPEED_EXPONENT_RANGE[1] + 1e-9, 0.025):
        total = np.zeros(len(log_grid))
        for shift, curve in zip(shifts, curves, strict=True):  # each edge's residual at tau_ref (v_ref / v)^p
            total += np.interp(log_grid + p * shift, log_grid, curve[1:])
        k = int(np.argmin(total))
        if total[k] < best[0]:
            best = (float(total[k]), float(p), float(np.exp(log_grid[k])))
    return best[1], best[2], reference


def fit_dynamics(recording: Recording, steps: list[ReducedStep], model: FrictionModel, samples: int = BOOTSTRAP,
                 seed: int = 0) -> DynamicsFit:
    """The onset's and the recovery's time constants from the recording's reduced steps (see the module).

    Parameters
    ----------
    recording : Recording
        The samples and the sensors.
    steps : list of ReducedStep
        Its steps (:func:`find_steps`), or some of them (a fold).
    model : FrictionModel
        The static model fitted to the same steps: its ratio at the measured amplitude shapes each edge.
    samples : int
        Bootstrap resamples of the edges.
    seed : int
        The bootstrap's seed.

    Returns
    -------
    DynamicsFit
        With ``dynamics`` None when neither time constant is resolved.

    Examples
    --------
    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> recording = example_recording(onset_s=0.004, recovery_s=0.040)
    >>> fit = fit_dynamics(recording, find_steps(recording), ExponentialModel(), samples=50)
    >>> round(fit.dynamics.onset_s * 1000, 1), round(fit.dynamics.recovery_s * 1000), fit.reference_speed_mm_s
    (3.9, 40, 100.0)
    """
    lag = recording.lag
    fits, notes = {}, []
    speed_note, exponent, reference = "", ASSUMED_SPEED_EXPONENT, REFERENCE_SPEED_MM_S
    for kind in EDGE_KINDS:
        edges = [s.onset if kind == "onset" else s.recovery for s in steps]
        curves, grid, contrasts = edge_curves(recording, edges, model)
        keep = np.abs(contrasts) >= MIN_CONTRAST
        curves = curves[keep]
        kept = [e for e, k in zip(edges, keep, strict=True) if k]
        window = min(((e.stop - e.at) / lag.rate_hz for e in kept), default=LONGEST_S)
        speeds = np.array([e.speed_mm_s for e in kept])
        known = speeds[np.isfinite(speeds) & (speeds > 0)] if len(speeds) else speeds
        one_speed = float(f"{np.exp(np.mean(np.log(known))):.6g}") if len(known) else math.nan
        fits[kind] = fit_time_constant(curves, grid, kind, lag, window, one_speed if kind == "recovery" else math.nan,
                                       samples, seed)
        if kind == "recovery":
            spans = len(known) == len(kept) and len(known) > 1 and known.max() / known.min() >= MIN_SPEED_SPAN
            if spans and fits[kind].resolved:
                exponent, tau_ref, reference = _speed_law(curves, grid, known)
                speed_note = (f"the recovery's speed law fitted: (v_ref/v)^{exponent:.3g} over "
                              f"{known.min():g}-{known.max():g} mm/s, {1000 * tau_ref:.3g} ms at {reference:.3g} mm/s")
                fits[kind] = _at_reference(fits[kind], tau_ref, reference)
            elif len(known) == len(kept) and len(known):
                reference = one_speed
                speed_note = (f"the recovery's speed law kept as assumed, (v_ref/v)^{ASSUMED_SPEED_EXPONENT:g}: the "
                              f"edges were all at {one_speed:.3g} mm/s (the exponent needs speeds spanning "
                              f"x{MIN_SPEED_SPAN:g})")
            else:
                speed_note = (f"the recovery's speed law kept as assumed, (v_ref/v)^{ASSUMED_SPEED_EXPONENT:g}; the "
                              "sliding speed was not known")
                if fits[kind].resolved:
                    tc = fits[kind]
                    fits[kind] = TimeConstant(kind, tc.fitted_s, tc.low_s, tc.high_s, tc.stderr_s, tc.edges, False,
                                              RECOVERY_S, tc.note + "; not used: the sliding speed is not known "
                                              f"(the published {1000 * RECOVERY_S:g} ms at 22 mm/s kept)")
    onset, recovery = fits["onset"], fits["recovery"]
    dynamics = None
    if onset.resolved or recovery.resolved:
        if not recovery.resolved:
            reference, exponent = REFERENCE_SPEED_MM_S, ASSUMED_SPEED_EXPONENT
        reference = min(max(reference, REFERENCE_SPEED_RANGE_MM_S[0]), REFERENCE_SPEED_RANGE_MM_S[1])
        dynamics = FrictionDynamics(onset.used_s, recovery.used_s, reference, exponent,
                                    source=_source_words(onset, recovery))
    return DynamicsFit(onset, recovery, exponent, speed_note, reference, lag, dynamics, notes)


def _source_words(onset: TimeConstant, recovery: TimeConstant) -> str:
    """Where each time constant used comes from, in a few words."""
    def one(tc: TimeConstant) -> str:
        return f"fitted on the plate, {tc.edges} edges" if tc.resolved else "published"
    if onset.resolved and recovery.resolved:
        return f"fitted on the plate, {onset.edges + recovery.edges} edges"
    return f"onset {one(onset)}, recovery {one(recovery)}"


def _at_reference(tc: TimeConstant, tau_ref: float, reference: float) -> TimeConstant:
    return TimeConstant(tc.kind, tc.fitted_s, tc.low_s, tc.high_s, tc.stderr_s, tc.edges, tc.resolved, tau_ref,
                        tc.note + f"; {1000 * tau_ref:.3g} ms at {reference:.3g} mm/s by the speed law", reference)


def predicted_course(recording: Recording, step: ReducedStep, model: FrictionModel, dynamics: FrictionDynamics | None,
                     up: int = UPSAMPLE) -> tuple[slice, np.ndarray]:
    """The ratio's time course a model predicts over a reduced step, as the sensors read it.

    Parameters
    ----------
    recording : Recording
        The samples and the sensors.
    step : ReducedStep
        The step: from before its onset to the end of its recovery's window.
    model : FrictionModel
        The static model (its ratio at the measured amplitude and the step's force).
    dynamics : FrictionDynamics or None
        The finger's dynamics (at the step's speed, or 22 mm/s when unknown); None: instantaneous.
    up : int
        The model's oversampling.

    Returns
    -------
    (slice, numpy.ndarray)
        The recording's samples covered, and the predicted ratio one a sample.

    Examples
    --------
    With the dynamics it was made with, the example is predicted to within 0.02 (its means are of 8 samples' ends,
    0.06 ms later than a period's middle); without them, not:

    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> recording, model = example_recording(), ExponentialModel()
    >>> step = find_steps(recording)[3]
    >>> _, measured = measured_course(recording, step)
    >>> lagging = FrictionDynamics(0.005, 0.030, 100.0, 0.5)
    >>> float(np.abs(predicted_course(recording, step, model, lagging)[1] - measured).max()) < 0.02
    True
    >>> float(np.abs(predicted_course(recording, step, model, None)[1] - measured).max()) > 0.3
    True
    """
    window = slice(step.onset.first, step.recovery.stop)
    held = _static_up(recording.amplitude_um_pp[window], step.force_n, model, up)
    rate = recording.lag.rate_hz * up
    if dynamics is not None:
        speed = step.recovery.speed_mm_s if math.isfinite(step.recovery.speed_mm_s) else REFERENCE_SPEED_MM_S
        held = dynamics.respond(held, rate, speed, felt=float(held[0]))
    return window, _middles(_sensors(held, recording.lag, rate), up)


def measured_course(recording: Recording, step: ReducedStep) -> tuple[slice, np.ndarray]:
    """The measured mu / mu0 over the same samples as :func:`predicted_course`.

    Parameters
    ----------
    recording : Recording
        The samples.
    step : ReducedStep
        The step (its mu0: the rests beside it).

    Returns
    -------
    (slice, numpy.ndarray)
        The recording's samples covered, and mu / mu0 one a sample.

    Examples
    --------
    >>> recording = example_recording()
    >>> window, ratio = measured_course(recording, find_steps(recording)[0])
    >>> window, round(float(ratio[0]), 3)
    (slice(235, 600, None), 1.0)
    """
    window = slice(step.onset.first, step.recovery.stop)
    return window, recording.lateral_force_n[window] / recording.normal_force_n[window] / step.mu0


def step_points(steps: list[ReducedStep], source: str) -> Measurements:
    """The steps' steady levels as measured points.

    Parameters
    ----------
    steps : list of ReducedStep
        The steps.
    source : str
        Where they come from, in words.

    Returns
    -------
    Measurements
        Each step's mu / mu0 (clipped into 0..1.2) at its amplitude (µm p-p) and force (N, to 0.01 N).

    Examples
    --------
    >>> points = step_points(find_steps(example_recording()), "an example")
    >>> points.amplitude_um_pp.round(2).tolist(), points.force_n.tolist()[:2]
    ([1.0, 1.6, 2.2, 2.8, 3.4, 4.0], [0.5, 0.5])
    """
    from ultraglide.render.physics.measurements import Measurements

    amplitude = np.array([s.amplitude_um_pp for s in steps])
    ratio = np.clip(np.array([s.mu / s.mu0 for s in steps]), 0.0, 1.2)
    force = np.array([round(s.force_n, 2) for s in steps])
    return Measurements(amplitude, ratio, force, source)


@dataclass(frozen=True)
class TimeRanking:
    """One candidate of :func:`compare_in_time`: its name (``stretched``, ``dynamic:stretched``), the held-out rms
    error of the ratio in time, the in-sample one, and how many held-out samples and steps it was judged on.

    Examples
    --------
    >>> TimeRanking("dynamic:stretched", 0.014, 0.013, 6744, 16).name
    'dynamic:stretched'
    """

    name: str
    held_out_rms: float
    in_sample_rms: float
    samples: int
    steps: int


COMPARED_IN_TIME = ("stretched", "exponential", "squeeze-film", "table")
TIME_FOLDS = 5
MIN_STEPS_IN_TIME = 6  # three folds of two steps


def compare_in_time(recording: Recording, kinds: tuple[str, ...] = COMPARED_IN_TIME, folds: int = TIME_FOLDS,
                    samples: int = 100) -> tuple[list[TimeRanking], DynamicsFit, list[ReducedStep]]:
    """Static models against the same with the fitted dynamics, ranked by held-out rms error of the ratio in time.

    Parameters
    ----------
    recording : Recording
        A calibration's recording.
    kinds : tuple of str
        The static models to fit (each also with dynamics).
    folds : int
        The reduced steps are held out in this many folds (every ``folds``-th step in one; fewer where there are
        fewer than two steps a fold).
    samples : int
        Bootstrap resamples for each fold's dynamics (their resolution decides what a fold's dynamic model uses).

    Returns
    -------
    (list of TimeRanking, DynamicsFit, list of ReducedStep)
        The ranking (best first), the dynamics fitted on every step (with the first static model), and the steps.

    Raises
    ------
    ModelError
        Too few whole steps to hold any out.

    Examples
    --------
    The example finger lags (5 ms, 30 ms): every model ranks better with the dynamics than without:

    >>> ranking, fit, steps = compare_in_time(example_recording(), kinds=("exponential",), samples=20)
    >>> [r.name for r in ranking], len(steps)
    (['dynamic:exponential', 'exponential'], 6)
    """
    from ultraglide.render.physics.fitting import fit_model

    steps = find_steps(recording)
    if len(steps) < MIN_STEPS_IN_TIME:
        raise ModelError(f"{recording.source}: {len(steps)} reduced steps measured whole (a rest, a step, a rest, "
                         f"sliding throughout); comparing in time needs at least {MIN_STEPS_IN_TIME}")
    folds = min(folds, len(steps) // 2)
    errors = {f"{p}{k}": [] for k in kinds for p in ("", "dynamic:")}
    inside = {name: [] for name in errors}
    for fold in range(folds):
        train = [s for s in steps if s.number % folds != fold]
        test = [s for s in steps if s.number % folds == fold]
        data = step_points(train, recording.source)
        for kind in kinds:
            try:
                static = fit_model(data, kind).model
            except ModelError:
                continue
            dynamics = fit_dynamics(recording, train, static, samples=samples, seed=fold).dynamics
            for name, lagging in ((kind, None), (f"dynamic:{kind}", dynamics or FrictionDynamics())):
                for group, into in ((test, errors[name]), (train, inside[name])):
                    for step in group:
                        _, predicted = predicted_course(recording, step, static, lagging)
                        _, measured = measured_course(recording, step)
                        into.append(measured - predicted)
    ranking = []
    for name, parts in errors.items():
        if not parts:
            continue
        held = np.concatenate(parts)
        train_parts = np.concatenate(inside[name])
        ranking.append(TimeRanking(name, float(np.sqrt(np.mean(held ** 2))),
                                   float(np.sqrt(np.mean(train_parts ** 2))), len(held), len(steps)))
    ranking.sort(key=lambda r: r.held_out_rms)
    whole = fit_dynamics(recording, steps, fit_model(step_points(steps, recording.source), kinds[0]).model)
    return ranking, whole, steps
