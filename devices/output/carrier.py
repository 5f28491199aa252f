"""The ultrasonic carrier: a phase-continuous sine at any block size.

A carrier of f Hz at a rate of fs repeats exactly every fs / gcd(f, fs) samples (96 samples for
25 kHz at 96 kHz), so one period is computed once, in float64, and every block is a slice of it:
the phase is an integer sample offset, exact forever and seamless at every block join. Carriers
whose period would be longer than ``MAX_TABLE`` samples (non-integer frequencies) keep a float64
phase accumulator instead (a compiled loop, :func:`ultraglide.devices.output.kernels.sine_block`).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from ultraglide.devices.errors import CarrierError
from ultraglide.devices.output.kernels import sine_block

MAX_CARRIER_FRACTION = 0.4  # a DAC's anti-imaging filter starts near 0.45 fs: stay below 0.4 fs
MAX_TABLE = 1 << 20


def check_carrier(carrier_hz: float, rate_hz: float) -> None:
    """Refuse a carrier that this sample rate cannot carry, saying what rate would.

    Parameters
    ----------
    carrier_hz : float
        The carrier (Hz), > 0.
    rate_hz : float
        The audio rate (Hz) that is to carry it.

    Raises
    ------
    CarrierError
        A carrier that is not positive, or above the share of the rate a carrier may take.

    Examples
    --------
    >>> check_carrier(25000.0, 96000)                                  # Hz: fine, says nothing
    >>> check_carrier(25000.0, 44100)                                  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.devices.errors.CarrierError: a 25000 Hz carrier needs a sample rate of at least 62,500 Hz ...
    """
    if not carrier_hz > 0:
        raise CarrierError(f"the carrier must be a positive frequency, got {carrier_hz} Hz")
    if carrier_hz > MAX_CARRIER_FRACTION * rate_hz:
        needed = carrier_hz / MAX_CARRIER_FRACTION
        raise CarrierError(f"a {carrier_hz:g} Hz carrier needs a sample rate of at least {needed:,.0f} Hz "
                          f"(got {rate_hz:,.0f} Hz); use 96000 or 192000")


class Carrier:
    """sin(2 pi f t) in consecutive blocks of any length, float32.

    Parameters
    ----------
    carrier_hz : float
        The carrier's frequency, Hz.
    rate_hz : float
        The sample rate, Hz.

    Raises
    ------
    CarrierError
        A carrier the rate cannot carry (at or above half the rate).

    Examples
    --------
    24 kHz at 96 kHz has an exact period of 4 samples:

    >>> carrier = Carrier(24000.0, 96000.0)
    >>> carrier.period, carrier.block(4).round(6).tolist(), carrier.block(2).round(6).tolist()
    (4, [0.0, 1.0, 0.0, -1.0], [0.0, 1.0])
    """

    def __init__(self, carrier_hz: float, rate_hz: float):
        check_carrier(carrier_hz, rate_hz)
        self.carrier_hz = carrier_hz
        self.rate_hz = rate_hz
        cycles = Fraction(carrier_hz).limit_denominator(1000) / Fraction(rate_hz)  # cycles per sample
        exact = math.isclose(float(cycles) * rate_hz, carrier_hz, rel_tol=1e-12)
        self.period = cycles.denominator if exact and cycles.denominator <= MAX_TABLE else 0
        self.offset = 0  # samples into the period (table mode)
        self.phase = 0.0  # cycles (accumulator mode)
        self._table = np.zeros(0, dtype=np.float32)
        if self.period:
            n = np.arange(self.period)
            one = np.sin(2.0 * np.pi * ((n * cycles.numerator) % cycles.denominator) / cycles.denominator)
            self._one_period = one.astype(np.float32)

    def _tiled(self, frames: int) -> np.ndarray:
        if len(self._table) < frames + self.period:
            copies = -(-(frames + self.period) // self.period)
            self._table = np.tile(self._one_period, copies)
        return self._table

    def span(self, frames: int, out: np.ndarray | None = None) -> tuple[np.ndarray, int]:
        """The next ``frames`` samples as ``(table, offset)``: sample k of them is
        ``table[(offset + k) % len(table)]``. In table mode the table is the one exact period (read-only)
        and the offset the span's exact place in it, so any part of the span can be made on its own;
        otherwise the table is the span's samples (written into ``out``, float32, if given) and the offset 0.

        Parameters
        ----------
        frames : int
            Samples.
        out : numpy.ndarray, optional
            float32, ``frames`` long (without an exact period).

        Returns
        -------
        (numpy.ndarray, int)
            The table and the span's offset in it.

        Examples
        --------
        24 kHz at 96 kHz: one period of 4 samples; 6 samples on, the next span starts at 6 mod 4 = 2:

        >>> carrier = Carrier(24000.0, 96000.0)
        >>> table, offset = carrier.span(6)
        >>> table.round(6).tolist(), offset, carrier.span(3)[1]
        ([0.0, 1.0, 0.0, -1.0], 0, 2)
        """
        if self.period:
            start = self.offset
            self.offset = (start + frames) % self.period
            return self._one_period, start
        return self.block(frames, out), 0

    def block(self, frames: int, out: np.ndarray | None = None) -> np.ndarray:
        """The next ``frames`` samples (a read-only view in table mode: copy before writing); without an
        exact period they are written into ``out`` (float32, ``frames`` long) if given.

        Parameters
        ----------
        frames : int
            Samples.
        out : numpy.ndarray, optional
            float32, ``frames`` long.

        Returns
        -------
        numpy.ndarray
            float32, in [-1, 1].

        Examples
        --------
        The samples are sin(2 pi f k / rate), block after block:

        >>> import numpy as np
        >>> carrier = Carrier(24100.0, 96000.0)
        >>> samples = np.concatenate([carrier.block(3), carrier.block(5)])
        >>> bool(np.allclose(samples, np.sin(2 * np.pi * 24100.0 / 96000.0 * np.arange(8)), atol=1e-6))
        True
        """
        if self.period:
            table = self._tiled(frames)
            start = self.offset
            self.offset = (start + frames) % self.period
            return table[start:start + frames]
        if out is None:
            out = np.empty(frames, dtype=np.float32)
        self.phase = sine_block(self.phase, self.carrier_hz / self.rate_hz, out)
        return out
