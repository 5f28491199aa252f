"""What a process does to keep the block thread on time: its scheduling, and the kernel's huge-page work
kept away from its memory.

The block thread runs at a real-time priority where the OS allows (SCHED_FIFO), and so, lower, do the
engine's other threads, which take the GIL now and then. Priority is not enough on kernels built without
full preemption (``CONFIG_PREEMPT_NONE``, Debian's cloud kernels and many VMs): a kernel thread holds its
CPU until it reaches a preemption point, whatever waits to run there. ``khugepaged`` is the one that bites.
numpy asks for transparent huge pages on every array of 4 MiB or more (``madvise(MADV_HUGEPAGE)``),
and khugepaged collapses such memory 2 MiB at a time; measured here (ftrace, demo dragged under Xvfb,
JACK at 256 frames), it kept the JACK thread off its CPU for 2.3 and 4.7 ms, and each time the callback
missed its 2.7 ms period. :func:`keep_huge_pages_out` turns huge pages off for the whole process
(``prctl(PR_SET_THP_DISABLE)``, inherited by the processes it starts), so khugepaged has nothing of ours to
collapse: the engine's memory and the UI's beside it.

An idle CPU is the other delay. In a VM an idle vCPU halts, and the host takes 100–450 µs to run it
again when the block thread's wake-up lands there (ftrace, cpuidle ``haltpoll``): most of a 64-frame
period at 96 kHz (667 µs). :class:`CpuWakeLatency` asks the kernel, while the engine renders (a finger
on the plate, or the ramp to rest after it), to keep every CPU in idle states that wake within the
given latency (a PM QoS request through ``/dev/cpu_dma_latency``, held while its file is open); 0 µs
keeps idle CPUs polling. At rest it is released, so the machine idles as its power governor likes.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import struct
import threading
import time

FIFO_PRIORITY = 60
OTHER_THREADS_PRIORITY = 1
PR_SET_THP_DISABLE = 41  # <linux/prctl.h>
PR_GET_THP_DISABLE = 42
CPU_LATENCY_QOS = "/dev/cpu_dma_latency"


def raise_priority() -> str:
    """Raise the calling thread's scheduling priority as far as the OS allows; says what it got.

    A thread the audio system already runs in real time (JACK's clients) keeps the priority it was given,
    which JACK orders below its own server thread. Tried in order: SCHED_FIFO 60, then nice -15, -10, -5.

    Returns
    -------
    str
        The scheduling the thread got, in words: ``SCHED_FIFO 60``, ``nice -15`` ... or
        ``normal (no permission to raise it)``.

    Examples
    --------
    On a thread of its own (the priority stays with that thread), checked against what the OS reports:

    >>> import os, threading
    >>> got = []
    >>> def block_thread():
    ...     got.append((raise_priority(), os.sched_getscheduler(0) == os.SCHED_FIFO))
    >>> thread = threading.Thread(target=block_thread); thread.start(); thread.join()
    >>> words, fifo = got[0]
    >>> words.startswith("SCHED_FIFO") == fifo
    True
    """
    try:
        policy = os.sched_getscheduler(0)
        # (priority OTHER_THREADS_PRIORITY is ours, from raise_other_threads racing the first block)
        if policy in (os.SCHED_FIFO, os.SCHED_RR) and os.sched_getparam(0).sched_priority > OTHER_THREADS_PRIORITY:
            name = "SCHED_FIFO" if policy == os.SCHED_FIFO else "SCHED_RR"
            return f"{name} {os.sched_getparam(0).sched_priority} (given by the audio system)"
    except (OSError, AttributeError):
        pass
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(FIFO_PRIORITY))
        return f"SCHED_FIFO {FIFO_PRIORITY}"
    except (OSError, AttributeError):
        pass
    for nice in (-15, -10, -5):
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)  # per thread on Linux
            return f"nice {nice}"
        except (OSError, AttributeError):
            continue
    return "normal (no permission to raise it)"


def raise_other_threads(priority: int = OTHER_THREADS_PRIORITY) -> str:
    """Run every other thread of this process in real time too, at the lowest real-time priority.

    All of them take the GIL now and then (the command thread, a serial reader, the simulated plate);
    one preempted by an ordinary process while it holds the GIL would stall the block thread for a
    whole time slice (priority inversion). At SCHED_FIFO 1 they run below the block thread and the
    audio server, above everything ordinary, and they sleep almost all the time. Threads they start later
    inherit it.

    Parameters
    ----------
    priority : int
        The SCHED_FIFO priority, 1 (the lowest) by default.

    Returns
    -------
    str
        How many threads run at that priority (raised now or before), in words, or
        ``other threads: normal``.

    Examples
    --------
    In a forked process of its own (it changes every thread of the process it runs in):

    >>> import multiprocessing, os
    >>> context = multiprocessing.get_context("fork")
    >>> reader, writer = context.Pipe(duplex=False)
    >>> child = context.Process(target=lambda: writer.send(
    ...     (raise_other_threads(), os.sched_getscheduler(0) == os.SCHED_FIFO)))
    >>> child.start(); words, fifo = reader.recv(); child.join()
    >>> words.startswith("other threads: SCHED_FIFO 1 (") == fifo
    True
    """
    try:
        running = _raise(_tasks(), priority)
    except (OSError, AttributeError):
        return "other threads: normal"
    return f"other threads: SCHED_FIFO {priority} ({running})" if running else "other threads: normal"


def _raise(tids: set[int], priority: int) -> int:
    """Put those of these threads that run at ordinary priority at SCHED_FIFO ``priority``; says how many of them
    run there now (raised now or before). Threads that have ended are skipped."""
    running = 0
    for tid in tids:
        try:
            if os.sched_getscheduler(tid) == os.SCHED_OTHER:
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
            if os.sched_getscheduler(tid) == os.SCHED_FIFO and os.sched_getparam(tid).sched_priority == priority:
                running += 1
        except (ProcessLookupError, PermissionError):
            continue
    return running


def _tasks() -> set[int]:
    """The thread ids of this process (Linux; empty elsewhere)."""
    try:
        return set(map(int, os.listdir("/proc/self/task")))
    except (OSError, ValueError):
        return set()


def _may_run_in_real_time(priority: int) -> bool:
    """Whether this thread may be put at SCHED_FIFO ``priority``: tried, and its own scheduling given back at once."""
    try:
        before = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError):
        return False
    os.sched_setscheduler(0, *before)
    return True


@contextlib.contextmanager
def threads_started_in_real_time(priority: int = OTHER_THREADS_PRIORITY):
    """Threads started inside the ``with`` run at SCHED_FIFO ``priority`` from its end on, where the OS allows.

    The calling thread, and the work it does inside, keep the caller's scheduling (ordinary for a command's
    main thread).

    For a command that streams to a plate on threads of its own (a driver's writer and reader, a simulated
    plate's) beside a main thread that stays ordinary: a writer thread at ordinary priority on a busy machine
    can go unscheduled past the plate's 100 ms watchdog; the engine raises all of its threads
    (:func:`raise_other_threads`). The set-up inside the block (imports, the first call of a compiled kernel, a
    handshake: half a second of CPU for a simulated plate) runs at ordinary priority: at SCHED_FIFO nothing of
    equal priority could preempt it, and it once kept another process's engine threads waiting 130 ms.

    Parameters
    ----------
    priority : int
        The SCHED_FIFO priority, 1 by default.

    Yields
    ------
    str
        What the threads get, in words: ``SCHED_FIFO 1`` or ``normal (no permission to raise it)``.

    Examples
    --------
    >>> import os, threading
    >>> done = threading.Event()
    >>> with threads_started_in_real_time() as words:
    ...     writer = threading.Thread(target=done.wait); writer.start()
    >>> raised = os.sched_getscheduler(writer.native_id) == os.SCHED_FIFO
    >>> done.set(); writer.join()
    >>> raised == (words == "SCHED_FIFO 1"), os.sched_getscheduler(0) == os.SCHED_OTHER
    (True, True)
    """
    if not _may_run_in_real_time(priority):
        yield "normal (no permission to raise it)"
        return
    before = _tasks()
    try:
        yield f"SCHED_FIFO {priority}"
    finally:
        with contextlib.suppress(OSError):
            _raise(_tasks() - before, priority)


_SCHED_SETATTR = {"x86_64": (314, 315), "aarch64": (274, 275), "riscv64": (274, 275), "armv7l": (380, 381),
                  "i686": (351, 352)}  # Linux's sched_setattr and sched_getattr, by machine
_SCHED_ATTR = "IIQiIQQQ"  # struct sched_attr as of Linux 3.14 (48 bytes): size, policy, flags, nice, priority,
# runtime (an ordinary thread's slice since 6.12, ns), deadline, period


def short_time_slice(slice_s: float) -> bool:
    """This thread's time slice (``slice_s``, s) where Linux allows it, its nice kept; whether the kernel took it (read
    back: a kernel before 6.12 keeps its own). Only an ordinary (SCHED_OTHER) thread's is changed.

    Linux's scheduler (EEVDF, 6.12 and later) lets a thread that wakes preempt the one running only when its slice is
    the shorter: a short slice gives a thread no more CPU than its nice does, only sooner.

    Parameters
    ----------
    slice_s : float
        The slice wanted, s (the kernel takes 0.1 ms to 100 ms).

    Returns
    -------
    bool
        Whether this thread now has it.

    Examples
    --------
    In a thread of its own (the setting is the thread's); where the kernel keeps its own slice, False:

    >>> import threading
    >>> got = []
    >>> worker = threading.Thread(target=lambda: got.append(short_time_slice(0.0001))); worker.start(); worker.join()
    >>> got in ([True], [False])
    True
    """
    import platform

    numbers = _SCHED_SETATTR.get(platform.machine())
    if numbers is None or not hasattr(os, "sched_getscheduler") or os.sched_getscheduler(0) != os.SCHED_OTHER:
        return False
    wanted = round(slice_s * 1e9)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        nice = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())  # this thread's (Linux)
        attr = ctypes.create_string_buffer(struct.pack(_SCHED_ATTR, struct.calcsize(_SCHED_ATTR), os.SCHED_OTHER, 0,
                                                       nice, 0, wanted, 0, 0))
        if libc.syscall(numbers[0], 0, attr, 0) != 0:
            return False
        read = ctypes.create_string_buffer(struct.calcsize(_SCHED_ATTR))
        if libc.syscall(numbers[1], 0, read, struct.calcsize(_SCHED_ATTR), 0) != 0:
            return False
        return struct.unpack(_SCHED_ATTR, read.raw)[5] == wanted
    except (OSError, AttributeError):
        return False


def keep_huge_pages_out() -> str:
    """Turn transparent huge pages off for this process and the processes it starts (Linux); says what it got.

    Memory already in huge pages stays as it is; khugepaged skips the process from now on, and new
    allocations take ordinary pages (numpy's large arrays are as fast for the engine's block sizes).

    Returns
    -------
    str
        ``huge pages off``, or ``huge pages: as the system has them (why)``.

    Examples
    --------
    In a forked process of its own (the setting is the whole process's):

    >>> import multiprocessing
    >>> with multiprocessing.get_context("fork").Pool(1) as pool:
    ...     pool.apply(keep_huge_pages_out)
    'huge pages off'
    """
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return "huge pages: as the system has them (no prctl)"
    prctl.restype = ctypes.c_int
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
    if prctl(PR_SET_THP_DISABLE, 1, 0, 0, 0) != 0:
        return f"huge pages: as the system has them ({os.strerror(ctypes.get_errno())})"
    return "huge pages off" if prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0) == 1 else "huge pages: as the system has them"


class CpuWakeLatency:
    """A PM QoS request bounding how long an idle CPU takes to wake (µs), held only while wanted.

    ``hold(True)`` opens ``/dev/cpu_dma_latency`` and writes the bound; ``hold(False)`` closes it, which
    withdraws the request (so does the process's end). Writing needs root or a udev rule granting the
    file; without it the request is not made and :meth:`words` says why. Not for the block path: it
    opens a file (the engine's command thread calls it).

    Parameters
    ----------
    latency_us : int or None
        The bound, µs (0: idle CPUs poll); None: never asked.

    Examples
    --------
    Held and released; where the file cannot be written, :meth:`words` says why and nothing is held:

    >>> wake = CpuWakeLatency(0)
    >>> wake.hold(True)
    >>> wake.held == (wake.holds == 1)
    True
    >>> wake.close(); wake.held
    False
    >>> CpuWakeLatency(None).words()
    'CPU wake-up: as the system has it (not asked)'
    """

    def __init__(self, latency_us: int | None = 0):
        self.latency_us = latency_us
        self.holds = 0  # how many times the request was made
        self.held_s = 0.0  # for how long in all, s (up to the last release)
        self._fd: int | None = None
        self._since = 0.0
        self._refused: str | None = None if latency_us is not None else "not asked"

    @property
    def held(self) -> bool:
        """Whether the request is held now.

        Examples
        --------
        >>> CpuWakeLatency(None).held                       # never asked: never held
        False
        """
        return self._fd is not None

    def hold(self, wanted: bool) -> None:
        """Make the request (``wanted``) or withdraw it; once refused (no permission), not tried again.

        Parameters
        ----------
        wanted : bool
            Make the request (True) or withdraw it (False).

        Examples
        --------
        Asked for, then withdrawn; where the file cannot be written nothing is held either way:

        >>> wake = CpuWakeLatency(0)
        >>> wake.hold(True)
        >>> wake.hold(False)
        >>> wake.held
        False
        """
        if wanted and self._fd is None and self._refused is None:
            try:
                fd = os.open(CPU_LATENCY_QOS, os.O_WRONLY | os.O_CLOEXEC)
            except OSError as error:
                self._refused = error.strerror or str(error)
                return
            try:
                os.write(fd, struct.pack("=i", int(self.latency_us)))
            except OSError as error:
                os.close(fd)
                self._refused = error.strerror or str(error)
                return
            self._fd = fd
            self._since = time.monotonic()
            self.holds += 1
        elif not wanted and self._fd is not None:
            self.close()

    def close(self) -> None:
        """Withdraw the request if held, counting the time it was.

        Examples
        --------
        >>> wake = CpuWakeLatency(0)
        >>> wake.close()                                  # nothing held: nothing to do
        >>> wake.held, wake.held_s
        (False, 0.0)
        """
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
            self.held_s += time.monotonic() - self._since

    def words(self) -> str:
        """The request in words: its bound (µs), held or released, how often, how long (s); or why it was not made.

        Returns
        -------
        str

        Examples
        --------
        >>> CpuWakeLatency(None).words()
        'CPU wake-up: as the system has it (not asked)'
        """
        if self._refused is not None:
            return f"CPU wake-up: as the system has it ({self._refused})"
        held_s = self.held_s + (time.monotonic() - self._since if self.held else 0.0)
        return (f"CPU wake-up within {self.latency_us} µs while rendering ({'held' if self.held else 'released'}; "
                f"{self.holds} {'time' if self.holds == 1 else 'times'}, {held_s:.1f} s in all)")
