"""A host that does not run for a while (a loaded machine deschedules it; here SIGSTOP) is not taken for a plate
that fell silent: the plate driver's writer sees the stall wherever it came (asleep, pulling, making frames, not a
write that waited for room on the port, which is the link's), starts its silence check again and says it stalled.
Before, only a stall that came while the writer slept was seen: one that came while it worked left the plate's
telemetry unread for 0.5 s, and the run ended "the plate was lost" (exit status 4; tests/test_counter_check.py
failed so beside two CPU hogs)."""

import json
import os
import random
import re
import signal
import subprocess
import sys
import time

from conftest import ROOT
from test_exits import DEADLINE_S

STOPS = 12  # each 0.55-0.8 s, longer than the host's 0.5 s silence check


def stalled_host(stimulus) -> dict:
    """Run tests/stalled_host.py, apply ``stimulus(pid)`` once it is ready, stop it (SIGTERM); returns its status."""
    host = subprocess.Popen([sys.executable, str(ROOT / "tests" / "stalled_host.py")], stdout=subprocess.PIPE,
                            text=True, cwd=ROOT)
    try:
        assert host.stdout.readline().strip() == "ready"
        stimulus(host.pid)
        host.send_signal(signal.SIGTERM)
        return json.loads(host.communicate(timeout=DEADLINE_S)[0].splitlines()[-1])
    finally:
        if host.poll() is None:
            os.kill(host.pid, signal.SIGCONT)
            host.kill()
            host.communicate()


def stop_for(pid: int, seconds: float) -> None:
    """SIGSTOP ``pid`` for ``seconds``, then SIGCONT (whatever happens meanwhile)."""
    os.kill(pid, signal.SIGSTOP)
    try:
        time.sleep(seconds)
    finally:
        os.kill(pid, signal.SIGCONT)


def test_a_host_stopped_again_and_again_never_takes_its_plate_for_lost():
    stopped_s = []
    shuffle = random.Random(7)

    def stimulus(pid):  # the host and its plate run 5-80 ms, then are stopped 0.55-0.8 s
        for _ in range(STOPS):
            time.sleep(shuffle.uniform(0.005, 0.08))
            began = time.perf_counter()
            stop_for(pid, shuffle.uniform(0.55, 0.8))
            stopped_s.append(time.perf_counter() - began)

    status = stalled_host(stimulus)
    lines = status["report"]["lines"]
    assert status["silences"] == 0 and status["disconnects"] == 0, lines  # never lost
    assert status["report"]["exit_status"] == 0, lines  # a clean run that says the host stalled
    said = [line for line in lines if line.startswith("the host stalled")]
    assert len(said) == 1, lines
    # seen: at least one stall (two stops with no turn of the writer between them are one), the longest at least
    # the shortest stop and at most all of them with the runs between
    assert 1 <= status["host_stalls"] <= STOPS, status["host_stalls"]
    longest = float(re.search(r"longest (\d+\.\d+) s", said[0]).group(1))
    assert min(stopped_s) - 0.01 <= longest <= sum(stopped_s) + STOPS * 0.1, (longest, stopped_s)


def test_a_plate_silent_between_host_stalls_is_still_found_silent():
    """Stalls move the silence check on by their own length, not start it again: a plate that falls silent while
    its host is stopped for 0.1 s every 0.35 s (more often than the check's 0.5 s) is found silent all the same.
    Had each stall started the check again, the host would never have found it (it is stopped to the end)."""
    def stimulus(pid):
        os.kill(pid, signal.SIGUSR1)  # the plate sends no more telemetry
        for _ in range(12):  # 0.25 s running, 0.1 s stopped, over 4 s
            time.sleep(0.25)
            stop_for(pid, 0.1)

    status = stalled_host(stimulus)
    lines = status["report"]["lines"]
    assert status["silences"] >= 1 and status["disconnects"] >= 1, (status["host_stalls"], lines)
    assert status["report"]["exit_status"] == 4, lines  # the plate lost
