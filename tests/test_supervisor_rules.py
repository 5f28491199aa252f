"""The supervisor's judgement (render/engine/supervisor.py) against a real child process that beats as it is told
in a shared header: a process whose block path or whose beat thread advances is alive, whatever its state; one
whose neither advances while it plays is frozen and killed; one that exits before it stopped is a death said with
its status; and one kept from a CPU by a busy machine is not taken for frozen unless it also sleeps."""

import mmap
import multiprocessing
import os
import re
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
from cpu_taken import cpu0_shared, cpu0_taken, free_of_cpu0, keep_on_cpu0
from ultraglide.render.engine import shm
from ultraglide.render.engine.supervisor import Supervisor

FROZEN_AFTER_S = 0.5  # long against a child at ordinary priority starved beside two CPU hogs (0.1 s once was not)
MODE = 0  # the header's first word (SEQ, unused here) tells the child what to beat
BLOCKS, BEAT_THREAD, NOTHING, EXIT, DEADLOCK, SPIN_IN_C = 1.0, 2.0, 3.0, 4.0, 5.0, 6.0


def child(buffer, state: str) -> None:
    """Beat as the header's MODE says, every 2 ms, with ``state`` published: blocks only, the beat thread only,
    nothing (busy, running Python), exit with status 3, sleep for good (a deadlock), or spin in C holding the
    interpreter while 24 threads wait for it."""
    fast = np.frombuffer(buffer, dtype=np.float64, count=shm.HEADER)
    fast[shm.STATE] = shm.STATES.index(state)
    while True:
        mode = fast[MODE]
        if mode == EXIT:
            os._exit(3)
        if mode == DEADLOCK:
            threading.Event().wait()
        if mode == SPIN_IN_C:
            for _ in range(24):
                threading.Thread(target=lambda: [time.sleep(0.001) for _ in iter(int, 1)], daemon=True).start()
            re.fullmatch(r"(a+)+b", "a" * 64)  # backtracks for longer than anyone waits, holding the interpreter
        deadline = time.perf_counter() + 0.002
        while time.perf_counter() < deadline:
            pass
        if mode == BLOCKS:  # each beat's time first, then its count, as the engine writes them
            fast[shm.HEARTBEAT_S] = time.perf_counter()
            fast[shm.HEARTBEAT] += 1
        elif mode == BEAT_THREAD:
            fast[shm.ENGINE_BEAT_S] = time.perf_counter()
            fast[shm.ENGINE_BEAT] += 1


class Watched:
    """A child beating as told, and a supervisor watching it (null device: nothing to rest)."""

    def __init__(self, state: str, mode: float):
        self.buffer = mmap.mmap(-1, shm.HEADER * 8)  # shared with the forked child
        self.fast = np.frombuffer(self.buffer, dtype=np.float64, count=shm.HEADER)
        self.fast[MODE] = mode
        self.process = multiprocessing.get_context("fork").Process(target=child, args=(self.buffer, state),
                                                                    daemon=True)
        self.process.start()
        self.supervisor = Supervisor(self.process, SimpleNamespace(fast=self.fast), "null",
                                     frozen_after_s=FROZEN_AFTER_S).start()

    def beats_for(self, index: int, count: int, timeout_s: float = 60.0) -> None:
        """Wait until the beat at ``index`` advanced ``count`` times (2 ms each at the least) or the watch judged."""
        start, deadline = self.fast[index], time.monotonic() + timeout_s
        while self.fast[index] < start + count and not self.supervisor.lost.is_set():
            assert time.monotonic() < deadline, "the child did not beat"
            time.sleep(0.001)

    def close(self) -> None:
        if self.process.is_alive():
            self.fast[MODE] = EXIT
        self.process.join(30)
        if self.process.is_alive():  # (spinning in C: it reads no mode)
            self.process.kill()
            self.process.join(30)
        self.supervisor.close()


@pytest.mark.parametrize("state", ["running", "stopping"])
def test_blocks_alone_are_a_sign_of_life_while_the_beat_thread_waits(state):
    """A block that loads a compiled kernel holds the interpreter: the beat thread waits, the blocks come."""
    watched = Watched(state, BLOCKS)
    try:
        watched.beats_for(shm.HEARTBEAT, int(6 * FROZEN_AFTER_S / 0.002))  # six times the freeze's time at least
        assert watched.supervisor.loss is None and watched.process.is_alive()
    finally:
        watched.close()


@pytest.mark.parametrize("state", ["running", "stopping"])
def test_the_beat_thread_alone_is_a_sign_of_life_while_no_block_is_pulled(state):
    """A plate's handshake after a reconnection, or the end of a stop: no block, the beat thread goes on."""
    watched = Watched(state, BEAT_THREAD)
    try:
        watched.beats_for(shm.ENGINE_BEAT, int(6 * FROZEN_AFTER_S / 0.002))
        assert watched.supervisor.loss is None and watched.process.is_alive()
    finally:
        watched.close()


@pytest.mark.parametrize("state", ["running", "paused", "stopping"])
def test_neither_beat_is_a_freeze_the_process_killed(state):
    watched = Watched(state, NOTHING)
    try:
        assert watched.supervisor.wait(60.0), "no freeze judged within 60 s"
        loss = watched.supervisor.loss
        assert loss.kind == "froze" and "its process ran no Python" in loss.cause, loss
        assert loss.silent_s >= FROZEN_AFTER_S
        watched.process.join(30)
        assert watched.process.exitcode == -9  # SIGKILL: a frozen process takes no other signal
    finally:
        watched.close()


def test_a_silence_counts_from_the_engines_own_last_beat_not_from_the_watchs_look(monkeypatch):
    """The watch looks every 50 ms while beats come: counted from its look, a freeze was judged up to 50 ms late
    (noticed 172-198 ms after a SIGSTOP, quiet, for a 150 ms freeze). The silence runs from the time the engine
    wrote with its last beat. (The watch's own lateness rule is set aside: it would restart the count.)"""
    from ultraglide.render.engine import supervisor

    monkeypatch.setattr(supervisor, "OWN_GAP_S", 3600.0)
    watched = Watched("running", BLOCKS)
    try:
        watched.beats_for(shm.HEARTBEAT, 50)
        watched.fast[MODE] = NOTHING  # still running Python, no beat
        assert watched.supervisor.wait(60.0), "no freeze judged within 60 s"
        loss = watched.supervisor.loss
        last_beat_s = float(watched.fast[shm.HEARTBEAT_S])
        assert loss.kind == "froze" and loss.silent_s >= FROZEN_AFTER_S
        assert loss.noticed_s - loss.silent_s == pytest.approx(last_beat_s, abs=1e-6)
    finally:
        watched.close()


def test_a_starting_engine_is_not_judged_by_its_beats():
    """Loading, compiling, opening the device: no beat yet, only its death is watched."""
    watched = Watched("starting", NOTHING)
    try:
        deadline = time.perf_counter() + 6 * FROZEN_AFTER_S
        while time.perf_counter() < deadline:  # the watch looks every 10-50 ms meanwhile
            assert not watched.supervisor.lost.wait(0.05)
        assert watched.supervisor.loss is None and watched.process.is_alive()
    finally:
        watched.close()


def test_an_exit_before_the_stop_is_a_death_with_its_status():
    """Ten times: the sentinel closes a moment before the process can be waited on; the status is still said."""
    for _ in range(10):
        watched = Watched("running", BLOCKS)
        try:
            watched.beats_for(shm.HEARTBEAT, 5)
            watched.fast[MODE] = EXIT
            assert watched.supervisor.wait(60.0), "the death was not noticed within 60 s"
            loss = watched.supervisor.loss
            assert (loss.kind, loss.cause) == ("died", "its process exited with status 3 before it had stopped")
        finally:
            watched.close()


def longest_silence(fast, index: int, seconds: float) -> float:
    """The longest time (s) the beat at ``index`` went without advancing over the next ``seconds``, from its stamps."""
    longest, end = 0.0, time.perf_counter() + seconds
    stamp = {shm.HEARTBEAT: shm.HEARTBEAT_S, shm.ENGINE_BEAT: shm.ENGINE_BEAT_S}[index]
    while (now := time.perf_counter()) < end:  # the clock read before the stamp: a silence is never overstated
        longest = max(longest, now - float(fast[stamp]))
        time.sleep(0.001)
    return longest


def test_a_child_kept_from_the_cpu_by_a_busy_machine_is_not_taken_for_frozen():
    """Beating every 2 ms but kept on CPU 0 while a real-time process spins there: it runs in bursts (the kernel
    leaves ordinary threads about 50 ms a second) and waits, runnable, in between, silent far longer than the freeze's
    time. Those waits are the machine's, counted as they go on (the kernel's own count grows only once a wait ends):
    no loss, and it beats on once the CPU is its own again."""
    watched = Watched("running", BLOCKS)
    try:
        watched.beats_for(shm.HEARTBEAT, 5)
        with cpu0_taken():
            threads = keep_on_cpu0(watched.process.pid)
            longest = longest_silence(watched.fast, shm.HEARTBEAT, 3.0)
        free_of_cpu0(threads)
        watched.beats_for(shm.HEARTBEAT, 50)
        assert longest > FROZEN_AFTER_S  # the stimulus: silences the watch would have judged a freeze
        assert watched.supervisor.loss is None and watched.process.is_alive()
    finally:
        watched.close()


def frozen_on_cpu0(busy, mode: float, within_s: float) -> None:
    """A child that beat, kept on CPU 0 while ``busy`` (a context) keeps that CPU busy, told ``mode``: it is judged
    frozen within ``within_s`` and killed."""
    watched = Watched("running", BLOCKS)
    try:
        watched.beats_for(shm.HEARTBEAT, 5)
        with busy:
            threads = keep_on_cpu0(watched.process.pid)
            watched.fast[MODE] = mode
            judged = watched.supervisor.wait(within_s)
        free_of_cpu0(threads)
        assert judged, f"no freeze judged within {within_s:.0f} s"
        loss = watched.supervisor.loss
        assert loss.kind == "froze" and "its process ran no Python" in loss.cause, loss
        watched.process.join(30)
        assert watched.process.exitcode == -9
    finally:
        watched.close()


def test_a_deadlocked_child_on_a_busy_cpu_is_still_frozen():
    """A deadlock sleeps, so it waits for no CPU: the same child on the same taken CPU, once it sleeps for good
    without a beat, is judged frozen and killed."""
    frozen_on_cpu0(cpu0_taken(), DEADLOCK, 60.0)


def test_a_child_spinning_in_c_on_a_busy_cpu_is_still_frozen():
    """A frozen engine may spin in C holding the interpreter, its other threads waiting for it, on a CPU it shares
    with busy processes: its threads then wait for the CPU at times, summed far longer than its silence (the watch
    once excused it all: 4 of 4 runs not judged in 10 s), but the spinner has had the CPU for the freeze's time
    without a beat: judged frozen and killed (with two hogs beside it, 2-4 s in)."""
    frozen_on_cpu0(cpu0_shared(2), SPIN_IN_C, 20.0)
