"""The stop signals' handler (``apps.cli.signals``), with real signals to this process and to child processes.

A stop signal raises ``Stopped`` in the main thread, but not where the exception would break something: inside a
block held for clean-up, inside ``threading``'s own handling of a lock (it would stay held for good, or be released
under another thread) and inside a finaliser (Python drops the exception there and the command goes on).
"""

import json
import linecache
import os
import random
import signal
import subprocess
import sys
import threading
import time

import pytest
from conftest import ROOT, wait_for
from ultraglide.apps.cli.signals import Stopped, StopSignals, held, in_a_finaliser, passing_a_lock

STOP_SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP]
DEADLINE_S = 60.0  # generous: the suite runs on a loaded 2-core machine


def wait_until(condition, what, timeout=DEADLINE_S):
    if not wait_for(condition, timeout):
        raise AssertionError(f"timed out waiting for {what}")


# ---- the handler itself, with real signals to this process ------------------------------------------------
def test_signals_wait_for_a_held_block_a_burst_is_ignored_and_a_later_one_raises_again():
    before = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    stop = StopSignals(grace_s=0.5)
    assert stop.install()

    def let_handlers_run():
        for _ in range(50):
            time.sleep(0.001)

    try:
        reached_end_of_block = False
        with pytest.raises(Stopped) as caught:
            with held():
                os.kill(os.getpid(), signal.SIGTERM)
                let_handlers_run()
                reached_end_of_block = True
        first_s = time.monotonic()
        assert reached_end_of_block  # the signal waited for the held block, then raised
        assert caught.value.signum == signal.SIGTERM and caught.value.exit_status == 143
        os.kill(os.getpid(), signal.SIGINT)  # right after the first, outside any held block: a burst, ignored
        let_handlers_run()
        assert time.monotonic() - first_s < stop.grace_s  # (the test's own premise)
        wait_until(lambda: time.monotonic() - first_s > stop.grace_s, "the grace period to pass", timeout=10)
        with pytest.raises(Stopped) as again:  # a later signal stops again, named after the first
            os.kill(os.getpid(), signal.SIGHUP)
            let_handlers_run()
        assert again.value.signum == signal.SIGTERM
    finally:
        stop.restore()
        ignored = [signal.getsignal(signum) for signum in STOP_SIGNALS]
        for signum, handler in before.items():  # this test process goes on: its own handlers back
            signal.signal(signum, handler)
    assert ignored == [signal.SIG_IGN] * 3  # once stopped, a process stays stopping until it has exited
    stop = StopSignals()
    stop.install()
    stop.restore()  # no signal came: the previous handlers are back
    assert {signum: signal.getsignal(signum) for signum in STOP_SIGNALS} == before


# a main thread waiting on a queue whose lock another thread holds most of the time (20 ms of every 20.5 ms): a stop
# raised while the wait re-takes that lock released it under its holder ("release unlocked lock" there), and
# could leave it held by nobody, after which both threads wait on it for ever (plate-sim did, once)
QUEUE_WAITER = r"""
import json, queue, signal, threading, time
from ultraglide.apps.cli.signals import StopSignals, Stopped
stop = StopSignals()
stop.install()
events = queue.Queue()
broken = []
done = threading.Event()
def hold_the_lock():
    try:
        while not done.is_set():
            with events.mutex:
                time.sleep(0.02)
            time.sleep(0.0005)
    except RuntimeError as error:
        broken.append(repr(error))
holder = threading.Thread(target=hold_the_lock, daemon=True)
holder.start()
print("waiting", flush=True)
try:
    while True:
        try:
            events.get(timeout=0.005)
        except queue.Empty:
            pass
except Stopped as stopped:
    time.sleep(0.1)  # the holder's next turns: a lock released under it fails there
    done.set()  # then the holder lets go (a whole lock is free once it has; a lock left held by nobody is not):
    holder.join(timeout=5)  # taking it while the holder still turns could be starved on a loaded machine
    taken = events.mutex.acquire(timeout=5)
    alarm_back = signal.getsignal(signal.SIGALRM) is signal.SIG_DFL  # the retries' handler gone with the stop
    print(json.dumps({"status": stopped.exit_status, "broken": broken, "lock_taken": taken, "alarm_back": alarm_back}),
          flush=True)
"""


def test_a_stop_that_finds_the_main_thread_waiting_on_a_busy_queue_leaves_its_lock_whole():
    for attempt in range(6):
        waiter = subprocess.Popen([sys.executable, "-c", QUEUE_WAITER], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, cwd=ROOT)
        try:
            assert waiter.stdout.readline().strip() == "waiting", waiter.stderr.read()
            time.sleep(random.uniform(0.05, 0.2))  # (the stimulus: a signal at some moment of the wait)
            waiter.send_signal(signal.SIGTERM)
            out, err = waiter.communicate(timeout=DEADLINE_S)
        finally:
            waiter.kill()
        said = json.loads(out.strip().splitlines()[-1])
        assert said == {"status": 143, "broken": [], "lock_taken": True, "alarm_back": True}, (attempt, said, err)




# ---- where a stop is put off --------------------------------------------------------------------------------
def test_threadings_lock_handling_is_no_place_for_a_stop_but_its_blocking_waits_are():
    entered = []

    def note_condition_entered(frame, event, arg):
        if event == "c_return" and frame.f_code is threading.Condition.__enter__.__code__:
            entered.append(frame)  # the lock is taken, Condition.__enter__ has not returned yet

    condition = threading.Condition()
    sys.setprofile(note_condition_entered)
    try:
        with condition:
            pass
    finally:
        sys.setprofile(None)
    assert entered and passing_a_lock(entered[0])
    assert not passing_a_lock(sys._getframe())

    never = threading.Event()
    waiting = threading.Thread(target=never.wait, daemon=True)
    waiting.start()
    joining = threading.Thread(target=waiting.join, daemon=True)
    joining.start()

    def blocked_in(thread, function, call):
        """The thread's innermost frame once it blocks on ``call`` (by the source line) in ``function``; else None."""
        frame = sys._current_frames().get(thread.ident)
        if frame is None or frame.f_code is not function.__code__:
            return None
        return frame if call in linecache.getline(frame.f_code.co_filename, frame.f_lineno) else None

    assert wait_for(lambda: blocked_in(waiting, threading.Condition.wait, "waiter.acquire(") is not None)
    assert wait_for(lambda: blocked_in(joining, threading.Thread._wait_for_tstate_lock, "lock.acquire(") is not None)
    assert not passing_a_lock(blocked_in(waiting, threading.Condition.wait, "waiter.acquire("))
    assert not passing_a_lock(blocked_in(joining, threading.Thread._wait_for_tstate_lock, "lock.acquire("))
    never.set()
    joining.join(timeout=DEADLINE_S)


def test_a_finaliser_is_no_place_for_a_stop():
    seen = {}

    class Noted:
        def __del__(self):
            seen["inside"] = in_a_finaliser(sys._getframe())
            seen["below"] = in_a_finaliser(sys._getframe(1))  # (the frame the collector interrupted)

    def drop():
        Noted()

    drop()
    assert seen == {"inside": True, "below": False}
    assert not in_a_finaliser(sys._getframe()) and not in_a_finaliser(None)


# rounds of a main thread busy with a queue's lock and with finalisers, each stopped by a SIGTERM at some moment: a
# stop raised as a condition had taken its lock left the lock held by the main thread for good (plate-sim then hung
# on its event queue in its clean-up); one raised inside a __del__ was printed as "Exception ignored" and dropped
STOPPED_ROUNDS = r"""
import json, os, queue, random, signal, sys, threading, time
from ultraglide.apps.cli.signals import StopSignals, Stopped
rounds = int(sys.argv[1])
leaked = dropped = 0
class Noted:
    def __del__(self):
        pass
for _ in range(rounds):
    stop = StopSignals(grace_s=0.0)
    stop.install()
    events = queue.Queue()
    started_s = time.monotonic()
    try:  # (a loaded machine may run the timer before start() has returned)
        threading.Timer(random.uniform(0.001, 0.01), os.kill, (os.getpid(), signal.SIGTERM)).start()
        while time.monotonic() - started_s < 10:  # a stop that never comes: one dropped
            try:
                events.get_nowait()
            except queue.Empty:
                pass
            Noted()
        dropped += 1
    except Stopped:
        pass
    stop.restore()
    alarm_back = signal.getsignal(signal.SIGALRM) is signal.SIG_DFL
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)
    if events.mutex.acquire(timeout=0):
        events.mutex.release()
    else:
        leaked += 1
    if not alarm_back:
        break
print(json.dumps({"leaked": leaked, "dropped": dropped, "alarm_back": alarm_back}), flush=True)
"""


def test_a_stop_leaves_no_lock_taken_and_is_not_dropped_by_a_finaliser():
    rounds = 60  # before the fix, 300 rounds left the lock taken in 34 and dropped the stop in 111
    result = subprocess.run([sys.executable, "-c", STOPPED_ROUNDS, str(rounds)], capture_output=True, text=True,
                            cwd=ROOT, timeout=600)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == {"leaked": 0, "dropped": 0, "alarm_back": True}
    assert "Exception ignored" not in result.stderr, result.stderr
