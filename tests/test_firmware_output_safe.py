"""The core's output-safe duty (``ug_port_output_safe`` in include/ug_port.h), through the software-in-the-loop
build: the core asks its port for a silent output whenever the output goes off (a host's DISABLE, a trip), and
when the protocol watchdog's ramp reaches zero, and not while it plays; the port (here the simulator's) counts
the calls. The boards' answer to the call (both DAC halves to mid-scale) is in test_firmware_board.py."""

from __future__ import annotations

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware import sil

PER_MS = 48  # drive samples a millisecond at the reference 48 kHz
SAFE_DISABLE, SAFE_RAMP_END = 1, 2  # ug_port.h UG_SAFE_*


class Core:
    def __init__(self):
        self.core = sil.FirmwareCore()
        self.seq = 0

    def send(self, kind: int, payload: bytes = b"") -> None:
        self.seq += 1
        self.core.receive(p.encode_frame(kind, self.seq, payload))
        self.core.transmit()

    def run(self, ms: int, measured: float = 0.0) -> np.ndarray:
        drive = []
        for _ in range(ms):
            drive.append(self.core.render(PER_MS).copy())
            self.core.sense(np.full(PER_MS, measured, dtype=np.float32))
            self.core.transmit()
        return np.concatenate(drive)


def test_disable_asks_for_a_silent_output_and_playing_does_not():
    core = Core()
    core.send(p.ENABLE, p.enable_payload(True))
    calls, _ = core.core.output_safe_calls()
    core.send(p.SETPOINTS, p.setpoints_payload(0, 12000, np.full(240, 0.5)))
    drive = core.run(15)
    assert drive.max() > 0.4  # it plays ...
    assert core.core.output_safe_calls()[0] == calls  # ... and asked for nothing
    core.send(p.ENABLE, p.enable_payload(False))
    assert core.core.output_safe_calls() == (calls + 1, SAFE_DISABLE)
    assert core.run(2).max() == 0.0


def test_a_trip_asks_for_a_silent_output_at_once():
    core = Core()
    core.send(p.ENABLE, p.enable_payload(True))
    core.send(p.SETPOINTS, p.setpoints_payload(0, 12000, np.full(240, 0.5)))
    core.run(12)
    before = core.core.output_safe_calls()[0]
    core.run(1, measured=7.0)  # above the sim-plate's trip (6 µm p-p limit x 1.01)
    assert not core.core.status().enabled
    assert core.core.output_safe_calls() == (before + 1, SAFE_DISABLE)


def test_the_watchdogs_ramp_ends_in_a_call_for_a_silent_output():
    core = Core()
    core.send(p.ENABLE, p.enable_payload(True))
    core.send(p.SETPOINTS, p.setpoints_payload(0, 12000, np.full(240, 0.6)))
    before = core.core.output_safe_calls()[0]
    core.run(110)  # the watchdog fires at 100 ms and ramps for 20 ms
    assert core.core.output_safe_calls()[0] == before
    drive = core.run(15)
    assert core.core.output_safe_calls() == (before + 1, SAFE_RAMP_END)
    assert drive[-PER_MS:].max() == 0.0


def test_lost_block_time_keeps_the_clock_and_the_watchdog_and_is_counted():
    core = Core()
    core.send(p.ENABLE, p.enable_payload(True))
    core.send(p.SETPOINTS, p.setpoints_payload(0, 12000, np.full(240, 0.6)))
    core.run(10)
    now = core.core.status().now_ms
    core.core.lose_time(2)  # a late block interrupt: two blocks whose time passed unplayed
    status = core.core.status()
    assert status.lost_ms == 2 and status.now_ms == now + 2
    assert status.samples == now * PER_MS  # no drive sample was made for them
    core.core.lose_time(88)  # 100 ms since the last frame, counting the lost time: the protocol watchdog fires
    assert core.core.status().fault_counts[0] == 1 and core.core.status().lost_ms == 90
