"""The envelope chain at the control rate: ramps, band and slew limits, the plate's dynamics.

In order, for each sample::

    target amplitude ──► gate (attack/release) ──► one-pole smoother (band and slew limit)
        ──► limit ──► pre-compensation for the plate (or the plain drive) ──► drive amplitude

All amplitudes are µm peak-to-peak. The recursion itself is compiled (:func:`render.kernels.envelope`);
this class holds its settings and state between blocks.

* **Gate**: the gain moves linearly toward 1 (finger down) or 0 (finger up, stop, pause), taking
  ``attack_s`` from 0 to 1 and ``release_s`` from 1 to 0, so nothing clicks.
* **Smoother**: y[n] = y[n-1] + k (x[n] - y[n-1]) moves at most k |x - y| <= k * limit per sample,
  so choosing k <= slew * dt / limit bounds the slew rate exactly, while k from ``band_hz`` sets
  the corner frequency.
* **Plate**: a resonator's vibration envelope follows a[n] = alpha a[n-1] + (1 - alpha) d[n],
  alpha = exp(-dt / tau), tau = Q / (pi f0). Pre-compensation drives the exact inverse while it lies
  within [0, max drive] (the profile's ``max_drive_um_pp``); beyond, the drive is clipped and the
  modelled plate carries on from what really happened, so it never exceeds the target or its own
  previous value, hence never the limit. The output stage's limiter (``devices/output/limiter.py``) then
  guards the real plate, whose Q may differ from the profile's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ultraglide.render import kernels
from ultraglide.render.errors import RenderError


@dataclass(frozen=True)
class EnvelopeBlock:
    """One block of the envelope chain's output, at the control rate (µm p-p each).

    Attributes
    ----------
    amplitude_um_pp : numpy.ndarray
        What the plate should do: the target after the ramps and limits.
    drive_um_pp : numpy.ndarray
        What is sent: the amplitude pre-compensated for the plate's slow response.
    plate_um_pp : numpy.ndarray
        What the plate model says the plate does under that drive.

    Examples
    --------
    >>> import numpy as np
    >>> chain = EnvelopeChain(12000.0, 0.001, 0.001, 1000.0, 1000.0, 6.0, 0.001, 8.0)
    >>> block = chain.process(np.full(24, 10.0), True)
    >>> isinstance(block, EnvelopeBlock), block.amplitude_um_pp.shape
    (True, (24,))
    """

    amplitude_um_pp: np.ndarray  # after ramps and limits: what the plate should do
    drive_um_pp: np.ndarray  # what is sent
    plate_um_pp: np.ndarray  # what the plate model says it does


class EnvelopeChain:
    """Stateful envelope processing, block after block; see the module docstring.

    Parameters
    ----------
    rate_hz : float
        The control rate, Hz.
    attack_s, release_s : float
        The gate's rise and fall, s.
    band_hz : float
        The smoother's band, Hz.
    slew_um_per_ms : float
        The fastest change, µm p-p per ms.
    limit_um_pp : float
        The plate's limit, µm p-p.
    time_constant_s : float
        The plate's envelope time constant, s.
    drive_max_um_pp : float
        The largest drive, µm p-p.
    precompensate : bool
        Drive the plate model onto the target (True) or drive the target itself.

    Raises
    ------
    RenderError
        An attack, release, band or slew not positive.

    Examples
    --------
    A 10 µm target under a 6 µm limit: the drive goes up to the 8 µm ceiling to bring the plate up, the modelled
    plate never passes 6 µm:

    >>> import numpy as np
    >>> chain = EnvelopeChain(12000.0, 0.001, 0.001, 1000.0, 1000.0, 6.0, 0.001, 8.0)
    >>> block = chain.process(np.full(24, 10.0), True)
    >>> float(block.amplitude_um_pp.max()), float(block.drive_um_pp.max()), bool(block.plate_um_pp.max() <= 6.0)
    (6.0, 8.0, True)
    """

    def __init__(self, rate_hz: float, attack_s: float, release_s: float, band_hz: float, slew_um_per_ms: float,
                 limit_um_pp: float, time_constant_s: float, drive_max_um_pp: float, precompensate: bool = True):
        if attack_s <= 0 or release_s <= 0:
            raise RenderError("attack and release must be longer than 0 s")
        if band_hz <= 0 or slew_um_per_ms <= 0:
            raise RenderError("band and slew limits must be positive")
        self.up_step = 1.0 / (attack_s * rate_hz)
        self.down_step = 1.0 / (release_s * rate_hz)
        k_band = 1.0 - math.exp(-2.0 * math.pi * band_hz / rate_hz)
        k_slew = slew_um_per_ms * 1e3 / rate_hz / max(limit_um_pp, 1e-9)
        self.k = min(k_band, k_slew, 1.0)
        self.limit = limit_um_pp
        self.alpha = math.exp(-1.0 / (rate_hz * time_constant_s))
        self.drive_max = drive_max_um_pp
        self.precompensate = precompensate
        self.gain = 0.0  # gate gain, 0..1
        self.goal = 0.0  # what the gate moves toward
        self.smoothed = 0.0
        self.plate = 0.0  # modelled plate amplitude, µm p-p
        self.ramps = 0
        self.drive_clipped = 0

    def process(self, target: np.ndarray, gate_open: np.ndarray | bool, out=None) -> EnvelopeBlock:
        """One block: ``target`` amplitudes and whether the gate is open (per sample, or for all).
        ``out``: three preallocated float64 arrays of the block's length (amplitude, drive, plate).

        Parameters
        ----------
        target : numpy.ndarray
            The amplitudes asked, µm p-p.
        gate_open : numpy.ndarray or bool
            Whether the finger touches, per sample or for the whole block.
        out : (numpy.ndarray, numpy.ndarray, numpy.ndarray), optional
            float64 arrays of the block's length for the amplitude, the drive and the plate (µm p-p).

        Returns
        -------
        EnvelopeBlock

        Examples
        --------
        With the gate shut nothing is asked of the plate:

        >>> import numpy as np
        >>> chain = EnvelopeChain(12000.0, 0.001, 0.001, 1000.0, 1000.0, 6.0, 0.001, 8.0)
        >>> block = chain.process(np.full(24, 10.0), False)
        >>> float(block.amplitude_um_pp.max()), float(block.drive_um_pp.max()), chain.at_rest
        (0.0, 0.0, True)
        """
        n = len(target)
        amplitude, drive, plate = out if out is not None else (np.empty(n), np.empty(n), np.empty(n))
        if isinstance(gate_open, np.ndarray) and gate_open.ndim:
            open_all, flags = -1, gate_open.astype(np.uint8)
        else:
            open_all, flags = int(bool(gate_open)), _NO_FLAGS
        self.gain, self.goal, self.smoothed, self.plate, ramps, clipped = kernels.envelope(
            np.asarray(target, dtype=np.float64), flags, open_all, self.gain, self.goal, self.up_step,
            self.down_step, self.k, self.smoothed, self.limit, self.precompensate, self.alpha, self.drive_max,
            self.plate, amplitude, drive, plate)
        self.ramps += ramps
        self.drive_clipped += clipped
        return EnvelopeBlock(amplitude, drive, plate)

    @property
    def at_rest(self) -> bool:
        """True once the goal and gain are 0 and the smoothed envelope and the plate model have come to rest.

        Examples
        --------
        >>> import numpy as np
        >>> chain = EnvelopeChain(12000.0, 0.001, 0.001, 1000.0, 1000.0, 6.0, 0.001, 8.0)
        >>> chain.at_rest
        True
        >>> _ = chain.process(np.full(24, 3.0), True)
        >>> chain.at_rest
        False
        """
        return self.goal == 0.0 and self.gain == 0.0 and self.smoothed < 1e-9 and self.plate < 1e-6


_NO_FLAGS = np.zeros(0, dtype=np.uint8)
