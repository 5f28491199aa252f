"""What the engine reports: :class:`EngineStatus`, a snapshot read from its shared memory, and the recent
:class:`History` a live chart draws."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from ultraglide.render.engine import shm
from ultraglide.render.engine.shm import ring_order


@dataclass(frozen=True)
class History:
    """The recent blocks, oldest first: one row per block (its first sample's time, its last values).

    Examples
    --------
    The history of an engine that has not rendered yet is empty:

    >>> from ultraglide.render.engine.shm import SharedBlock
    >>> block = SharedBlock.create()
    >>> header, times, history, _ = block.read_fast()
    >>> status = status_from_shared(header, times, history, {}, 0, "null", 10.0)
    >>> isinstance(status.history, History), status.history.time_s.shape
    (True, (0,))
    >>> block.close()
    """

    time_s: np.ndarray
    target_ratio: np.ndarray
    commanded_um_pp: np.ndarray
    plate_um_pp: np.ndarray
    limited_samples: np.ndarray
    measured_ratio: np.ndarray  # the friction ratio measured by the plate's force sensors (NaN: none, open loop)
    down: np.ndarray  # 1.0 where a finger touched at the block's end, else 0.0


@dataclass(frozen=True)
class EngineStatus:
    """A snapshot of the engine. Times in µs or s as named; amplitudes µm p-p.

    Attributes
    ----------
    device : str
        The device's name.
    state : str
        ``starting``, ``running``, ``paused``, ``stopping``, ``stopped`` or ``failed``.
    blocks, late_blocks, underruns : int
        Blocks rendered, those late, and the device's underruns.
    block_p50_us, block_p99_us : float or None
        Block times (µs) over the recent blocks.
    limited_percent : float
        Samples held at the plate's limit in the last second (%).
    touches, touches_dropped : int
        Touch reports taken and dropped.
    faults : list of str
        The device's faults, in words.
    history : History
        The recent rows for a live chart (times in s, amplitudes in µm p-p).

    Examples
    --------
    >>> import time
    >>> from ultraglide.render.engine import Engine, EngineConfig
    >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
    ...     engine.wait_ready(60.0)
    ...     status = engine.status()
    >>> status.device, status.state, status.late_blocks >= 0
    ('null', 'running', True)
    """

    device: str
    state: str  # starting, running, paused, stopping, stopped, failed
    priority: str  # the scheduling the block thread got: SCHED_FIFO n, nice n, or normal
    blocks: int
    late_blocks: int
    underruns: int  # the device's: audio underflows or xruns, plate-driver underruns
    block_p50_us: float | None
    block_p99_us: float | None
    limited_percent: float  # samples held at the plate's limit in the last second, %
    clipped_samples: int
    drive_clipped_samples: int
    ramps: int  # the gate's ramps (finger down, up, pause)
    touches: int
    touches_dropped: int
    faults: list[str]
    control_samples: int
    history: History = field(repr=False)
    device_status: dict = field(repr=False, default_factory=dict)
    texture: str = ""  # what the renderer renders with (as of the command thread's last status, ≤ 0.1 s old)
    model: str = ""
    force_n: float = math.nan  # the default force, N
    last_touch: tuple[float, float, float, bool] | None = None  # as drained: x mm, y mm, force N (NaN), down
    run_block_p50_us: float | None = None  # over every block of the run (±1 %: a histogram)
    run_block_p99_us: float | None = None
    resting_blocks: int = 0  # of ``blocks``, those served as zeros while paused at rest (not in block times)
    loop: str = ""  # the friction loop's state in words ("closed loop: following, error 0.03"); "" without it

    def words(self, priority: bool = True) -> str:
        """One line for people.

        Parameters
        ----------
        priority : bool
            Include the block thread's scheduling.

        Returns
        -------
        str

        Examples
        --------
        An engine that has not rendered yet:

        >>> from ultraglide.render.engine.shm import SharedBlock
        >>> block = SharedBlock.create()
        >>> header, times, history, _ = block.read_fast()
        >>> status_from_shared(header, times, history, {}, 0, "null", 10.0).words(priority=False)
        'null starting | 0 blocks, 0 late, 0 underruns | block -/- µs p50/p99 | 0% at the limit'
        >>> block.close()
        """
        p50 = "-" if self.block_p50_us is None else f"{self.block_p50_us:.0f}"
        p99 = "-" if self.block_p99_us is None else f"{self.block_p99_us:.0f}"
        faults = f" | faults: {', '.join(self.faults)}" if self.faults else ""
        loop = f" | {self.loop}" if self.loop else ""
        return (f"{self.device} {self.state} | {self.blocks} blocks, {self.late_blocks} late, "
                f"{self.underruns} underruns | block {p50}/{p99} µs p50/p99 | "
                f"{self.limited_percent:.0f}% at the limit" + loop + (f" | {self.priority}" if priority else "")
                + faults)

    def summary(self) -> dict:
        """The figures as plain JSON values (no history): strict JSON, as ``json.dumps(..., allow_nan=False)``
        takes it.

        Returns
        -------
        dict
            The figures. A float not known or not finite (the default force, N, before the engine has said; a
            touch's force when the panel gives none) is None; tuples are lists, numpy numbers Python's, keys
            text.

        Examples
        --------
        >>> import json
        >>> from ultraglide.render.engine.shm import SharedBlock
        >>> block = SharedBlock.create()
        >>> header, times, history, _ = block.read_fast()
        >>> summary = status_from_shared(header, times, history, {}, 0, "null", 10.0).summary()
        >>> block.close()
        >>> json.loads(json.dumps(summary, allow_nan=False))["state"], "history" in summary, summary["force_n"]
        ('starting', False, None)
        """
        values = asdict(self)
        del values["history"]
        return _plain(values)


def _plain(value):
    """``value`` as strict JSON values: a float that is NaN or infinite is None, numpy numbers and arrays are
    Python's, tuples are lists, keys are text; anything else that JSON cannot hold is its text."""
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, int | np.integer) and not isinstance(value, np.bool_):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, dict):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [_plain(item) for item in value]
    return str(value)


def _underruns(device_status: dict) -> int:
    count = 0
    for key in ("underruns", "xruns", "late_blocks", "late_batches"):
        value = device_status.get(key)
        if isinstance(value, int | float):
            count += int(value)
    return count + int((device_status.get("fault_counts") or {}).get("underrun", 0))  # a plate's own buffer


def status_from_shared(header, block_times, history_ring, device_status, dropped, device_name,
                       history_s) -> EngineStatus:
    """An :class:`EngineStatus` from the shared memory's arrays.

    Parameters
    ----------
    header : numpy.ndarray
        The counters (the segment's fast header, :meth:`SharedBlock.read_fast`'s first array).
    block_times : numpy.ndarray
        The ring of block times, s; their p50 and p99 are given in µs.
    history_ring : numpy.ndarray
        The ring of history rows; the last ``history_s`` seconds are kept.
    device_status : dict
        The device's status as the engine wrote it.
    dropped : int
        Touches dropped by a full touch ring.
    device_name : str
        The device's name where its status has none.
    history_s : float
        How much history to keep, s.

    Returns
    -------
    EngineStatus

    Examples
    --------
    A segment the engine has not written yet:

    >>> from ultraglide.render.engine.shm import SharedBlock
    >>> block = SharedBlock.create()
    >>> header, times, history, _ = block.read_fast()
    >>> status = status_from_shared(header, times, history, {"device": "null"}, 0, "null", 10.0)
    >>> status.device, status.state, status.blocks, status.block_p99_us
    ('null', 'starting', 0, None)
    >>> block.close()
    """
    blocks = int(header[shm.BLOCKS])
    times = ring_order(block_times, int(header[shm.BLOCK_TIME_INDEX]))
    p50 = p99 = None
    if len(times):
        p50, p99 = (float(v) * 1e6 for v in np.percentile(times, [50, 99]))
    rows = ring_order(history_ring, int(header[shm.HISTORY_INDEX]))
    if len(rows):
        rows = rows[rows[:, 0] >= rows[-1, 0] - history_s]
    last_second = rows[rows[:, 0] >= rows[-1, 0] - 1.0] if len(rows) else rows
    limited = 0.0
    if len(last_second) > 1:
        span_samples = (last_second[-1, 0] - last_second[0, 0]) * 12000.0
        limited = float(min(100.0, 100.0 * last_second[:, 4].sum() / max(span_samples, 1.0)))
    faults = list(device_status.get("device_faults") or []) + list(device_status.get("errors") or [])
    state = shm.STATES[int(header[shm.STATE])]
    touched = int(header[shm.TOUCHES]) > 0
    return EngineStatus(
        device=str(device_status.get("device", device_name)), state=state,
        priority=str(device_status.get("priority", "not yet running")), blocks=blocks,
        late_blocks=int(header[shm.LATE_BLOCKS]), underruns=_underruns(device_status),
        block_p50_us=p50, block_p99_us=p99, limited_percent=limited,
        clipped_samples=int(header[shm.CLIPPED]), drive_clipped_samples=int(header[shm.DRIVE_CLIPPED]),
        ramps=int(header[shm.RAMPS]),
        touches=int(header[shm.TOUCHES]), touches_dropped=dropped, faults=faults,
        control_samples=int(header[shm.CONTROL_SAMPLES]),
        history=History(*(rows[:, k].copy() for k in range(shm.HISTORY_FIELDS))),
        device_status=device_status, resting_blocks=int(header[shm.RESTING_BLOCKS]),
        texture=str(device_status.get("texture", "")),
        model=str(device_status.get("model", "")), force_n=float(device_status.get("force_n", math.nan)),
        loop=str(device_status.get("loop", "")),
        last_touch=(float(header[shm.LAST_TOUCH_X]), float(header[shm.LAST_TOUCH_Y]),
                    float(header[shm.LAST_TOUCH_FORCE]), bool(header[shm.LAST_TOUCH_DOWN] > 0.5)) if touched else None)
