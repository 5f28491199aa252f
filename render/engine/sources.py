"""A renderer as the source a device is started with (``devices.source.BlockSource``), and the output
stages that put it behind a device's limiter: the one place where a renderer meets a device.

:class:`EnvelopeSource` serves every path: a device started by a command or a script
(:func:`renderer_source`), an export (:func:`offline_stage`) and the engine's block path, which gives
it preallocated buffers so that a real-time block allocates nothing.
"""

from __future__ import annotations

import numpy as np
from ultraglide.devices.output.source import Device
from ultraglide.devices.output.stage import OutputStage, output_stage
from ultraglide.render.renderer import Renderer


class EnvelopeSource:
    """A renderer's drive envelope, µm p-p at its control rate: the source a device is started with
    (a :class:`~ultraglide.devices.output.source.BlockSource`). The device puts it behind its output stage.

    ``realtime_capacity`` (control samples): render every block into buffers made here once, for a
    real-time path (:meth:`Renderer.control_buffers` with ``always``); the array :meth:`pull` returns
    is then overwritten by the next pull. None (the default): each pull returns a new array.

    Parameters
    ----------
    renderer : Renderer
    realtime_capacity : int, optional
        Control samples per block at most, for a real-time path; None: a new array each pull.

    Examples
    --------
    >>> import ultraglide
    >>> source = EnvelopeSource(ultraglide.Renderer("grating-1mm", trajectory=ultraglide.SwipePath(duration_s=0.1)))
    >>> source.control_rate_hz, source.pull(1200, None).shape              # Hz; 0.1 s of drive (µm p-p)
    (12000.0, (1200,))
    >>> source.request_stop()
    >>> _ = source.pull(1200, None)
    >>> source.finished
    True
    """

    def __init__(self, renderer: Renderer, realtime_capacity: int | None = None):
        self.renderer = renderer
        self.control_rate_hz = renderer.settings.control_rate_hz
        self.buffers = None if realtime_capacity is None else renderer.control_buffers(realtime_capacity, always=True)

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        """The next ``n`` drive samples (µm p-p); ``now_s``: when the first reaches the plate (perf_counter s).

        Parameters
        ----------
        n : int
            Control samples.
        now_s : float or None
            When the first reaches the plate, perf_counter s; None offline.

        Returns
        -------
        numpy.ndarray
            The drive, µm p-p (the source's buffer, overwritten by the next pull).

        Examples
        --------
        >>> import ultraglide
        >>> swipe = ultraglide.SwipePath(duration_s=0.01)
        >>> source = EnvelopeSource(ultraglide.Renderer("grating-1mm", trajectory=swipe))
        >>> drive = source.pull(120, None)                         # 10 ms at 12 kHz
        >>> drive.shape, bool(drive.max() <= source.renderer.profile.max_drive_um_pp)
        ((120,), True)
        """
        return self.renderer.control(n, now_s, out=self.buffers).drive_um_pp

    def request_stop(self) -> None:
        """Ramp the renderer down to rest.

        Examples
        --------
        >>> import time
        >>> import ultraglide
        >>> renderer = ultraglide.Renderer("grating-1mm")
        >>> now = time.perf_counter()
        >>> renderer.push(now, 10.0, 10.0)
        >>> source = EnvelopeSource(renderer)
        >>> _ = source.pull(120, now)
        >>> source.request_stop()
        >>> _ = source.pull(1200, now + 0.01)                      # the release and the plate's tail
        >>> source.finished, float(source.pull(12, now + 0.11).max())
        (True, 0.0)
        """
        self.renderer.stop()

    @property
    def finished(self) -> bool:
        """True once the renderer is at rest after a stop or the end of its path.

        Examples
        --------
        >>> import ultraglide
        >>> swipe = ultraglide.SwipePath(duration_s=0.01)
        >>> source = EnvelopeSource(ultraglide.Renderer("grating-1mm", trajectory=swipe))
        >>> source.finished
        False
        >>> _ = source.pull(1200, None)                             # the swipe's 10 ms, then 90 ms at rest
        >>> source.finished
        True
        """
        return self.renderer.finished

    def __repr__(self) -> str:
        return f"EnvelopeSource({self.renderer!r})"


def renderer_source(device: Device, renderer: Renderer) -> OutputStage:
    """What to ``device.start()`` with so that it plays ``renderer``: the renderer behind the drive limiter,
    as the signal the device wants (``device.signal``, ``device.rate_hz``).

    Starting the device with an :class:`EnvelopeSource` does the same; built here, the caller can read
    the limiter's counters.

    Parameters
    ----------
    device : Device
        An opened device (:func:`ultraglide.open_device`).
    renderer : Renderer
        What it plays.

    Returns
    -------
    OutputStage
        The source to start the device with; ``stage.limiter`` counts what the limiter did.

    Raises
    ------
    DeviceError
        A renderer whose rates the device cannot take.

    Examples
    --------
    >>> import ultraglide
    >>> renderer = ultraglide.Renderer("grating-1mm", trajectory=ultraglide.SwipePath(duration_s=0.1))
    >>> device = ultraglide.open_device("null", renderer.profile)
    >>> stage = renderer_source(device, renderer)
    >>> samples = stage.pull(9600, None)                      # 0.1 s of the audio signal
    >>> stage.signal, bool(abs(samples).max() <= 1.0)
    ('audio', True)
    """
    carrier_hz = getattr(device, "carrier_hz", None) or renderer.carrier_hz
    return output_stage(EnvelopeSource(renderer), renderer.profile, device.signal, device.rate_hz, carrier_hz)


def offline_stage(renderer: Renderer) -> OutputStage:
    """The audio a plate would get from ``renderer`` (limiter, then carrier) at its own audio rate, for export.

    Parameters
    ----------
    renderer : Renderer

    Returns
    -------
    OutputStage
        Audio at the renderer's rate, on its carrier.

    Examples
    --------
    >>> import ultraglide
    >>> offline_stage(ultraglide.Renderer("grating-1mm", trajectory=ultraglide.SwipePath(duration_s=0.1)))
    OutputStage(audio at 96000 Hz, carrier 25000 Hz, plate 'sim-plate', limit 6 µm p-p)
    """
    return OutputStage(EnvelopeSource(renderer), renderer.profile, "audio", renderer.settings.audio_rate_hz,
                       renderer.carrier_hz)
