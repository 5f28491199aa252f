"""The simulated plate in its own process, recording its own amplitude: for tests that judge what a plate
delivered by the plate's account rather than the host's.

    python tests/sim_recorder.py LINK RESONANCE_HZ Q DRIFT_HZ_PER_S RECORD.json

Serves ``PtyPlate`` (sim-plate profile, the given physical truth) at LINK, prints ``ready`` once the
link exists (with the perf_counter time its clock counts from), samples the simulator's amplitude
every 5 ms until SIGTERM, then writes
``{"record": [[t_s, amplitude_um_pp, resonance_hz, drive_um_pp], ...], "events": [...]}`` to RECORD.json,
where drive_um_pp is the setpoint the plate was playing (its amplitude at resonance, once settled).
"""

import json
import sys
import time

from stop_flag import stop_on_sigterm
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.plate import PlateTruth
from ultraglide.devices.sim.pty_plate import PtyPlate


def main() -> None:
    link, resonance_hz, q, drift, output = sys.argv[1:6]
    stopped = stop_on_sigterm()
    profile = load_profile("sim-plate")
    plate = PtyPlate(profile, link, PlateTruth(float(resonance_hz), float(q), float(drift))).start()
    sim = plate.simulator
    record, events = [], []
    print(f"ready {sim._started!r}", flush=True)  # perf_counter is the system's monotonic clock: comparable
    while not stopped:
        time.sleep(0.005)
        now = sim.elapsed_s()
        drive = sim.drive_um_pp  # after the firmware's limiter, the watchdog's ramp included
        record.append((now, sim.amplitude_um_pp, sim.truth.resonance_at(now), drive))
        for _ in range(sim.events.qsize()):  # what is there now: a storm of events (a burst of overruns) coming
            events.append(sim.events.get_nowait())  # faster than this takes them must not keep it from SIGTERM
    plate.stop()
    while not sim.events.empty():
        events.append(sim.events.get())
    with open(output, "w") as stream:
        json.dump({"record": record, "events": events}, stream)


if __name__ == "__main__":
    main()
