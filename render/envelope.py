"""Envelope stages at the control rate, each a small stateful object with ``process(block)``.

In the renderer they compose in this order::

    target amplitude ──► Gate (attack/release) ──► Smoother (band and slew limit)
        ──► Precompensator (plate dynamics, drive headroom) ──► drive amplitude

All amplitudes are µm peak-to-peak. No stage loops over samples in Python: the smoother is one
``lfilter`` call, and the gate and the precompensator work run by run (a run is a stretch where
nothing changes regime; there are a handful per block).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from render.errors import RenderError


class Gate:
    """Attack and release ramps: the gain moves linearly toward 1 (finger down) or 0 (up, stop).

    A ramp from 0 to 1 takes ``attack_s``, from 1 to 0 ``release_s``, so nothing clicks.
    """

    def __init__(self, rate_hz: float, attack_s: float = 0.005, release_s: float = 0.010):
        if attack_s <= 0 or release_s <= 0:
            raise RenderError("attack and release must be longer than 0 s")
        self.up_step = 1.0 / (attack_s * rate_hz)
        self.down_step = 1.0 / (release_s * rate_hz)
        self.gain = 0.0
        self.ramps = 0  # ramps started (finger down, finger up, start, stop)
        self._target = 0.0

    def process(self, open_: np.ndarray | bool, n: int) -> np.ndarray | float:
        """Gain (0..1) for each of ``n`` samples, given whether the gate is open at each sample
        (or for all of them). A steady gain comes back as a plain number."""
        if not isinstance(open_, np.ndarray) or open_.ndim == 0:
            goal = 1.0 if open_ else 0.0
            if goal == self.gain == self._target:
                return goal
            open_ = np.full(n, goal)
        target = np.asarray(open_, dtype=float)
        out = np.empty(target.shape)
        changes = np.flatnonzero(np.diff(target)) + 1
        starts = np.concatenate(([0], changes))
        ends = np.concatenate((changes, [len(target)]))
        for start, end in zip(starts, ends, strict=True):  # runs of constant target, not samples
            if len(target) == 0:
                break
            goal = target[start]
            if goal != self._target:
                self.ramps += 1
                self._target = goal
            steps = np.arange(1, end - start + 1)
            if goal > self.gain:
                out[start:end] = np.minimum(self.gain + self.up_step * steps, goal)
            else:
                out[start:end] = np.maximum(self.gain - self.down_step * steps, goal)
            self.gain = float(out[end - 1])
        return out

    @property
    def closed(self) -> bool:
        return self.gain == 0.0 and self._target == 0.0


class Smoother:
    """One-pole low-pass limiting both the bandwidth and the slew rate of the amplitude.

    y[n] = y[n-1] + k (x[n] - y[n-1]) moves at most k |x - y| <= k * limit per sample, so choosing
    k <= slew * dt / limit bounds the slew rate exactly, while k from ``band_hz`` sets the corner.
    """

    SMALL = 64  # blocks up to this size use a cached matrix: cheaper than lfilter's set-up

    def __init__(self, rate_hz: float, band_hz: float, slew_um_per_ms: float, limit_um_pp: float):
        if band_hz <= 0 or slew_um_per_ms <= 0:
            raise RenderError("band and slew limits must be positive")
        k_band = 1.0 - math.exp(-2.0 * math.pi * band_hz / rate_hz)
        k_slew = slew_um_per_ms * 1e3 / rate_hz / max(limit_um_pp, 1e-9)
        self.k = min(k_band, k_slew, 1.0)
        self._b = np.array([self.k])
        self._a = np.array([1.0, self.k - 1.0])
        self._previous = 0.0  # the last output, y[-1]
        self._matrices: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def _matrix(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """y = M x + p y[-1] for a block of n: M[i, j] = k (1-k)^(i-j), p[i] = (1-k)^(i+1)."""
        if n not in self._matrices:
            lag = np.subtract.outer(np.arange(n), np.arange(n))
            keep = (1.0 - self.k) ** np.maximum(lag, 0)
            self._matrices[n] = (np.tril(self.k * keep), (1.0 - self.k) ** np.arange(1, n + 1))
        return self._matrices[n]

    def process(self, x: np.ndarray) -> np.ndarray:
        n = len(x)
        if n == 0:
            return np.zeros(0)
        if n <= self.SMALL:
            matrix, carry = self._matrix(n)
            y = matrix @ x
            y += carry * self._previous
        else:  # lfilter's state for this filter is (1 - k) y[-1]
            y, _ = lfilter(self._b, self._a, x, zi=[(1.0 - self.k) * self._previous])
        self._previous = float(y[-1])
        return y


class Precompensator:
    _WINDOW = 256

    """Drive that makes a first-order plate (time constant tau) follow the target amplitude.

    The plate's envelope obeys a[n] = alpha a[n-1] + (1 - alpha) d[n], alpha = exp(-dt / tau).
    The exact inverse d[n] = (t[n] - alpha a[n-1]) / (1 - alpha) is used while it lies within the
    drive's range [0, ``drive_max``]; beyond, the drive is clipped and the modelled plate state
    carries on from what really happened. So the modelled amplitude never exceeds the target (on
    a rise the plate lags) or the previous amplitude (on a fall), hence never the limit.
    """

    def __init__(self, rate_hz: float, time_constant_s: float, drive_max_um_pp: float):
        self.alpha = math.exp(-1.0 / (rate_hz * time_constant_s))
        self.gain = 1.0 / (1.0 - self.alpha)
        self.drive_max = drive_max_um_pp
        self.plate = 0.0  # modelled plate amplitude, µm p-p
        self.clipped = 0
        self._powers = self.alpha ** np.arange(1, self._WINDOW + 1)
        self._steps = np.zeros(0)

    def _lower_clip_only(self, target: np.ndarray) -> np.ndarray:
        """The plate when only the drive's floor (0) can bind: a[n] = max(t[n], alpha a[n-1]).

        That recursion is a running maximum of t[k] alpha^(n-k), computed in the log domain:
        log a[n] = n log(alpha) + max over k <= n of (log t[k] - k log(alpha)).
        """
        n = len(target)
        if len(self._steps) < n + 1:
            self._steps = np.arange(-1, 2 * n + 1) * math.log(self.alpha)
        steps = self._steps[:n + 1]
        logs = np.empty(n + 1)
        logs[0] = self.plate
        logs[1:] = target
        np.maximum(logs, 1e-300, out=logs)  # log(0) would warn; 1e-300 µm is rest all the same
        np.log(logs, out=logs)
        logs -= steps
        np.maximum.accumulate(logs, out=logs)
        logs += steps
        return np.exp(logs[1:])

    def process(self, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drive and the modelled plate amplitude for each target sample."""
        target = np.asarray(target, dtype=float)
        if len(target) == 0:
            return target.copy(), target.copy()
        plate = self._lower_clip_only(target)
        previous = np.concatenate(([self.plate], plate[:-1]))
        drive = (plate - self.alpha * previous) * self.gain
        np.maximum(drive, 0.0, out=drive)  # rounding: the floor holds exactly
        over = np.flatnonzero(drive > self.drive_max)
        decaying = np.count_nonzero(plate > target)
        if not len(over):
            self.clipped += int(decaying)
            self.plate = float(plate[-1])
            return drive, plate
        # the ceiling binds somewhere: exact run-by-run from there on
        first = int(over[0])
        self.clipped += int(np.count_nonzero(plate[:first] > target[:first]))
        if first:
            self.plate = float(plate[first - 1])
        tail_drive, tail_plate = self._runs(target[first:])
        drive[first:], plate[first:] = tail_drive, tail_plate
        return drive, plate

    def _runs(self, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(target)
        drive = np.empty(n)
        plate = np.empty(n)
        alpha, gain, top = self.alpha, self.gain, self.drive_max
        free = np.empty(n)  # the inverse while the plate tracks the target exactly
        free[1:] = (target[1:] - alpha * target[:-1]) * gain
        state = self.plate
        i = 0
        while i < n:  # runs: tracking, or clipped at 0 or at drive_max; searched a window at a time
            wanted = (target[i] - alpha * state) * gain
            if 0.0 <= wanted <= top:
                drive[i], plate[i] = wanted, target[i]
                end = i + 1
                while end < n:
                    window = free[end:end + self._WINDOW]
                    bad = np.flatnonzero((window < 0.0) | (window > top))
                    if len(bad):
                        end += bad[0]
                        break
                    end += len(window)
                drive[i + 1:end] = free[i + 1:end]
                plate[i + 1:end] = target[i + 1:end]
            else:
                level = 0.0 if wanted < 0.0 else top
                end, relaxing = i, state
                while end < n:  # at a constant drive the plate relaxes exponentially toward it
                    ahead = target[end:end + self._WINDOW]
                    relaxed = level + (relaxing - level) * self._powers[:len(ahead)]
                    before = np.concatenate(([relaxing], relaxed[:-1]))
                    still = (ahead - alpha * before) * gain
                    back = (still >= 0.0) if level == 0.0 else (still <= top)
                    if end == i:
                        back[0] = False
                    found = np.flatnonzero(back)
                    stop = found[0] if len(found) else len(ahead)
                    drive[end:end + stop] = level
                    plate[end:end + stop] = relaxed[:stop]
                    end += stop
                    if len(found):
                        break
                    relaxing = relaxed[-1]
                self.clipped += end - i
            state = plate[end - 1]
            i = end
        self.plate = state
        return drive, plate


class PlateEnvelope:
    """The first-order envelope response of a plate to a drive, for simulation and checks."""

    def __init__(self, rate_hz: float, time_constant_s: float):
        self.alpha = math.exp(-1.0 / (rate_hz * time_constant_s))
        self._b = np.array([1.0 - self.alpha])
        self._a = np.array([1.0, -self.alpha])
        self._state = np.zeros(1)

    def process(self, drive: np.ndarray) -> np.ndarray:
        out, self._state = lfilter(self._b, self._a, drive, zi=self._state)
        return out
