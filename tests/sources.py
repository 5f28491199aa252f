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
