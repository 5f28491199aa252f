"""Envelope sources the tests stream from: the one definition each (a device pulls them as it would a renderer)."""

from __future__ import annotations

import numpy as np


class Constant:
    """A steady drive (µm p-p) that ramps to rest when asked, by ``ramp_um_pp`` a value; counts what was pulled."""

    def __init__(self, amplitude_um_pp: float = 3.0, ramp_um_pp: float = 0.01):
        self.amplitude = amplitude_um_pp
        self.ramp_um_pp = ramp_um_pp
        self.stopping = False
        self.pulled = 0

    def pull(self, n, now_s):
        self.pulled += n
        if self.stopping:
            self.amplitude = max(0.0, self.amplitude - self.ramp_um_pp * n)
        return np.full(n, self.amplitude)

    def request_stop(self):
        self.stopping = True

    @property
    def finished(self):
        return self.stopping and self.amplitude == 0.0


class Pulses:
    """A drive that pulses: ``on_values`` values of ``amplitude_um_pp`` every ``period_values`` (by the stream's
    count), zeros between; ends at once when asked to stop. At 12 kHz, 120 and 24: 2 ms pulses at 100 Hz, as a
    plan pulses the plate once a period of a 1 mm grating swept at 100 mm/s."""

    def __init__(self, amplitude_um_pp: float = 4.0, period_values: int = 120, on_values: int = 24):
        self.amplitude, self.period, self.on = amplitude_um_pp, period_values, on_values
        self.stopping = False
        self.pulled = 0

    def pull(self, n, now_s):
        index = self.pulled + np.arange(n)
        self.pulled += n
        if self.stopping:
            return np.zeros(n)
        return np.where(index % self.period < self.on, self.amplitude, 0.0)

    def request_stop(self):
        self.stopping = True

    @property
    def finished(self):
        return self.stopping
