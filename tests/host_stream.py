"""A host streaming a square wave to a plate on a serial port, in its own process, so that a test can stop it
(SIGSTOP) and see what the plate gets when it resumes:

    python tests/host_stream.py PORT LOW_UM_PP HIGH_UM_PP HALF_PERIOD_S

The drive is LOW while ``int(t / HALF_PERIOD_S)`` is even and HIGH while it is odd, ``t`` being the
perf_counter time the writer pulls it (the system's monotonic clock, comparable across processes): an edge
at every multiple of the half period, as a touch that reaches the host then. Prints ``ready`` once streaming;
on SIGTERM stops the driver (ramp, zero, disable) and prints its status as one JSON line.
"""

import sys
import time

import numpy as np
from stop_flag import drive_until_sigterm
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.serial.plate import SerialPlate
from ultraglide.render.engine.realtime import threads_started_in_real_time


class Square:
    def __init__(self, low, high, half_s):
        self.low, self.high, self.half_s = low, high, half_s
        self.stopping = False

    def pull(self, n, now_s):
        if self.stopping:
            return np.zeros(n)
        return np.full(n, self.high if int(time.perf_counter() / self.half_s) % 2 else self.low)

    def request_stop(self):
        self.stopping = True

    @property
    def finished(self):
        return self.stopping


def main() -> None:
    port, low, high, half = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    driver = SerialPlate(port, load_profile("sim-plate"), ack_timeout_s=10)
    # the driver's writer and reader in real time where allowed, at the priority the engine gives them (SCHED_FIFO
    # 1), from the block's end on; this thread, which only waits, and the start-up and exit stay ordinary: a whole
    # process at a priority above the engine's threads once held another test's engine off its CPU for 140 ms
    with threads_started_in_real_time():
        driver.start(Square(low, high, half))
    drive_until_sigterm(driver)


if __name__ == "__main__":
    main()
