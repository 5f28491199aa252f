"""The engine's process hygiene (render/engine/realtime.py), read back from the kernel's own accounts in /proc:
huge pages off for the engine and the app beside it, so khugepaged has nothing of ours to collapse."""

import json
import os
import re
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import ROOT, may_run_in_real_time, wait_for

THP_MODE = Path("/sys/kernel/mm/transparent_hugepage/enabled")

# Run in a fresh interpreter: the setting is per process and inherited, so the test process stays as it was.
# Each starts as a fresh app would: huge pages as the system has them (a test process that started an
# engine has them off, and its children inherit that).
FRESH = "import ctypes; ctypes.CDLL(None).prctl(41, 0, 0, 0, 0)\n"  # PR_SET_THP_DISABLE, 0
PROBE = FRESH + """
import json, subprocess, sys
import numpy as np

def thp_enabled(pid="self"):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("THP_enabled:"):
            return int(line.split()[1])

def huge_kib(array):
    # AnonHugePages of the mappings that hold the array (numpy madvises arrays of 4 MiB or more, which
    # splits malloc's mapping: the first page apart, the aligned rest marked for huge pages)
    start = array.__array_interface__["data"][0]
    end = start + array.nbytes
    mine, total = False, 0
    for line in open("/proc/self/smaps"):
        fields = line.split()
        if "-" in fields[0] and ":" not in fields[0]:
            low, high = (int(x, 16) for x in fields[0].split("-"))
            mine = low < end and start < high
        elif mine and fields[0] == "AnonHugePages:":
            total += int(fields[1])
    return total

if sys.argv[1] == "off":
    from ultraglide.render.engine.realtime import keep_huge_pages_out
    said = keep_huge_pages_out()
else:
    said = ""
array = np.ones(64 << 20, dtype=np.uint8)  # 64 MiB, written: every page faulted in
ASK = "print(open('/proc/self/status').read().split('THP_enabled:')[1].split()[0])"
child = subprocess.run([sys.executable, "-c", ASK], capture_output=True, text=True).stdout.strip()
print(json.dumps({"said": said, "thp_enabled": thp_enabled(), "child": int(child), "huge_kib": huge_kib(array)}))
"""

ENGINE = FRESH + """
import json, sys
from ultraglide.render.engine import Engine, EngineConfig
def thp_enabled(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("THP_enabled:"):
            return int(line.split()[1])
realtime = sys.argv[1] == "realtime"
with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=realtime)) as engine:
    engine.wait_ready(120)
    pid = engine.info["pid"]
    figures = {"app": thp_enabled("self"), "engine": thp_enabled(pid)}
    import time
    deadline = time.monotonic() + 60
    while "huge pages" not in engine.status().priority and time.monotonic() < deadline:
        time.sleep(0.02)
    figures["priority"] = engine.status().priority
print(json.dumps(figures))
"""

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists() or "THP_enabled" not in
                                Path("/proc/self/status").read_text(), reason="needs Linux 5.0+ (/proc THP_enabled)")


def probe(*args: str, script: str = PROBE) -> dict:
    result = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, cwd=ROOT,
                            timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    return json.loads(result.stdout.splitlines()[-1])


def test_huge_pages_off_for_the_process_and_its_children():
    off = probe("off")
    assert off["said"] == "huge pages off"
    assert off["thp_enabled"] == 0 and off["child"] == 0  # the kernel's word, for it and what it starts
    assert off["huge_kib"] == 0  # a 64 MiB numpy array sits in ordinary pages


def test_without_it_numpy_arrays_get_huge_pages():
    """The control: on this kernel the same array would be in huge pages (what khugepaged works on)."""
    mode = THP_MODE.read_text() if THP_MODE.exists() else "[never]"
    if "[never]" in mode:
        pytest.skip("transparent huge pages are off on this system: nothing to keep out")
    on = probe("on")
    assert on["thp_enabled"] == 1 and on["child"] == 1
    if on["huge_kib"] == 0:
        pytest.skip("the kernel found no free huge page for the control array just now (fragmented memory)")
    assert on["huge_kib"] >= 2048


def test_engine_turns_huge_pages_off_for_itself_and_the_app():
    figures = probe("realtime", script=ENGINE)
    assert (figures["app"], figures["engine"]) == (0, 0)  # THP_enabled, the kernel's word for each process
    assert "huge pages off" in figures["priority"]


def test_engine_without_realtime_leaves_huge_pages_alone():
    figures = probe("plain", script=ENGINE)
    assert figures["app"] == 1 and figures["engine"] == 1
    assert "huge pages: as the system has them" in figures["priority"]


def qos_fds(pid: int) -> int:
    """How many of a process's open files are the CPU latency request (the kernel's view, /proc/PID/fd)."""
    count = 0
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            count += os.readlink(fd) == "/dev/cpu_dma_latency"
        except OSError:
            continue
    return count


def cpu_latency_target_us() -> int:
    """The kernel's aggregate of every process's request (2e9: none)."""
    return struct.unpack("=i", Path("/dev/cpu_dma_latency").read_bytes()[:4])[0]


@pytest.mark.skipif(not os.access("/dev/cpu_dma_latency", os.W_OK), reason="needs write access to /dev/cpu_dma_latency")
def test_engine_keeps_cpus_quick_to_wake_only_while_rendering():
    from ultraglide.render.engine import Engine, EngineConfig

    def until(condition, what):
        deadline = time.monotonic() + 60
        while not condition():
            assert time.monotonic() < deadline, f"not within 60 s: {what}"
            time.sleep(0.01)

    def times(n):
        return f"{n} {'time' if n == 1 else 'times'},"

    with Engine.start(EngineConfig(texture="grating-1mm", device="null", start_paused=True)) as engine:
        engine.wait_ready(120)
        pid = engine.info["pid"]
        until(lambda: engine.status().resting_blocks > 0 and qos_fds(pid) == 0, "paused at rest, no request")
        # a paused engine renders its first blocks until it is at rest: on a loaded machine the command loop
        # may see those and hold once before this (the count goes on from there, one more a stretch)
        until(lambda: "(released; " in engine.status().priority, "said in the status")
        before = int(re.search(r"\(released; (\d+) time", engine.status().priority).group(1))
        engine.pause(False)
        engine.touch(time.perf_counter(), 40.0, 25.0)
        until(lambda: qos_fds(pid) == 1, "a request while rendering")
        assert cpu_latency_target_us() == 0  # the kernel now keeps every idle CPU polling
        until(lambda: f"CPU wake-up within 0 µs while rendering (held; {times(before + 1)}"
              in engine.status().priority, "said in the status")
        engine.pause(True)
        until(lambda: qos_fds(pid) == 0, "released at rest again")
        until(lambda: f"(released; {times(before + 1)}" in engine.status().priority, "said in the status")
        final = engine.stop()
    assert f"CPU wake-up within 0 µs while rendering (released; {times(before + 1)}" in final.priority  # the account


def test_a_refused_request_is_said_and_nothing_is_held():
    """As an unprivileged user the file cannot be opened: no request, and the words say why."""
    if os.geteuid() != 0 and os.access("/dev/cpu_dma_latency", os.W_OK):
        pytest.skip("this user may write the request")
    drop = "import os; os.setgroups([]); os.setgid(65534); os.setuid(65534)\n" if os.geteuid() == 0 else ""
    script = ("from ultraglide.render.engine.realtime import CpuWakeLatency\n" + drop +  # imported first, then nobody
              "w = CpuWakeLatency(0); w.hold(True); print(w.held, '|', w.words())")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    held, words = result.stdout.strip().split(" | ")
    assert held == "False"
    assert words == "CPU wake-up: as the system has it (Permission denied)"


def test_no_request_when_not_asked():
    from ultraglide.render.engine.realtime import CpuWakeLatency

    wake = CpuWakeLatency(None)
    wake.hold(True)
    assert not wake.held and qos_fds(os.getpid()) == 0
    assert wake.words() == "CPU wake-up: as the system has it (not asked)"


def test_threads_started_in_real_time_run_there_from_the_blocks_end_and_their_starter_never_does():
    """The threads a block starts are raised when it ends; the block's own work (a device's set-up) stays ordinary."""
    import threading

    from ultraglide.render.engine.realtime import threads_started_in_real_time

    seen, at_start, after_block = {}, [], []
    block_ended = threading.Event()

    def scheduling():
        return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority

    def started():
        at_start.append(scheduling())
        assert block_ended.wait(timeout=60)
        after_block.append(scheduling())

    def starter():  # on a thread of its own: the test worker's threads keep their scheduling
        seen["before"] = scheduling()
        with threads_started_in_real_time() as words:
            thread = threading.Thread(target=started)
            thread.start()
            assert wait_for(lambda: at_start, timeout=60)
            seen["inside"] = scheduling()  # the set-up's work, after a thread was started
        block_ended.set()
        thread.join()
        seen["words"], seen["after"] = words, scheduling()
        late = threading.Thread(target=started)  # started after the block: ordinary
        late.start()
        late.join()

    worker = threading.Thread(target=starter)
    worker.start()
    worker.join()
    ordinary = (os.SCHED_OTHER, 0)
    assert seen["before"] == seen["inside"] == seen["after"] == ordinary
    assert at_start == [ordinary, ordinary]  # inside the block, and the late one
    if may_run_in_real_time():
        assert seen["words"] == "SCHED_FIFO 1" and after_block[0] == (os.SCHED_FIFO, 1)
    else:
        assert seen["words"] == "normal (no permission to raise it)" and after_block[0] == ordinary
    assert after_block[1] == ordinary  # started after the block: never raised
