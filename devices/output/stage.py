"""The output stage: the one path from a drive envelope to any device.

Every device hands the source it is started with to :func:`output_stage` first thing, so whatever
feeds it, its output has passed the :class:`~ultraglide.devices.output.limiter.DriveLimiter`. The stage
pulls the drive envelope (µm p-p at the control rate) from an *envelope source*, limits it, and
gives the device what it wants:

* control devices (serial and simulated plates, whose firmware makes the carrier): the limited
  envelope, µm p-p at the control rate, or at a whole fraction of it (a slower stream, e.g. 1 kHz for
  a slow link): each value the mean of the limited control samples it stands for, so never above them;
* audio devices (sound card, WAV file) and offline export: the limited envelope, interpolated
  linearly between control samples (one control period behind them) and riding a phase-continuous
  carrier, float32 in [-1, 1] (1 = the plate's full-scale drive).

An envelope source is a :class:`~ultraglide.devices.output.source.BlockSource` of drive amplitudes
(µm p-p); it may say its rate as ``control_rate_hz`` (default 12 kHz).

Example, one second of a steady 3 µm p-p drive at 96 kHz::

    >>> import numpy as np
    >>> from ultraglide.devices.profiles import load_profile
    >>> class Steady:
    ...     finished = False
    ...     def pull(self, n, now_s): return np.full(n, 3.0)
    ...     def request_stop(self): pass
    >>> stage = OutputStage(Steady(), load_profile("sim-plate"), "audio", rate_hz=96000, carrier_hz=25000.0)
    >>> samples = stage.pull(96000, None)
    >>> round(float(np.abs(samples[96:]).max()), 3)      # 3 of 8 µm full scale
    0.375
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output import kernels
from ultraglide.devices.output.carrier import Carrier
from ultraglide.devices.output.limiter import DriveLimiter
from ultraglide.devices.output.source import BlockSource
from ultraglide.devices.profiles import PlateProfile

CONTROL_RATE_HZ = 12000.0  # an envelope source's rate unless it says otherwise
KNOTS_CAPACITY = 1024  # control samples held for the audio path before its buffer grows (a live block: 8 or 16)
SIGNALS = ("control", "audio")


@dataclass(frozen=True, eq=False)
class Modulation:
    """A span of audio frames, its envelope already limited: ready to be put on the carrier whole or in
    chunks, on any threads (:meth:`render` runs a compiled kernel that releases the GIL). Each frame
    depends on its own index alone (its control samples and the carrier's exact phase there), so
    chunks join seamlessly and give what one call gives, sample for sample.

    Examples
    --------
    A two-sample carrier (+1, -1) under an envelope rising from 0 to 8 µm over two frames (1/8 of full scale
    per µm), rendered whole and in two chunks:

    >>> import numpy as np
    >>> span = Modulation(np.array([0.0, 8.0, 8.0]), 0, 2, 0.125, np.array([1.0, -1.0], dtype=np.float32), 0, 4)
    >>> whole, chunks = np.empty(4, dtype=np.float32), np.empty(4, dtype=np.float32)
    >>> span.render(whole); span.render(chunks, 0, 3); span.render(chunks, 3, 4)
    >>> whole.tolist(), bool(np.array_equal(whole, chunks))
    ([0.0, -0.5, 1.0, -1.0], True)
    """

    knots: np.ndarray  # limited drive, µm p-p: the control sample before the span, then those it reaches
    first_frame: int  # the span's first frame, counted in audio frames from knot 0
    upsampling: int
    scale: float  # 1 / full-scale drive (µm p-p)
    carrier: np.ndarray  # one exact period of the carrier (or the span's own carrier samples)
    carrier_offset: int  # where in it the span starts
    frames: int

    def render(self, out: np.ndarray, start: int = 0, stop: int | None = None) -> None:
        """Frames ``start`` to ``stop`` of the span into ``out[start:stop]`` (float32, in [-1, 1]).

        Parameters
        ----------
        out : numpy.ndarray
            float32, at least ``stop`` long.
        start, stop : int
            The frames, from the span's first (``stop`` None: its last).

        Examples
        --------
        A steady 4 µm p-p on a 24 kHz carrier at 96 kHz (a 4-sample period), 4 of the plate's 8 µm full scale:

        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
        ...                                pull=lambda n, now_s: np.full(n, 4.0))
        >>> stage = OutputStage(steady, load_profile("sim-plate"), "audio", 96000, carrier_hz=24000.0)
        >>> _ = stage.pull(960, None)                            # past the first control sample's rise
        >>> span = stage.modulation(8)
        >>> out = np.empty(8, dtype=np.float32)
        >>> span.render(out)
        >>> out.round(6).tolist()
        [0.0, 0.5, 0.0, -0.5, 0.0, 0.5, 0.0, -0.5]
        """
        stop = self.frames if stop is None else stop
        kernels.modulate(self.knots, self.first_frame + start, self.upsampling, self.scale, self.carrier,
                         (self.carrier_offset + start) % len(self.carrier), out[start:stop])


class OutputStage:
    """Limits an envelope source's drive and turns it into a device's signal (see the module docstring).

    Every output passes through one: the drive limiter holds the plate's limit on what leaves, whatever the source
    asks. Devices build it through :func:`output_stage`.

    Parameters
    ----------
    source : BlockSource
        An envelope source: drive amplitudes (µm p-p) at the control rate (its ``control_rate_hz``, 12 kHz by
        default).
    profile : PlateProfile
        The plate: its limit (µm p-p), full scale and carrier range.
    signal : {"control", "audio"}
        ``"control"``: the limited envelope (µm p-p) at the control rate or a whole fraction of it; ``"audio"``:
        the envelope on the carrier, float32 in [-1, 1] (1 = full scale), at a whole multiple of the control rate.
    rate_hz : float, optional
        The device's rate (Hz); the control rate by default.
    carrier_hz : float, optional
        The audio signal's carrier (Hz); the plate's resonance by default.

    Attributes
    ----------
    frames : int
        The index of the next value the device takes.
    limiter : DriveLimiter
        The limiter, with its counters (:meth:`status`).

    Raises
    ------
    DeviceError
        An unknown signal, a rate that does not fit the control rate, or a carrier outside the plate's range.

    Examples
    --------
    >>> import numpy as np, types
    >>> from ultraglide.devices.profiles import load_profile
    >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
    ...                                pull=lambda n, now_s: np.full(n, 9.0))   # 9 µm p-p: above the 6 µm limit
    >>> stage = OutputStage(steady, load_profile("sim-plate"), "audio", 96000)
    >>> stage
    OutputStage(audio at 96000 Hz, carrier 25000 Hz, plate 'sim-plate', limit 6 µm p-p)
    >>> block = stage.pull(9600, None)                      # 0.1 s of audio
    >>> block.dtype, float(abs(block[-960:]).max())          # 6 of the plate's 8 µm full scale
    (dtype('float32'), 0.75)
    >>> stage.status()["worst_excess_um_pp"]
    3.0
    """

    def __init__(self, source: BlockSource, profile: PlateProfile, signal: str, rate_hz: float | None = None,
                 carrier_hz: float | None = None):
        if signal not in SIGNALS:
            raise DeviceError(f"a device's signal is control or audio, got {signal!r}")
        self.source = source
        self.profile = profile
        self.signal = signal
        self.control_rate_hz = float(getattr(source, "control_rate_hz", CONTROL_RATE_HZ))
        self.rate_hz = float(rate_hz or self.control_rate_hz)
        self.carrier_hz = float(carrier_hz or profile.resonance_hz)
        # control: limited control samples a device value stands for (1, or k for a stream k times slower)
        self.decimation = max(1, round(self.control_rate_hz / self.rate_hz))
        if signal == "control" and abs(self.rate_hz * self.decimation - self.control_rate_hz) > 1e-6:
            raise DeviceError(f"the device takes setpoints at {self.rate_hz:g} Hz but the envelope comes at "
                              f"{self.control_rate_hz:g} Hz: the device's rate must be the control rate or a "
                              "whole fraction of it")
        self._fine = np.zeros(0)  # control: the limited control samples of a slower stream's block (grown once)
        self.upsampling = round(self.rate_hz / self.control_rate_hz)
        if signal == "audio":
            if self.upsampling < 1 or abs(self.rate_hz - self.upsampling * self.control_rate_hz) > 1e-6:
                raise DeviceError(f"the audio rate ({self.rate_hz:g} Hz) must be a whole multiple of the "
                                  f"control rate ({self.control_rate_hz:g} Hz)")
            profile.check_carrier(self.carrier_hz)
            self.carrier = Carrier(self.carrier_hz, self.rate_hz)
        self.limiter = DriveLimiter(profile, self.control_rate_hz)
        self.observers: list = []  # callables given each block of limited drive (µm p-p, control rate), to keep
        self.frames = 0
        self._scale = 1.0 / profile.full_scale_um_pp
        self._last_drive = 0.0  # the control sample before the pending ones, for interpolation
        # knots[0]: the last control sample played out (= _last_drive); knots[1:1 + _count]: limited control
        # samples not yet played out. Grown only when a longer block than any before comes.
        self._knots = np.zeros(KNOTS_CAPACITY + 1)
        self._count = 0
        self._played = 0  # audio frames already produced from the first pending sample's period
        self._carrier_samples = np.zeros(0, dtype=np.float32)  # the span's carrier when it has no exact period

    def __repr__(self) -> str:
        """``OutputStage(audio at 96000 Hz, carrier 25000 Hz, plate 'sim-plate', limit 6 µm p-p)``."""
        carrier = f", carrier {self.carrier_hz:g} Hz" if self.signal == "audio" else ""
        return (f"OutputStage({self.signal} at {self.rate_hz:g} Hz{carrier}, plate {self.profile.name!r}, "
                f"limit {self.limiter.limit_um_pp:g} µm p-p)")

    def matches(self, profile: PlateProfile, signal: str, rate_hz: float, carrier_hz: float | None) -> bool:
        """Whether this stage already gives what a device with these facts needs.

        Parameters
        ----------
        profile : PlateProfile
        signal : {"control", "audio"}
        rate_hz : float
            The device's rate (Hz).
        carrier_hz : float or None
            The device's carrier (Hz); the plate's resonance when None.

        Returns
        -------
        bool

        Examples
        --------
        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
        ...                                pull=lambda n, now_s: np.full(n, 9.0))          # 9 µm p-p asked
        >>> plate = load_profile("sim-plate")
        >>> stage = OutputStage(steady, plate, "audio", 96000)
        >>> stage.matches(plate, "audio", 96000, None), stage.matches(plate, "audio", 48000, None)
        (True, False)
        """
        return (self.profile == profile and self.signal == signal and self.rate_hz == float(rate_hz)
                and (signal == "control" or self.carrier_hz == float(carrier_hz or profile.resonance_hz)))

    # ---- what a device pulls ---------------------------------------------------------------------
    def pull(self, n: int, now_s: float | None, out: np.ndarray | None = None) -> np.ndarray:
        """The next ``n`` values of the device's signal; ``now_s``: when (perf_counter s) the first plays.
        ``out``: an array of ``n`` to write them into (float64 µm p-p for control, float32 for audio), so the
        block allocates nothing (the real-time path); without it a new array is returned.

        Parameters
        ----------
        n : int
            How many values.
        now_s : float or None
            When (perf_counter s) the first plays; None offline.
        out : numpy.ndarray, optional
            An array of ``n`` to write into.

        Returns
        -------
        numpy.ndarray
            µm p-p (control) or float32 in [-1, 1] (audio).

        Examples
        --------
        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
        ...                                pull=lambda n, now_s: np.full(n, 9.0))          # 9 µm p-p asked
        >>> stage = OutputStage(steady, load_profile("sim-plate"), "control")
        >>> drive = stage.pull(1200, None)                              # 0.1 s at 12 kHz
        >>> float(drive[0]), float(drive[-1]), stage.frames      # overdrive (8 µm) at first, then the 6 µm limit
        (8.0, 6.0, 1200)
        """
        if self.signal == "control":
            out = self._limited(n, now_s, out) if self.decimation == 1 else self._decimated(n, now_s, out)
            if n:
                self._last_drive = float(out[n - 1])
            self.frames += n
            return out
        return self._audio(n, now_s, out)

    def skip(self, n: int) -> None:
        """``n`` stream values the device's writer skipped without pulling (it ran behind): counted, so
        :attr:`frames` stays the index of the next value on the wire.

        Parameters
        ----------
        n : int
            Values skipped.

        Examples
        --------
        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
        ...                                pull=lambda n, now_s: np.full(n, 3.0))
        >>> stage = OutputStage(steady, load_profile("sim-plate"), "control")
        >>> _ = stage.pull(100, None)
        >>> stage.skip(20)
        >>> stage.frames
        120
        """
        self.frames += n

    def _limited(self, n: int, now_s: float | None, out: np.ndarray | None = None) -> np.ndarray:
        drive = self.limiter.process(self.source.pull(n, now_s), out)
        if self.observers:
            kept = drive.copy() if out is not None else drive  # theirs to keep: the stage's buffers move on
            for observer in self.observers:
                observer(kept)
        return drive

    def _decimated(self, n: int, now_s: float | None, out: np.ndarray | None) -> np.ndarray:
        """``n`` values of a stream ``decimation`` times slower than the control rate: each the mean of the
        limited control samples it stands for (so the limit holds for it as for them)."""
        k = self.decimation
        if len(self._fine) < n * k:  # a longer block than any before: grow once
            self._fine = np.zeros(n * k)
        fine = self._limited(n * k, now_s, self._fine[:n * k])
        if out is None:
            out = np.empty(n)
        np.mean(fine.reshape(n, k), axis=1, out=out)
        return out

    def _audio(self, frames: int, now_s: float | None, out: np.ndarray | None = None) -> np.ndarray:
        knots, first_frame, carrier, offset = self._span(frames, now_s)
        if out is None:
            out = np.empty(frames, dtype=np.float32)
        kernels.modulate(knots, first_frame, self.upsampling, self._scale, carrier, offset, out)
        self._consume(frames)
        return out

    def modulation(self, frames: int, now_s: float | None = None) -> Modulation:
        """The next ``frames`` of an audio stage, to render later (whole, or in chunks on other threads).
        The envelope is pulled and limited here, in order: only the carrier's modulation is left.

        Parameters
        ----------
        frames : int
            Audio frames.
        now_s : float, optional
            When the first reaches the plate, perf_counter s.

        Returns
        -------
        Modulation

        Raises
        ------
        DeviceError
            A stage whose signal is not audio.

        Examples
        --------
        Rendered later, the span gives what :meth:`pull` would have:

        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
        ...                                pull=lambda n, now_s: np.full(n, 3.0))
        >>> plate = load_profile("sim-plate")
        >>> pulled = OutputStage(steady, plate, "audio", 96000).pull(960, None)
        >>> span = OutputStage(steady, plate, "audio", 96000).modulation(960)
        >>> later = np.empty(960, dtype=np.float32)
        >>> span.render(later)
        >>> bool(np.array_equal(pulled, later))
        True
        """
        if self.signal != "audio":
            raise DeviceError("only an audio output stage modulates a carrier")
        knots, first_frame, carrier, offset = self._span(frames, now_s)
        knots = knots.copy()  # the stage's buffer moves on; the span is rendered later
        if not self.carrier.period:
            carrier = carrier.copy()
        self._consume(frames)
        return Modulation(knots, first_frame, self.upsampling, self._scale, carrier, offset, frames)

    @property
    def _pending(self) -> np.ndarray:
        """Limited control samples not yet played out (a view of the stage's buffer)."""
        return self._knots[1:1 + self._count]

    def _span(self, frames: int, now_s: float | None) -> tuple[np.ndarray, int, np.ndarray, int]:
        """Pull and limit what the next ``frames`` audio frames need; return their knots (a view of the
        stage's buffer, valid until :meth:`_consume`), the first frame's place among them, and the carrier
        (table and offset)."""
        up = self.upsampling
        count = self._count
        available = count * up - self._played
        if frames > available:
            needed = -(-(frames - available) // up)
            if 1 + count + needed > len(self._knots):  # a longer block than any before: grow once
                grown = np.zeros(max(2 * len(self._knots), 1 + count + needed))
                grown[:1 + count] = self._knots[:1 + count]
                self._knots = grown
            self._limited(needed, now_s, self._knots[1 + count:1 + count + needed])
            self._count = count + needed
        # knot 0 is the last control sample already played out, knot i + 1 is pending sample i
        last = (self._played + frames - 1) // up
        if self.carrier.period:
            carrier, offset = self.carrier.span(frames)
        else:
            if len(self._carrier_samples) < frames:
                self._carrier_samples = np.zeros(frames, dtype=np.float32)
            carrier, offset = self.carrier.span(frames, self._carrier_samples[:frames])
        return self._knots[:last + 2], self._played, carrier, offset

    def _consume(self, frames: int) -> None:
        """Move past ``frames`` audio frames: the control samples they used up leave the knots."""
        up = self.upsampling
        consumed = (self._played + frames) // up
        if consumed:
            knots = self._knots
            self._last_drive = float(knots[consumed])
            knots[0] = knots[consumed]
            remaining = self._count - consumed
            for k in range(1, remaining + 1):  # at most a control period's worth: no block-sized copy
                knots[k] = knots[consumed + k]
            self._count = remaining
        self._played = (self._played + frames) % up
        self.frames += frames

    def request_stop(self) -> None:
        """Ask the envelope source to ramp down to rest.

        Examples
        --------
        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> source = types.SimpleNamespace(finished=False, pull=lambda n, now_s: np.zeros(n))
        >>> source.request_stop = lambda: setattr(source, "finished", True)
        >>> stage = OutputStage(source, load_profile("sim-plate"), "control")
        >>> stage.request_stop()
        >>> source.finished
        True
        """
        self.source.request_stop()

    @property
    def finished(self) -> bool:
        """The source is at rest and so is everything it gave that is still to play.

        Examples
        --------
        A source at rest, but a drive still to play out, is not finished until that drive has played:

        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> source = types.SimpleNamespace(finished=True, request_stop=lambda: None, pull=lambda n, now_s: np.zeros(n))
        >>> stage = OutputStage(source, load_profile("sim-plate"), "control")
        >>> stage.finished                                    # nothing played, nothing pending
        True
        """
        return (self.source.finished and self._last_drive < 1e-6
                and (len(self._pending) == 0 or float(self._pending.max()) < 1e-6))

    def status(self) -> dict:
        """The limiter's counters: how often and how far it lowered the drive.

        Returns
        -------
        dict
            ``limited_fraction``, ``worst_excess_um_pp``, ``limit_um_pp``, ``max_drive_um_pp``.

        Examples
        --------
        >>> import numpy as np, types
        >>> from ultraglide.devices.profiles import load_profile
        >>> steady = types.SimpleNamespace(finished=False, request_stop=lambda: None,
        ...                                pull=lambda n, now_s: np.full(n, 9.0))          # 9 µm p-p asked
        >>> stage = OutputStage(steady, load_profile("sim-plate"), "control")
        >>> _ = stage.pull(1200, None)
        >>> stage.status()
        {'limited_fraction': 1.0, 'worst_excess_um_pp': 3.0, 'limit_um_pp': 6.0, 'max_drive_um_pp': 8.0}
        """
        return self.limiter.status()


def output_stage(source: BlockSource, profile: PlateProfile, signal: str, rate_hz: float,
                 carrier_hz: float | None = None) -> OutputStage:
    """What every device's ``start(source)`` calls first: ``source`` behind the drive limiter, as this
    device's signal.

    A stage built for the same profile, signal and rates (by an app that wants its counters) is used as
    it is; any other source is wrapped.

    Parameters
    ----------
    source : BlockSource or OutputStage
        An envelope source: drive amplitudes (µm p-p) at the control rate.
    profile : PlateProfile
        The plate: its limits hold on whatever leaves.
    signal : {"control", "audio"}
        What the device takes: the limited envelope, or the envelope on the carrier (float32, [-1, 1]).
    rate_hz : float
        The device's rate (Hz): the control rate or a whole fraction of it, or an audio rate.
    carrier_hz : float, optional
        The audio signal's carrier (Hz); the plate's resonance by default.

    Returns
    -------
    OutputStage

    Raises
    ------
    DeviceError
        An output stage given for another plate, signal or rate, or a rate that does not fit.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.devices.profiles import load_profile
    >>> class Steady:                                       # 9 µm p-p asked, above the plate's 6 µm limit
    ...     finished = False
    ...     def pull(self, n, now_s): return np.full(n, 9.0)
    ...     def request_stop(self): pass
    >>> stage = output_stage(Steady(), load_profile("sim-plate"), "control", 12000)
    >>> float(stage.pull(1200, None)[-1])                   # held at the limit
    6.0
    """
    if isinstance(source, OutputStage):
        if not source.matches(profile, signal, rate_hz, carrier_hz):
            raise DeviceError(f"this output stage gives {source.signal} at {source.rate_hz:g} Hz for plate "
                              f"{source.profile.name}; the device needs {signal} at {float(rate_hz):g} Hz for "
                              f"plate {profile.name}")
        return source
    return OutputStage(source, profile, signal, rate_hz, carrier_hz)
