"""The simulated plate in its own process, in real time where allowed, timing when its amplitude crosses a
level: for tests that measure a host's latency by the plate's account, whatever load the test process has.

    python tests/sim_crossings.py LINK LEVEL_UM_PP

Serves ``PtyPlate`` (sim-plate) at LINK, prints ``ready`` once the link exists, polls the plate's amplitude
every 0.5 ms and notes each crossing of LEVEL (perf_counter s: the system's monotonic clock, comparable
across processes); on SIGTERM prints ``{"crossings": [...], "faults": {...}}`` as one JSON line.
"""

import json
import os
import sys
import time

from stop_flag import stop_on_sigterm
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.pty_plate import PtyPlate


def main() -> None:
    link, level = sys.argv[1], float(sys.argv[2])
    try:  # the plate keeps real time however loaded the machine (its threads inherit the policy)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(40))
    except (OSError, AttributeError):
        pass
    stopped = stop_on_sigterm()
    plate = PtyPlate(load_profile("sim-plate"), link).start()
    sim = plate.simulator
    print("ready", flush=True)
    crossings = []
    previous = sim.amplitude_um_pp
    while not stopped:
        time.sleep(0.0005)
        now = sim.amplitude_um_pp
        if (previous - level) * (now - level) < 0:
            crossings.append(time.perf_counter())
        previous = now
    plate.stop()
    print(json.dumps({"crossings": crossings, "faults": sim.fault_counts()}), flush=True)


if __name__ == "__main__":
    main()
