"""What a device pulls from: it never sees the renderer, only this protocol (see docs/design.md)."""

from __future__ import annotations

import time
from typing import Protocol

import numpy as np


class BlockSource(Protocol):
    """A stream of blocks. A device is started with an *envelope source*: drive amplitudes in µm
    peak-to-peak at the control rate (``control_rate_hz`` if it says, else 12 kHz). The device wraps
    it in its output stage (:mod:`ultraglide.devices.output.stage`), itself a BlockSource, which
    limits it and gives audio devices float32 samples in [-1, 1] (1 = full-scale drive) and control
    devices limited setpoints in µm peak-to-peak.

    Attributes
    ----------
    finished : bool
        True once the source is at rest after :meth:`request_stop` (or the end of its path).

    Examples
    --------
    >>> import numpy as np
    >>> class Steady:                                                      # 3 µm p-p, until asked to stop
    ...     finished = False
    ...     def pull(self, n, now_s): return np.zeros(n) if self.finished else np.full(n, 3.0)
    ...     def request_stop(self): self.finished = True
    >>> source = Steady()                                                  # a protocol: anything shaped so
    >>> float(source.pull(12, None)[0])
    3.0
    >>> source.request_stop()
    >>> float(source.pull(12, None)[0]), source.finished
    (0.0, True)
    """

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        """The next ``n`` values; ``now_s`` is when (perf_counter s) the first reaches the plate.

        **The real-time contract** (the one place it is written; every source and device keeps it):

        * *Who calls it*: the device's own thread, never the app's: PortAudio's callback thread (audio),
          the serial writer thread (plate drivers: every 1 or 2 ms), the pacing thread of the WAV and null
          sinks (every 10 ms), or, offline, the exporter's thread. One thread pulls a source; the device
          copies or sends the block before it pulls the next, so a source may return the same buffer
          every time (the engine's does).
        * *Its deadline*: the block's own duration (``n`` / rate) minus the device's margin: an audio
          callback of 256 frames at 96 kHz has 2.7 ms, including the device's own work. A late block is
          an underrun the person feels.
        * *What it must not do*: allocate arrays (preallocate at start; small Python numbers are the
          only change), do file or network I/O, wait for anything, hold a lock longer than a copy (the
          engine's touch ring and status are lock-free; a live trajectory's lock is only ever taken by
          this same thread, so it is never contended), run a per-sample Python loop (compiled kernels do
          the per-sample work).
        * *What an exception does*: the device stops pulling, rests the hardware (zero, disabled) and
          reports the error in its ``status()["errors"]``; the command or the engine then says so and
          exits non-zero. A source never raises on purpose to stop: it ramps down when asked
          (:meth:`request_stop`) and says :attr:`finished`.

        Parameters
        ----------
        n : int
            Values, at the device's rate.
        now_s : float or None
            When the first reaches the plate, perf_counter s; None offline.

        Returns
        -------
        numpy.ndarray
            The drive envelope, µm p-p.

        Examples
        --------
        The renderer's envelope source, offline along a 10 ms swipe (120 values at 12 kHz, the drive before
        the limiter):

        >>> import ultraglide
        >>> swipe = ultraglide.SwipePath(duration_s=0.01)
        >>> source = ultraglide.EnvelopeSource(ultraglide.Renderer("grating-1mm", trajectory=swipe))
        >>> block = source.pull(120, None)
        >>> len(block), bool(block.min() >= 0.0)
        (120, True)
        """

    def request_stop(self) -> None:
        """Start ramping down to rest.

        Examples
        --------
        >>> import time
        >>> import ultraglide
        >>> renderer = ultraglide.Renderer("grating-1mm")
        >>> now = time.perf_counter()
        >>> renderer.push(now, 10.0, 10.0)
        >>> source = ultraglide.EnvelopeSource(renderer)
        >>> _ = source.pull(120, now)
        >>> source.request_stop()
        >>> _ = source.pull(1200, now + 0.01)                     # 100 ms: the release and the plate's tail
        >>> source.finished
        True
        """

    @property
    def finished(self) -> bool:
        """True once the ramp down has reached rest.

        Examples
        --------
        An offline swipe is finished once its path has ended and the output is at rest:

        >>> import ultraglide
        >>> swipe = ultraglide.SwipePath(duration_s=0.01)
        >>> source = ultraglide.EnvelopeSource(ultraglide.Renderer("grating-1mm", trajectory=swipe))
        >>> source.finished
        False
        >>> _ = source.pull(1200, None)                            # 100 ms
        >>> source.finished
        True
        """


class Device(Protocol):
    """What every device offers (:func:`ultraglide.devices.urls.open_device` returns one; a device of
    one's own needs only this). ``signal`` is ``"control"`` (drive envelope in µm p-p, for plate drivers
    that make their own carrier) or ``"audio"`` (float32 samples in [-1, 1]); ``rate_hz`` the rate it
    pulls at. ``start(source)`` begins pulling from an envelope source on the device's own thread, behind
    its output stage; ``stop()`` ramps the source to rest, then rests the hardware.

    Attributes
    ----------
    signal : {"control", "audio"}
        What it takes.
    rate_hz : float
        The rate (Hz) it pulls at.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> device = open_device("null", load_profile("sim-plate"))
    >>> device.signal, device.rate_hz                                      # Hz
    ('audio', 96000)
    """

    signal: str
    rate_hz: float

    def start(self, source: BlockSource) -> None:
        """Begin pulling from ``source``.

        Parameters
        ----------
        source : BlockSource

        Examples
        --------
        The null device paces its pulls in real time, as a sound card would:

        >>> import ultraglide
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> device = open_device("null", load_profile("sim-plate"))
        >>> device.start(ultraglide.EnvelopeSource(ultraglide.Renderer("grating-1mm")))
        >>> device.stop()
        >>> device.status()["errors"]
        []
        """

    def stop(self) -> None:
        """Ramp down through the source, then rest the hardware.

        Examples
        --------
        >>> import ultraglide
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> device = open_device("null", load_profile("sim-plate"))
        >>> source = ultraglide.EnvelopeSource(ultraglide.Renderer("grating-1mm"))
        >>> device.start(source)
        >>> device.stop()                                      # the source ramped to rest first
        >>> source.finished
        True
        """

    def status(self) -> dict:
        """Counters and state, as plain values.

        Returns
        -------
        dict

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> status = open_device("null", load_profile("sim-plate")).status()
        >>> isinstance(status, dict), "errors" in status
        (True, True)
        """


STOP_TIMEOUT_S = 1.0  # a ramp down that has not reached rest by then is cut off


def ramp_down(source: BlockSource, consuming, timeout_s: float = STOP_TIMEOUT_S) -> None:
    """Ask ``source`` to ramp to rest and wait while ``consuming()`` (the device still pulls) until it is
    finished or ``timeout_s`` has passed. Every device stops through this before resting its hardware.

    Parameters
    ----------
    source : BlockSource
        What the device pulls from.
    consuming : callable
        True while the device still pulls blocks (so the ramp can play out).
    timeout_s : float
        The longest wait (s); a ramp not at rest by then is cut off.

    Examples
    --------
    >>> import types
    >>> source = types.SimpleNamespace(finished=False)
    >>> source.request_stop = lambda: setattr(source, "finished", True)
    >>> ramp_down(source, consuming=lambda: True, timeout_s=1.0)
    >>> source.finished
    True
    """
    source.request_stop()
    deadline = time.monotonic() + timeout_s
    while consuming() and not source.finished and time.monotonic() < deadline:
        time.sleep(0.005)
