"""The simulated plate in its own process, in real time where allowed (SCHED_FIFO 1, as the engine's device
threads), timing when its amplitude crosses a level: for tests that measure a host's latency by the plate's
account, whatever load the test process has.

    python tests/sim_crossings.py LINK LEVEL_UM_PP

Serves ``PtyPlate`` (sim-plate) at LINK, prints ``ready`` once the link exists, polls the plate's amplitude
every 0.5 ms and notes each crossing of LEVEL (perf_counter s: the system's monotonic clock, comparable
across processes); on SIGTERM prints ``{"crossings": [...], "faults": {...}}`` as one JSON line.
"""

import json
import sys
import threading
import time

from stop_flag import stop_on_sigterm
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.pty_plate import PtyPlate
from ultraglide.render.engine.realtime import threads_started_in_real_time


def main() -> None:
    link, level = sys.argv[1], float(sys.argv[2])
    stopped = stop_on_sigterm()
    crossings = []
    done = threading.Event()

    def poll():
        previous = sim.amplitude_um_pp
        while not done.is_set():
            time.sleep(0.0005)
            now = sim.amplitude_um_pp
            if (previous - level) * (now - level) < 0:
                crossings.append(time.perf_counter())
            previous = now

    # the plate's threads and the poller in real time where allowed, at the priority the engine gives its device's
    # threads (SCHED_FIFO 1), from the block's end on; the set-up and the exit stay ordinary: a whole process at a
    # priority above the engine's threads once held another test's engine off its CPU for 100 ms while it exited
    with threads_started_in_real_time():
        plate = PtyPlate(load_profile("sim-plate"), link).start()
        sim = plate.simulator
        poller = threading.Thread(target=poll)
        poller.start()
    print("ready", flush=True)
    while not stopped:
        time.sleep(0.01)
    done.set()
    poller.join()
    plate.stop()
    print(json.dumps({"crossings": crossings, "faults": sim.fault_counts()}), flush=True)


if __name__ == "__main__":
    main()
