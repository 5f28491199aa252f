"""The simulated plate on a real pty, every frame it decodes kept: for tests of what a host sends a plate.

``tap`` (tests/conftest.py) serves one for a test and stops it after.
"""

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.pty_plate import PtyPlate


class PlateTap:
    """The simulated plate on a real pty, and every frame it decodes, in order, with its watchdog count then."""

    def __init__(self):
        self.plate = PtyPlate(load_profile("sim-plate")).start()
        self.frames = []  # (kind, payload, watchdog trips so far)
        simulator = self.plate.simulator
        receive, decoder = simulator.receive, p.FrameDecoder()

        def tapped(data):
            replies = receive(data)
            for frame in decoder.feed(data):
                self.frames.append((frame.kind, frame.payload, simulator.counters.watchdog_trips))
            return replies

        simulator.receive = tapped

    def setpoint_frames(self):
        return [p.parse_setpoints(payload)[2] for kind, payload, _ in list(self.frames) if kind == p.SETPOINTS]

    def assert_rested_by_the_host(self):
        """Zero setpoints, then disable, received before the link closed, the watchdog never needed."""
        frames = list(self.frames)
        disables = [i for i, (kind, payload, _) in enumerate(frames)
                    if kind == p.ENABLE and payload == p.enable_payload(False)]
        assert disables, "the plate never received DISABLE"
        last = disables[-1]
        enables = [i for i, (kind, payload, _) in enumerate(frames[:last])
                   if kind == p.ENABLE and payload == p.enable_payload(True)]
        assert enables, "the plate was never enabled"
        # (the simulator counts a trip for the silence before the host connects: only the session counts)
        assert frames[last][2] == frames[enables[-1]][2], "the watchdog fired before the host rested the plate"
        setpoints = [p.parse_setpoints(payload)[2] for kind, payload, _ in frames[:last] if kind == p.SETPOINTS]
        assert setpoints and max(np.max(values) for values in setpoints) > 0.01  # it was driving
        assert np.all(setpoints[-1] == 0.0), "the last setpoints before DISABLE were not zero"
        assert not any(kind == p.SETPOINTS and np.any(p.parse_setpoints(payload)[2] > 0)
                       for kind, payload, _ in frames[last:])
        assert not self.plate.simulator.enabled

    def disables(self) -> list[int]:
        """The positions in :attr:`frames` of every ENABLE 0 the plate decoded, in order."""
        return [i for i, (kind, payload, _) in enumerate(list(self.frames))
                if kind == p.ENABLE and payload == p.enable_payload(False)]

    def close(self):
        self.plate.stop()
