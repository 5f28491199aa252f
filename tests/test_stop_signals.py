"""The stop signals' handler (``apps.cli.signals``), with real signals to this process and to child processes.

A stop signal raises ``Stopped`` in the main thread, but not where the exception would break something: inside a
block held for clean-up, or while a wait takes its condition's lock back.
"""

import json
import os
import random
import signal
import subprocess
import sys
import time

import pytest
from conftest import ROOT, wait_for
from ultraglide.apps.cli.signals import Stopped, StopSignals, held

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



