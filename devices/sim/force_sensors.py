"""The force sensors under the simulated plate: what they make of the finger's normal and lateral force.

Each of the two channels is a first-order low-pass (``bandwidth_hz``, the sensor's and its amplifier's),
then a pure delay (``delay_s``: the conditioning electronics and converter), then white noise of
``noise_n`` rms per sensor sample (held over each of the device's sensor periods, ``sensor_rate_hz``, so
that the device's average over a period, which is what SENSORS carries, keeps exactly that noise).

:class:`ForceSensors` works on blocks of plate samples at ``sample_rate_hz``: :meth:`~ForceSensors.measure`
takes the true forces as they are computed, :meth:`~ForceSensors.output` gives what the sensors read for a
block of samples (the true forces of ``delay_s`` earlier, filtered, plus noise; zero before the first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from ultraglide.devices.errors import DeviceError

MAX_DELAY_S = 0.1
MAX_NOISE_N = 1.0


@dataclass(frozen=True)
class ForceSensorParams:
    """Noise (N rms per sensor sample), bandwidth (Hz, first order; 0: none), delay (s), the device's sensor
    rate (Hz, the samples SENSORS carries) and the noise's seed."""

    noise_n: float = 0.005
    bandwidth_hz: float = 300.0
    delay_s: float = 0.001
    sensor_rate_hz: int = 1000
    seed: int = 1

    def __post_init__(self) -> None:
        if not (math.isfinite(self.noise_n) and 0.0 <= self.noise_n <= MAX_NOISE_N):
            raise DeviceError(f"the force sensors' noise must be 0 to {MAX_NOISE_N:g} N rms, got {self.noise_n}")
        if not (math.isfinite(self.bandwidth_hz) and 0.0 <= self.bandwidth_hz <= 20000.0):
            raise DeviceError(f"the force sensors' bandwidth must be 0 (none) to 20000 Hz, got {self.bandwidth_hz}")
        if not (math.isfinite(self.delay_s) and 0.0 <= self.delay_s <= MAX_DELAY_S):
            raise DeviceError(f"the force sensors' delay must be 0 to {1000 * MAX_DELAY_S:g} ms, got {self.delay_s}")
        if not 1 <= self.sensor_rate_hz <= 48000:
            raise DeviceError(f"the sensor rate must be 1 to 48000 Hz, got {self.sensor_rate_hz}")

    def words(self) -> str:
        band = f"{self.bandwidth_hz:g} Hz" if self.bandwidth_hz else "unfiltered"
        return f"force sensors {1000 * self.noise_n:g} mN rms, {band}, {1000 * self.delay_s:g} ms late"


@njit(cache=True, nogil=True)
def low_pass(x, alpha, state):
    """First-order low-pass of each row of ``x`` in place: y[n] = alpha y[n-1] + (1 - alpha) x[n], from and
    into ``state`` (one value a row)."""
    for row in range(x.shape[0]):
        y = state[row]
        for i in range(x.shape[1]):
            y = alpha * y + (1.0 - alpha) * x[row, i]
            x[row, i] = y
        state[row] = y


class ForceSensors:
    """See the module docstring. Samples are numbered on the plate's clock; blocks come in order."""

    def __init__(self, params: ForceSensorParams, sample_rate_hz: int = 48000):
        self.params = params
        self.sample_rate_hz = int(sample_rate_hz)
        self.delay_samples = int(round(params.delay_s * self.sample_rate_hz))
        band = params.bandwidth_hz
        self._alpha = math.exp(-2.0 * math.pi * band / self.sample_rate_hz) if band else 0.0
        self._filter_state = np.zeros(2)  # the low-pass's last outputs (normal, lateral)
        self._buffer = np.zeros((2, 0))  # delayed, filtered forces from sample _buffer_start on
        self._buffer_start: int | None = None
        self._decimation = max(1, self.sample_rate_hz // params.sensor_rate_hz)
        self._rng = np.random.default_rng(params.seed)
        self._noise_period = -1
        self._noise_value = np.zeros(2)

    def measure(self, first_sample: int, normal_n: np.ndarray, lateral_n: np.ndarray) -> None:
        """The true forces over samples ``first_sample`` on (N): they reach the output ``delay_s`` later."""
        forces = np.empty((2, len(normal_n)))
        forces[0] = normal_n
        forces[1] = lateral_n
        if self._alpha:
            low_pass(forces, self._alpha, self._filter_state)
        at = first_sample + self.delay_samples  # where these samples come out
        if self.params.noise_n > 0 and forces.shape[1]:
            forces += self._noise(at, forces.shape[1])
        if self._buffer_start is None or at != self._buffer_start + self._buffer.shape[1]:
            # the first measurement (or a restart): before it, the sensors read nothing
            self._buffer_start = first_sample
            self._buffer = np.zeros((2, self.delay_samples))
        self._buffer = np.concatenate((self._buffer, forces), axis=1)

    def output(self, start: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """What the sensors read over samples ``start`` to ``start + n`` (N): normal, lateral."""
        if self._buffer_start is None:
            out = np.zeros((2, n))
        else:
            offset = start - self._buffer_start
            if 0 <= offset and offset + n <= self._buffer.shape[1]:  # all of it buffered (a plate's every block)
                out = self._buffer[:, offset:offset + n].copy()
            else:
                out = np.zeros((2, n))
                lo, hi = max(offset, 0), min(offset + n, self._buffer.shape[1])
                if hi > lo:
                    out[:, lo - offset:hi - offset] = self._buffer[:, lo:hi]
            if offset > 0:  # what has been read is dropped
                drop = min(offset, self._buffer.shape[1])
                self._buffer = self._buffer[:, drop:]
                self._buffer_start += drop
        return out[0], out[1]

    def _noise(self, start: int, n: int) -> np.ndarray:
        """White noise for output samples ``start`` on, held over each sensor period (samples numbered from the
        plate's start)."""
        period = self._decimation
        first, last = start // period, (start + n - 1) // period
        values = np.empty((2, last - first + 1))
        held = 1 if first == self._noise_period else 0  # a period begun in the last block keeps its value
        if held:
            values[:, 0] = self._noise_value
        values[:, held:] = self._rng.normal(0.0, self.params.noise_n, (last - first + 1 - held, 2)).T
        self._noise_period = last
        self._noise_value = values[:, -1].copy()
        if last == first:
            return np.repeat(values, n, axis=1)
        counts = np.full(last - first + 1, period)  # samples of each period within the block: both ends cut
        counts[0] = (first + 1) * period - start
        counts[-1] = start + n - last * period
        return np.repeat(values, counts, axis=1)
