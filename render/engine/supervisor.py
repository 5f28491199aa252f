"""The app's watch over its engine: a dead or frozen engine is noticed, the device made safe, the loss said.

The engine (:mod:`render.engine.process`) drives the device from a process of its own, so the app is the only
one left to act when that process dies (killed, crashed) or freezes (stopped by SIGSTOP, stuck holding the
interpreter). :class:`Supervisor` is a thread of the app that watches:

* **the process**: its sentinel (a pipe the kernel closes when it ends) wakes the watch at once, so a death is
  noticed within a few milliseconds (aim: 100 ms);
* **its heartbeats** in the shared memory (looked at every 50 ms, every 10 ms once a look found none new, and
  again just as a silence would become a freeze):
  ``HEARTBEAT``, which the block path advances every block, and ``ENGINE_BEAT``, which a thread of the engine
  advances every 20 ms. From its first block on (running, paused or stopping), neither advancing for
  ``frozen_after_s`` (0.15 s) is a freeze: either is a sign that its process runs Python. A device that pulls no
  block for a while (a plate's handshake after a reconnection, the end of a stop) keeps the engine's beat going,
  and a block that loads a compiled kernel (holding the interpreter, so the beat thread waits) ends with a block's
  beat: neither is taken for a freeze. A watch that did not run itself for a while (this process stopped with the
  engine by Ctrl-Z, or starved) gives the engine the same time again before judging it, and the time the engine's
  threads waited, runnable, for a CPU (:class:`CpuWaits`) is the machine's, not counted as its silence.

A frozen engine is killed (SIGKILL: a frozen process takes no other signal). A serial plate's port is taken from
it first (:func:`devices.after_loss.borrow_port`) and ENABLE 0 sent on it as soon as the kill is sent. Once the
process is gone, and so its port, its files and its locks, the device is made safe from here
(:func:`devices.after_loss.rest_after_loss`: ENABLE 0 on a serial plate, its ACK awaited; the WAV recording
finished; the audio stream and the simulated plate ended with the process), and the CSV logs it wrote are
finished. :attr:`Supervisor.loss` then says what happened and when, in
words, and the run's exit status is :data:`EXIT_ENGINE_LOST` (7).

An engine whose shared state says it stopped (or failed to start, and said why) ends as it should: no loss.

Example::

    engine = Engine.start(config)          # the engine's supervisor starts with it
    engine.sleep(2.0)                      # EngineLost (one line, exit status 7) if the engine was lost meanwhile
    engine.loss                            # None, or the EngineLoss: engine.loss.lines() for the run's report
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from dataclasses import dataclass
from multiprocessing.connection import wait

from ultraglide.devices.after_loss import borrow_port
from ultraglide.devices.serial.run_report import EXIT_ENGINE_LOST
from ultraglide.render.engine import shm

FROZEN_AFTER_S = 0.15  # no sign of life for this long while the engine should play: it is frozen
POLL_S = 0.05  # the watch looks at the heartbeats this often (a death wakes it at once); 0.01 took 4 % of a core
SILENT_POLL_S = 0.01  # ... and this often once a look found no beat,
JUDGE_LATE_S = 0.0005  # and this long after a silence would become a freeze: judged within a millisecond of it
OWN_GAP_S = 0.1  # the watch itself woke this late: this process did not run, so the engine gets its time again
KILL_WAIT_S = 2.0  # the longest wait for a killed engine's process to end
CLEAN_ENDS = ("stopped", "failed")  # the engine's states in which its process ends as it should


@dataclass(frozen=True)
class EngineLoss:
    """How the engine was lost: ``kind`` (``died`` or ``froze``), ``cause`` in words, when it was noticed
    (``noticed_s``, perf_counter s) and how long after its last sign of life (``silent_s``), what was done to make
    the device safe (``rested``, sentences) and when that was done (``rested_s``).

    Examples
    --------
    >>> loss = EngineLoss("froze", "no sign of life for 0.25 s", 12.0, 0.25, ("the plate disabled",), 12.02)
    >>> loss.lines(since_s=10.0)[0]
    'the engine froze at 2.00 s: no sign of life for 0.25 s; noticed 250 ms after its last sign of life, and killed
    (SIGKILL)'
    >>> loss.exit_status
    7
    """

    kind: str
    cause: str
    noticed_s: float
    silent_s: float
    rested: tuple[str, ...]
    rested_s: float
    exit_status: int = EXIT_ENGINE_LOST

    def lines(self, since_s: float | None = None) -> list[str]:
        """The loss in sentences, its time counted from ``since_s`` (perf_counter s; None: not said).

        Parameters
        ----------
        since_s : float, optional
            Where the time is counted from, perf_counter s (None: no time said).

        Returns
        -------
        list of str
            Two sentences: what happened, and what made the device safe.

        Examples
        --------
        >>> loss = EngineLoss("died", "killed by SIGKILL", 12.0, 0.05, ("the plate disabled",), 12.03)
        >>> loss.lines()                                                         # doctest: +NORMALIZE_WHITESPACE
        ['the engine was lost: killed by SIGKILL; noticed 50 ms after its last sign of life',
         'made safe by ultraglide 30 ms after: the plate disabled']
        """
        at = "" if since_s is None else f" at {max(0.0, self.noticed_s - since_s):.2f} s"
        if self.kind == "froze":
            first = (f"the engine froze{at}: {self.cause}; noticed {1000 * self.silent_s:.0f} ms after its last sign "
                     "of life, and killed (SIGKILL)")
        else:
            first = (f"the engine was lost{at}: {self.cause}; noticed {1000 * self.silent_s:.0f} ms after its last "
                     "sign of life")
        done = "; ".join(self.rested) if self.rested else "nothing to rest"
        return [first, f"made safe by ultraglide {1000 * (self.rested_s - self.noticed_s):.0f} ms after: {done}"]

    def words(self) -> str:
        """One line: what happened and what was done.

        Returns
        -------
        str

        Examples
        --------
        >>> loss = EngineLoss("died", "killed by SIGKILL", 12.0, 0.05, (), 12.0)
        >>> loss.words().split("; ")                                      # doctest: +NORMALIZE_WHITESPACE
        ['the engine was lost: killed by SIGKILL', 'noticed 50 ms after its last sign of life',
         'made safe by ultraglide 0 ms after: nothing to rest']
        """
        return "; ".join(self.lines())


class Supervisor:
    """The watch over one engine process (see the module's docstring). Made and started by the
    :class:`~render.engine.engine.Engine`; ``close()`` once the engine has answered a stop (or failed to).

    Examples
    --------
    Every engine has one, watching its process:

    >>> from ultraglide.render.engine import Engine, EngineConfig
    >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
    ...     engine.wait_ready(60.0)
    ...     supervisor = engine.supervisor
    ...     watched = supervisor.pid == engine.process.pid
    >>> isinstance(supervisor, Supervisor), watched
    (True, True)
    """

    def __init__(self, process, shared, device_url: str, logs=(), frozen_after_s: float = FROZEN_AFTER_S,
                 poll_s: float = POLL_S, realtime: bool = False):
        self.process = process
        self.pid = process.pid
        self._sentinel = process.sentinel
        self._fast = shared.fast
        self.device_url = device_url
        self.logs = tuple(str(path) for path in logs if path)
        self.frozen_after_s = frozen_after_s
        self.poll_s = poll_s
        self.realtime = realtime
        self.loss: EngineLoss | None = None
        self.lost = threading.Event()  # set once the loss is handled (the device safe)
        self._kill_reason: str | None = None
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="engine-supervisor", daemon=True)

    def start(self) -> Supervisor:
        """Start the watch (a daemon thread of this process); returns the supervisor, for chaining.

        Returns
        -------
        Supervisor
            Itself.

        Examples
        --------
        An engine's supervisor is started with it, watching on a thread of its own:

        >>> import threading
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     watching = [thread.name for thread in threading.enumerate() if thread.name == "engine-supervisor"]
        >>> watching
        ['engine-supervisor']
        """
        self._thread.start()
        return self

    def close(self) -> EngineLoss | None:
        """End the watch; a process already ended without having stopped is handled first (the device made safe).
        Returns the loss, if there was one.

        Returns
        -------
        EngineLoss or None

        Examples
        --------
        An engine stopped as asked was not lost:

        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> engine = Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False))
        >>> _ = engine.stop()
        >>> print(engine.supervisor.close())
        None
        """
        self._closing.set()
        if self._thread.is_alive():
            self._thread.join()
        self._fast = None
        return self.loss

    def kill(self, reason: str) -> None:
        """End an engine that will not stop (SIGKILL), ``reason`` said in the loss; the watch then makes the device
        safe as for any death (before :meth:`close` returns).

        Parameters
        ----------
        reason : str
            Why, in words, for the loss.

        Examples
        --------
        The engine killed is a loss (exit status 7), its cause the reason given:

        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> engine = Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False))
        >>> engine.supervisor.kill("it would not stop")
        >>> engine.supervisor.wait(30.0)
        True
        >>> loss = engine.supervisor.close()
        >>> loss.kind, loss.cause, loss.exit_status
        ('died', 'it would not stop, so it was killed (SIGKILL)', 7)
        >>> _ = engine.stop()
        """
        self._kill_reason = reason
        self._kill()

    def wait(self, timeout_s: float) -> bool:
        """Sleep up to ``timeout_s``; True (at once) if the engine was lost.

        Parameters
        ----------
        timeout_s : float
            s.

        Returns
        -------
        bool
            True if the engine was lost.

        Examples
        --------
        >>> from ultraglide.render.engine import Engine, EngineConfig
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.supervisor.wait(0.05)                          # well all along: False after 50 ms
        False
        """
        return self.lost.wait(timeout_s)

    # ---- the watch -----------------------------------------------------------------------------------------
    def _watch(self) -> None:
        _prepare_rest(self.device_url)  # what making the device safe needs, imported now rather than then
        if self.realtime:  # a busy app (the demo's drawing) must not hold the watch back: SCHED_FIFO 1 where allowed
            with contextlib.suppress(OSError, AttributeError):  # (after the imports: their CPU at FIFO 1 would keep
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))  # the engine's threads off it); Linux
        fast = self._fast
        now = time.perf_counter()
        block_beat, engine_beat = fast[shm.HEARTBEAT], fast[shm.ENGINE_BEAT]
        block_seen = engine_seen = last_wake = now
        stopped_since = None  # when the process was first seen stopped (SIGSTOP): judged on its own clock
        cpu_waits = None  # the engine's threads' waits for a CPU, watched from the first look that found it silent
        timeout_s = self.poll_s
        while True:
            ended = bool(wait([self._sentinel], timeout_s))
            now = time.perf_counter()
            state = shm.STATES[int(fast[shm.STATE])] if 0 <= fast[shm.STATE] < len(shm.STATES) else "starting"
            if ended:
                if state not in CLEAN_ENDS:
                    self._lost("died", self._how_it_ended(), now, now - max(block_seen, engine_seen))
                return
            if self._closing.is_set():
                return
            if now - last_wake > OWN_GAP_S:  # this process did not run: what the engine did meanwhile is unknown
                block_seen = engine_seen = now
                cpu_waits = None  # (its waits until now excused a silence forgiven already)
            last_wake = now
            # a process seen stopped twice frozen_after_s apart is frozen, however late this watch ran between (the
            # two stopped together by Ctrl-Z are continued together: the engine is not seen stopped again)
            beating = False
            if fast[shm.HEARTBEAT] != block_beat:
                block_beat, beating = fast[shm.HEARTBEAT], True
                block_seen = _beat_time(fast[shm.HEARTBEAT_S], block_seen, now)
            if fast[shm.ENGINE_BEAT] != engine_beat:
                engine_beat, beating = fast[shm.ENGINE_BEAT], True
                engine_seen = _beat_time(fast[shm.ENGINE_BEAT_S], engine_seen, now)
            # /proc is read only when no beat came since the last look: a process that beats is not stopped
            stopped = not beating and _process_state(self.pid) in ("T", "t")
            stopped_since = (stopped_since or now) if stopped else None
            if beating:
                cpu_waits = None
            timeout_s = self.poll_s
            if not beating:  # silent: look closer, and again just as the silence would become a freeze
                judged_at = max(block_seen, engine_seen) + self.frozen_after_s
                if stopped_since is not None:
                    judged_at = min(judged_at, stopped_since + self.frozen_after_s)
                timeout_s = min(self.poll_s, SILENT_POLL_S, max(JUDGE_LATE_S, judged_at - now + JUDGE_LATE_S))
            if state in CLEAN_ENDS:
                continue
            silent_s = now - max(block_seen, engine_seen)
            if stopped_since is not None and now - stopped_since > self.frozen_after_s:
                frozen = True
            elif state in ("running", "paused", "stopping"):
                # neither beat: the block path may end as a stop rests the device (the beat thread goes on), and
                # the beat thread may wait for the interpreter while a block loads a compiled kernel (blocks come)
                waited_s = ran_s = 0.0  # a loaded machine kept it from a CPU this long: that is not its silence;
                if not beating:  # but a thread that had the CPU the freeze's time without a beat is frozen (spinning)
                    if cpu_waits is None:
                        cpu_waits = CpuWaits(self.pid, now)
                    else:
                        waited_s = min(silent_s, cpu_waits.look(now))
                        ran_s = cpu_waits.ran_s
                frozen = silent_s - waited_s > self.frozen_after_s or ran_s > self.frozen_after_s
                if not frozen and silent_s > self.frozen_after_s:  # excused: looked at again as a silent engine is,
                    timeout_s = SILENT_POLL_S  # not every JUDGE_LATE_S (its wait goes on)
            else:  # starting: loading, compiling, opening the device (its death is watched, its beat not yet)
                frozen = False
            if frozen:
                stopped_s = 0.0 if stopped_since is None else now - stopped_since  # (seen stopped this long)
                cause = self._frozen_cause(max(now - block_seen, stopped_s))
                borrowed = borrow_port(self.device_url, self.pid)  # while the frozen process still holds it
                self._kill(borrowed)
                self._lost("froze", cause, now, max(now - max(block_seen, engine_seen), stopped_s), borrowed)
                return

    def _frozen_cause(self, blockless_s: float) -> str:
        stopped = _process_state(self.pid) in ("T", "t")
        why = "its process was stopped (SIGSTOP, or a debugger)" if stopped else "its process ran no Python"
        return f"no block for {1000 * blockless_s:.0f} ms and {why}"

    def _kill(self, borrowed=None) -> None:
        """SIGKILL, the disable sent on the engine's own port if it was borrowed (a killed process writes no more,
        and the kernel tears its memory down before it closes its files), then its end awaited."""
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGKILL)
        if borrowed is not None:
            borrowed.send()
        wait([self._sentinel], KILL_WAIT_S)

    def _how_it_ended(self) -> str:
        if self._kill_reason is not None:
            return f"{self._kill_reason}, so it was killed (SIGKILL)"
        code = None
        try:  # waited for (not WNOHANG): its sentinel closes as it dies, a moment before it can be waited on
            info = os.waitid(os.P_PID, self.pid, os.WEXITED | os.WNOWAIT)
        except ChildProcessError:  # reaped already (multiprocessing polls its children as it starts another, from
            info, deadline = None, time.monotonic() + 1.0  # any thread): its status, once that thread has stored it
            while (code := self.process.exitcode) is None and time.monotonic() < deadline:
                time.sleep(0.001)
        if info is not None:
            code = -info.si_status if info.si_code in (os.CLD_KILLED, os.CLD_DUMPED) else info.si_status
        if code is None:
            return "its process ended"
        if code < 0:
            with contextlib.suppress(ValueError):
                return f"its process was killed by {signal.Signals(-code).name}"
            return f"its process was killed by signal {-code}"
        return f"its process exited with status {code} before it had stopped"

    def _lost(self, kind: str, cause: str, noticed_s: float, silent_s: float, borrowed=None) -> None:
        from ultraglide.devices.after_loss import finish_log, rest_after_loss

        try:
            rested = rest_after_loss(self.device_url, self.pid, borrowed)
            rested += [finish_log(path) for path in self.logs]
        except Exception as error:  # noqa: BLE001 - the loss must be said whatever went wrong in the rest
            rested = [f"the device could not be made safe ({type(error).__name__}: {error})"]
        self.loss = EngineLoss(kind, cause, noticed_s, max(0.0, silent_s), tuple(rested), time.perf_counter())
        self.lost.set()


def _prepare_rest(device_url: str) -> None:
    """Import what :func:`devices.after_loss.rest_after_loss` will need for this device (pyserial for a serial plate:
    tens of milliseconds), so that a loss costs none of it."""
    with contextlib.suppress(Exception):
        from ultraglide.devices import after_loss  # noqa: F401
        from ultraglide.devices.urls import parse_device_url

        if parse_device_url(device_url).kind == "serial":
            from ultraglide.devices.serial import link  # noqa: F401


def _beat_time(stamped_s: float, seen_s: float, now_s: float) -> float:
    """When a beat seen advanced was made: the engine's own time for it (perf_counter s), within what is possible
    (not before the beat seen last, not after now); a watch that looked 50 ms after the last beat would otherwise
    count the silence from its look and judge a freeze 50 ms late."""
    return min(now_s, max(seen_s, stamped_s))


class CpuWaits:
    """How long the threads of process ``pid`` have waited, runnable, for a CPU since this was made (s, summed over
    the threads), as the watch of a silent engine sees it look by look.

    Two parts: the waits that ended (the kernel's schedstat, whose second field grows only as a thread is given a
    CPU, by the whole wait at once), and the waits going on, which schedstat does not show yet: a thread runnable
    (state R) whose CPU time has not grown since the last look waits still, counted from the first look that saw it
    so. Each thread's is at most the time since the first look (a wait that began before it counts from it). A
    thread that sleeps (a deadlock) is not runnable; one that spins (an engine stuck in C) waits only while a busy
    CPU is given to others, and its own CPU time meanwhile (:attr:`ran_s`, the most any one thread had) tells it
    from a starved one. Schedstat's CPU time moves on at the kernel's ticks (4 ms at 250 Hz) and as a thread leaves
    its CPU: a thread running now may look waiting for that long. Nothing is counted where /proc does not say (no
    schedstat, the process gone).

    Parameters
    ----------
    pid : int
        The process whose threads are watched.
    now_s : float
        The time of this first look (``time.perf_counter()`` s).

    Examples
    --------
    A process asleep waits for no CPU, however busy the machine:

    >>> import subprocess, time
    >>> asleep = subprocess.Popen(["sleep", "30"])
    >>> while [state for state, _, _ in _thread_cpu(asleep.pid).values()] != ["S"]:
    ...     time.sleep(0.01)
    >>> waits = CpuWaits(asleep.pid, time.perf_counter())
    >>> time.sleep(0.05)
    >>> waits.look(time.perf_counter())
    0.0
    >>> asleep.kill(); asleep.wait()
    -9
    """

    def __init__(self, pid: int, now_s: float):
        self.pid = pid
        self._first = _thread_cpu(pid)
        self._last = dict(self._first)
        self._first_s = now_s
        self._waiting_since = {tid: now_s for tid, (state, _, _) in self._first.items() if state == "R"}
        self.ran_s = 0.0  # the most CPU time any one thread had since the first look, s (as of the last look)

    def look(self, now_s: float) -> float:
        """Look again.

        Parameters
        ----------
        now_s : float
            The time of this look (``time.perf_counter()`` s).

        Returns
        -------
        float
            How long the threads have waited for a CPU since the first look (s, summed over the threads).

        Examples
        --------
        A thread kept busy has CPU time of its own to show, and whatever it waited is at most the time since the
        first look:

        >>> import os, time
        >>> start = time.perf_counter()
        >>> waits = CpuWaits(os.getpid(), start)
        >>> end = start + 0.05
        >>> while time.perf_counter() < end:
        ...     pass
        >>> now = time.perf_counter()
        >>> waited_s = waits.look(now)
        >>> waits.ran_s > 0, waited_s <= len(_thread_cpu(os.getpid())) * (now - start)
        (True, True)
        """
        threads = _thread_cpu(self.pid)
        waited_s = ran_s = 0.0
        waiting_since = {}
        for tid, (state, ran_ns, waited_ns) in threads.items():
            first = self._first.setdefault(tid, (state, ran_ns, waited_ns))  # (a thread new since: from its first)
            ongoing_s = 0.0
            if state == "R":
                last = self._last.get(tid)
                ran = last is None or ran_ns != last[1]  # it ran since the last look: a wait, if any, starts now
                waiting_since[tid] = now_s if ran else self._waiting_since.get(tid, now_s)
                ongoing_s = now_s - waiting_since[tid]
            waited_s += min(now_s - self._first_s, (waited_ns - first[2]) / 1e9 + ongoing_s)
            ran_s = max(ran_s, (ran_ns - first[1]) / 1e9)
        self._last, self._waiting_since, self.ran_s = threads, waiting_since, ran_s
        return waited_s


def _thread_cpu(pid: int) -> dict[str, tuple[str, int, int]]:
    """Each thread of process ``pid`` by thread id: its state (R runnable, S sleeping, ...), its time on a CPU and
    its ended waits for one (ns, the kernel's schedstat); empty where /proc does not say."""
    threads = {}
    with contextlib.suppress(OSError):
        for tid in os.listdir(f"/proc/{pid}/task"):
            with contextlib.suppress(OSError, ValueError, IndexError):
                with open(f"/proc/{pid}/task/{tid}/stat", "rb") as stat:
                    state = stat.read().rsplit(b")", 1)[1].split()[0].decode()
                with open(f"/proc/{pid}/task/{tid}/schedstat", "rb") as schedstat:
                    ran_ns, waited_ns = map(int, schedstat.read().split()[:2])
                threads[tid] = (state, ran_ns, waited_ns)
    return threads


def _process_state(pid: int) -> str:
    """The kernel's one-letter state of process ``pid`` (R, S, D, T, t, Z ...), or "" where /proc does not say."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rsplit(b")", 1)[1].split()[0].decode()
    except (OSError, IndexError, UnicodeDecodeError):
        return ""
