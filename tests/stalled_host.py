"""A host and the plate it drives (a scripted plate on a real pty) in one process of their own, so that a test can
stop the whole of it (SIGSTOP, as a loaded machine deschedules a process) and see what the host makes of it:

    python tests/stalled_host.py

Streams a constant drive to a :class:`scripted_plate.ScriptedPlate` (telemetry 50 times a second, ``enabled``
as the host last set it), prints ``ready`` once the host has had 10 telemetry frames; on SIGUSR1 the plate falls
silent (no telemetry from then on); on SIGTERM stops the driver and prints its status (:meth:`SerialPlate.status`)
as one JSON line.
"""

import signal

from conftest import wait_for
from scripted_plate import PROFILE, ScriptedPlate
from sources import Constant
from stop_flag import drive_until_sigterm
from ultraglide.devices.serial.plate import SerialPlate


def main() -> None:
    with ScriptedPlate(enabled_follows=True) as plate:
        signal.signal(signal.SIGUSR1, lambda *_: setattr(plate, "telemetry", False))
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.start(Constant(1.0))
        if not wait_for(lambda: driver.telemetry_frames >= 10, timeout=60.0):
            raise SystemExit("the host had no telemetry from the scripted plate within 60 s")
        drive_until_sigterm(driver)


if __name__ == "__main__":
    main()
