"""The engine's shared memory: a touch ring (UI → engine) and two seqlock'd status blocks (engine → UI).

Everything is float64 in one ``multiprocessing.shared_memory`` segment, so either side maps it as
numpy arrays and no message is pickled on the real-time path.

* **Touch ring**: single producer (the UI process), single consumer (the engine's block path).
  The producer writes a slot, then advances ``head``; the consumer reads slots up to ``head``, then
  advances ``tail``. Each index has one writer, and x86-64 and ARM64 Python both store an aligned
  float64 whole, so neither side ever waits on the other. A full ring drops the newest touch and
  counts it (the consumer drains every block, so it fills only if the engine has stalled).
* **Fast status** (written by the block path after every block): counters, the last block's time,
  a ring of recent block times and a ring of history rows (time, target friction, commanded and
  plate µm p-p, samples limited), and a ring of touch-to-output times.
* **Slow status** (written by the engine's command thread ten times a second): the device's own
  status as JSON text (names, underruns, faults).

A seqlock: the writer makes the sequence odd, writes, makes it even; a reader copies, then retries
while the sequence was odd or changed. The writer never waits; the reader retries only if it raced.
"""

from __future__ import annotations

import _posixshmem
import contextlib
import errno
import json
import math
import os
import secrets
import time
from dataclasses import dataclass
from multiprocessing import resource_tracker, shared_memory

import numpy as np

TOUCH_SLOTS = 1024
TOUCH_FIELDS = 5  # t_s, x_mm, y_mm, force_n (NaN: the default), down (1/0)
BLOCK_TIMES = 4096  # recent block render times, s
HISTOGRAM_BINS = 1024  # block render times over the whole run, in 2 % wide bins from 1 µs
HISTOGRAM_RATIO = 1.02
HISTORY_ROWS = 8192  # about 5 s at 64-frame blocks and 96 kHz
HISTORY_FIELDS = 7  # t_s, target ratio, commanded µm p-p, plate µm p-p, samples limited, measured ratio (NaN: none),
#                     finger down (1) or not (0) at the block's end
LATENCY_ROWS = 1024  # touch t_s, block rendered at s, block's first sample presented at s
SLOW_BYTES = 16384

# fast status header, by index
SEQ, BLOCKS, LATE_BLOCKS, CONTROL_SAMPLES, CLIPPED, DRIVE_CLIPPED, RAMPS, TOUCHES, STATE, \
    BLOCK_TIME_INDEX, HISTORY_INDEX, LATENCY_INDEX, LAST_BLOCK_S = range(13)
# written outside the seqlock, each a single word with a single writer (the simulated plate's probe)
PLATE_PROBE_UM_PP, PROBE_RISE_S = 14, 15
# the last touch the block path drained (as the renderer got it: mm, N or NaN for the default, 1/0 down)
LAST_TOUCH_X, LAST_TOUCH_Y, LAST_TOUCH_FORCE, LAST_TOUCH_DOWN = 16, 17, 18, 19
RESTING_BLOCKS = 20  # blocks served as zeros while paused and at rest (the renderer not run)
# signs of life for the app's supervisor (render/engine/supervisor.py), each a single word with a single writer:
# HEARTBEAT advances every block the block path serves; ENGINE_BEAT every 20 ms while the engine's process runs
# Python (its beat thread), so a device that stops pulling for a while (a reconnecting plate's handshake) is not
# taken for a frozen engine
HEARTBEAT, ENGINE_BEAT = 21, 22
# when each last advanced (perf_counter s, the clock every process shares), written before its count: a count seen
# advanced has its time written, so the supervisor counts a silence from the engine's own last sign of life, not
# from when it looked
HEARTBEAT_S, ENGINE_BEAT_S = 13, 23
HEADER = 24

STATES = ("starting", "running", "paused", "stopping", "stopped", "failed")


@dataclass(frozen=True)
class Layout:
    """Offsets (in float64 slots) of each part in the segment.

    Examples
    --------
    The parts lie one after another, the touch ring first:

    >>> layout = Layout()
    >>> layout.touches, layout.fast - layout.touches == TOUCH_SLOTS * TOUCH_FIELDS, layout.size * 8 > SLOW_BYTES
    (4, True, True)
    """

    touch_head: int = 0
    touch_tail: int = 1
    touch_dropped: int = 2
    touches: int = 4
    fast: int = 4 + TOUCH_SLOTS * TOUCH_FIELDS
    block_times: int = fast + HEADER
    histogram: int = block_times + BLOCK_TIMES
    history: int = histogram + HISTOGRAM_BINS
    latency: int = history + HISTORY_ROWS * HISTORY_FIELDS
    slow: int = latency + LATENCY_ROWS * 3  # seq, length, then bytes
    size: int = slow + 2 + SLOW_BYTES // 8


LAYOUT = Layout()


class SharedBlock:
    """The segment, mapped as numpy views. ``create`` in the UI process, ``attach`` in the engine.

    Examples
    --------
    The UI's block and the engine's view of it share their memory:

    >>> ui = SharedBlock.create()
    >>> engine = SharedBlock.attach(ui.name)
    >>> ui.push_touch(0.5, 10.0, 20.0, float("nan"), 1.0)
    True
    >>> engine.touches[0, :3].tolist()
    [0.5, 10.0, 20.0]
    >>> engine.write_slow({"device": "null"}); ui.read_slow()
    {'device': 'null'}
    >>> engine.close(); ui.close()
    """

    def __init__(self, memory: shared_memory.SharedMemory, owner: bool):
        self.memory = memory
        self.owner = owner
        self.name = memory.name
        words = np.ndarray((LAYOUT.size,), dtype=np.float64, buffer=memory.buf)
        L = LAYOUT
        self.words = words
        self.touch_index = words[L.touch_head:L.touch_head + 4]  # head, tail, dropped
        self.touches = words[L.touches:L.fast].reshape(TOUCH_SLOTS, TOUCH_FIELDS)
        self.fast = words[L.fast:L.fast + HEADER]
        self.block_times = words[L.block_times:L.histogram]
        self.histogram = words[L.histogram:L.history]
        self.history = words[L.history:L.latency].reshape(HISTORY_ROWS, HISTORY_FIELDS)
        self.latency = words[L.latency:L.slow].reshape(LATENCY_ROWS, 3)
        self.slow_header = words[L.slow:L.slow + 2]
        self.slow_bytes = np.ndarray((SLOW_BYTES,), dtype=np.uint8, buffer=memory.buf, offset=(L.slow + 2) * 8)

    @classmethod
    def create(cls) -> SharedBlock:
        """A new segment, its memory committed; OSError in one line naming it (in /dev/shm), the size asked and what
        to do when the system refuses it (no room, read-only, a file-size limit). Nothing is left behind then.

        The segment is made here (``shm_open``, exclusive) and its pages committed with ``posix_fallocate`` before
        anything maps it: a sparse segment on a full ``/dev/shm`` would kill the process with SIGBUS at its first
        touch of a page the system cannot give. Only a whole segment is then attached as a ``SharedMemory`` (which
        registers it with multiprocessing's resource tracker): one refused before that was never registered, so the
        tracker has nothing to warn about. Python 3.11's ``SharedMemory`` unregisters a segment it fails to map
        without having registered it, and its resource tracker then dies with a traceback (a KeyError); registering
        the name first keeps the two in step.

        Returns
        -------
        SharedBlock
            The owner's block.

        Raises
        ------
        OSError
            The system refused the segment, in one line.

        Examples
        --------
        >>> import os
        >>> block = SharedBlock.create()
        >>> block.owner, os.path.exists(f"/dev/shm/{block.name}")
        (True, True)
        >>> block.close()
        >>> os.path.exists(f"/dev/shm/{block.name}")                  # the owner unlinks it
        False
        """
        size = LAYOUT.size * 8
        name = f"ultraglide_{os.getpid()}_{secrets.token_hex(4)}"
        fd = -1
        try:
            fd = _posixshmem.shm_open(f"/{name}", os.O_CREAT | os.O_EXCL | os.O_RDWR, mode=0o600)
            os.posix_fallocate(fd, 0, size)
        except OSError as error:
            if fd >= 0:
                with contextlib.suppress(OSError):
                    _posixshmem.shm_unlink(f"/{name}")
            raise _refused(error, size, name) from None
        finally:
            if fd >= 0:
                os.close(fd)
        resource_tracker.register(f"/{name}", "shared_memory")
        try:
            memory = shared_memory.SharedMemory(name=name)
        except OSError as error:  # (it unlinked the segment and unregistered it)
            raise _refused(error, size, name) from None
        block = cls(memory, owner=True)
        block.words[:] = 0.0
        return block

    @classmethod
    def attach(cls, name: str) -> SharedBlock:
        # a spawned engine shares its parent's resource tracker, so attaching registers nothing new;
        # only the owner unlinks
        """The engine's view of a segment its parent made (``name``); only the owner unlinks it.

        Parameters
        ----------
        name : str
            The segment's name (:attr:`name` of the owner's block).

        Returns
        -------
        SharedBlock

        Examples
        --------
        >>> owner = SharedBlock.create()
        >>> view = SharedBlock.attach(owner.name)
        >>> owner.fast[0] = 7.0
        >>> view.owner, float(view.fast[0])                          # the same memory
        (False, 7.0)
        >>> view.close(); owner.close()
        """
        return cls(shared_memory.SharedMemory(name=name), owner=False)

    def close(self) -> None:
        """Drop every view of the segment and close it; the owner unlinks it too.

        Examples
        --------
        A view closed leaves the segment to its owner:

        >>> import os
        >>> owner = SharedBlock.create()
        >>> SharedBlock.attach(owner.name).close()
        >>> os.path.exists(f"/dev/shm/{owner.name}")
        True
        >>> owner.close()
        """
        for name in ("words", "touch_index", "touches", "fast", "block_times", "histogram", "history", "latency",
                     "slow_header", "slow_bytes"):
            setattr(self, name, None)
        self.memory.close()
        if self.owner:
            self.memory.unlink()

    # ---- the touch ring ------------------------------------------------------------------------
    def push_touch(self, t_s: float, x_mm: float, y_mm: float, force_n: float, down: float) -> bool:
        """Producer side (one thread of the UI process). False when the ring is full (dropped).

        Parameters
        ----------
        t_s : float
            perf_counter s.
        x_mm, y_mm : float
            mm.
        force_n : float
            N, or NaN for the default.
        down : float
            1.0 touching, 0.0 lifted.

        Returns
        -------
        bool

        Examples
        --------
        The ring holds 1024 reports nobody has taken; the next is dropped and counted:

        >>> block = SharedBlock.create()
        >>> all(block.push_touch(0.001 * k, 10.0, 20.0, float("nan"), 1.0) for k in range(TOUCH_SLOTS))
        True
        >>> block.push_touch(2.0, 10.0, 20.0, float("nan"), 1.0), int(block.touch_index[2])
        (False, 1)
        >>> block.close()
        """
        index = self.touch_index
        head = int(index[0])
        if head - int(index[1]) >= TOUCH_SLOTS:
            index[2] += 1
            return False
        slot = self.touches[head % TOUCH_SLOTS]
        slot[0] = t_s
        slot[1] = x_mm
        slot[2] = y_mm
        slot[3] = force_n
        slot[4] = down
        index[0] = head + 1  # published after the slot is whole
        return True

    # ---- the slow status -----------------------------------------------------------------------
    def write_slow(self, status: dict) -> None:
        """Writer side (the engine's command thread); truncated statuses are replaced by a note.

        Parameters
        ----------
        status : dict
            The device's status (JSON-able; other values as their str).

        Examples
        --------
        A status too long for the segment (16 KiB) is replaced by a note:

        >>> block = SharedBlock.create()
        >>> block.write_slow({"log": "x" * SLOW_BYTES})
        >>> block.read_slow()
        {'note': 'device status too long to share'}
        >>> block.close()
        """
        data = json.dumps(status, default=str).encode()
        if len(data) > SLOW_BYTES:
            data = json.dumps({"note": "device status too long to share"}).encode()
        header = self.slow_header
        header[0] += 1
        self.slow_bytes[:len(data)] = np.frombuffer(data, dtype=np.uint8)
        header[1] = len(data)
        header[0] += 1

    def read_slow(self, post_mortem: bool = False) -> dict:
        """The device's status as the engine last wrote it (a dict, from JSON), read consistently through its
        seqlock; TimeoutError if it kept changing while read. ``post_mortem``: the writer is dead (its process
        ended, perhaps mid-write): the bytes as they are, {} if they are not whole JSON.

        Parameters
        ----------
        post_mortem : bool
            The writer is dead: read the bytes as they are.

        Returns
        -------
        dict

        Raises
        ------
        TimeoutError
            It kept changing while read.

        Examples
        --------
        >>> block = SharedBlock.create()
        >>> block.read_slow(post_mortem=True)                       # nothing written yet
        {}
        >>> block.write_slow({"underruns": 0, "port": "null"})
        >>> block.read_slow()
        {'underruns': 0, 'port': 'null'}
        >>> block.close()
        """
        if post_mortem:
            data = bytes(self.slow_bytes[:min(int(self.slow_header[1]), len(self.slow_bytes))])
            try:
                return json.loads(data) if data else {}
            except ValueError:  # the write it died in
                return {}
        for _ in _attempts():
            before = self.slow_header[0]
            length = int(self.slow_header[1])
            data = bytes(self.slow_bytes[:length])
            if before % 2 == 0 and self.slow_header[0] == before:
                return json.loads(data) if data else {}
        raise TimeoutError("the engine's device status kept changing while being read")

    def read_fast(self, post_mortem: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A consistent copy of (header, block times, history, latency rows); ``post_mortem``: the writer is dead
        (perhaps mid-write): a copy as it is, at most its last block's figures torn.

        Parameters
        ----------
        post_mortem : bool
            The writer is dead: a copy as it is.

        Returns
        -------
        (numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray)
            The header, the block times, the history rows and the latency rows (copies).

        Examples
        --------
        >>> block = SharedBlock.create()
        >>> header, times, history, latency = block.read_fast()
        >>> header.shape, times.shape, history.shape, latency.shape
        ((24,), (4096,), (8192, 7), (1024, 3))
        >>> header[0] = 5.0; float(block.fast[0])                  # a copy: the segment is untouched
        0.0
        >>> block.close()
        """
        if post_mortem:
            return self.fast.copy(), self.block_times.copy(), self.history.copy(), self.latency.copy()
        for _ in _attempts():
            before = self.fast[SEQ]
            if before % 2:
                continue
            header = self.fast.copy()
            times = self.block_times.copy()
            history = self.history.copy()
            latency = self.latency.copy()
            if self.fast[SEQ] == before:
                return header, times, history, latency
        raise TimeoutError("the engine's status kept changing while being read")

    def read_histogram(self, post_mortem: bool = False) -> np.ndarray:
        """A consistent copy of the run's block-time histogram (counts per bin); ``post_mortem``: as it is.

        Parameters
        ----------
        post_mortem : bool
            The writer is dead: a copy as it is.

        Returns
        -------
        numpy.ndarray
            Counts per bin (:func:`histogram_bin`).

        Examples
        --------
        >>> block = SharedBlock.create()
        >>> block.histogram[histogram_bin(0.0005)] += 1                    # one block of 500 µs
        >>> counts = block.read_histogram()
        >>> len(counts), int(counts.sum()), int(counts.argmax()) == histogram_bin(0.0005)
        (1024, 1, True)
        >>> block.close()
        """
        if post_mortem:
            return self.histogram.copy()
        for _ in _attempts():
            before = self.fast[SEQ]
            if before % 2:
                continue
            counts = self.histogram.copy()
            if self.fast[SEQ] == before:
                return counts
        raise TimeoutError("the engine's status kept changing while being read")


def _refused(error: OSError, size: int, name: str) -> OSError:
    """The system's refusal of the engine's segment as one line: what, how much, why, what to do."""
    why = (error.strerror or str(error)).lower()
    advice = {errno.ENOSPC: "free space in /dev/shm (df -h /dev/shm) or make it larger",
              errno.ENOMEM: "free memory, or raise the memory limit (ulimit -v)",
              errno.EROFS: "/dev/shm is read-only: mount it writable (a tmpfs)",
              errno.EACCES: "/dev/shm takes no new file from this user: check its permissions",
              errno.EFBIG: "the file-size limit (ulimit -f) is too small for it: raise it",
              errno.EMFILE: "this process has too many files open"}.get(error.errno, "check /dev/shm (a tmpfs)")
    return OSError(error.errno, f"the engine's shared memory ({size:,} bytes) could not be made: {why}; {advice}",
                   f"/dev/shm/{name}")


_LOG_RATIO = math.log(HISTOGRAM_RATIO)


def histogram_bin(seconds: float) -> int:
    """The histogram bin of a block time, s (bin k holds 1 µs·1.02^k up to 1 µs·1.02^(k+1)).

    Parameters
    ----------
    seconds : float
        A block's time (s).

    Returns
    -------
    int

    Examples
    --------
    >>> histogram_bin(1e-6), histogram_bin(1e-3)                       # 1 µs; 1 ms: log(1000) / log(1.02)
    (0, 348)
    """
    if seconds <= 1e-6:
        return 0
    return min(int(math.log(seconds * 1e6) / _LOG_RATIO), HISTOGRAM_BINS - 1)


def histogram_percentiles(counts: np.ndarray, percents) -> list[float | None]:
    """Percentiles (s) of the times counted in ``counts``, each the geometric middle of its bin (±1 %).

    Parameters
    ----------
    counts : numpy.ndarray
        Block times counted per bin.
    percents : sequence of float
        Which percentiles (0-100).

    Returns
    -------
    list of float or None
        Seconds; None when nothing was counted.

    Examples
    --------
    >>> import numpy as np
    >>> counts = np.zeros(1000, dtype=np.int64)
    >>> counts[histogram_bin(1e-3)] = 10
    >>> [round(p * 1e3, 2) for p in histogram_percentiles(counts, [50, 99])]   # ms, within 1 %
    [0.99, 0.99]
    >>> histogram_percentiles(np.zeros(1000, dtype=np.int64), [50])
    [None]
    """
    total = counts.sum()
    if total == 0:
        return [None for _ in percents]
    cumulative = np.cumsum(counts)
    bins = [int(np.searchsorted(cumulative, total * p / 100.0)) for p in percents]
    return [1e-6 * HISTOGRAM_RATIO ** (k + 0.5) for k in bins]


def _attempts(timeout_s: float = 2.0):
    """Retries for a seqlock reader: a few at once, then yielding the CPU (the writer may have been
    preempted mid-write on a loaded machine), until ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    attempt = 0
    while attempt < 8 or time.monotonic() < deadline:
        if attempt >= 8:
            time.sleep(0.0002)
        yield attempt
        attempt += 1


def ring_order(ring: np.ndarray, written: int) -> np.ndarray:
    """The rows of a ring in the order written, oldest first (``written`` = rows written in all).

    Parameters
    ----------
    ring : numpy.ndarray
        The ring's rows.
    written : int
        Rows written in all.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> import numpy as np
    >>> ring_order(np.arange(5), 7).tolist(), ring_order(np.arange(5), 3).tolist()   # wrapped; not yet full
    ([2, 3, 4, 0, 1], [0, 1, 2])
    """
    size = len(ring)
    if written <= size:
        return ring[:written]
    start = written % size
    return np.concatenate((ring[start:], ring[:start]))


def finite_or_none(value: float) -> float | None:
    """``value`` as a float, or None when it is NaN or infinite (for strict JSON).

    Parameters
    ----------
    value : float

    Returns
    -------
    float or None

    Examples
    --------
    >>> finite_or_none(float("nan")), finite_or_none(2)
    (None, 2.0)
    """
    return None if not math.isfinite(value) else float(value)
