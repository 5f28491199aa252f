# pyright: basic
"""The functions of the public API that span packages: render a texture to a WAV file, and hand a
renderer to a device.

They live here, in the namespace's root, because ``apps`` is a leaf nothing imports; the commands
use them (``export`` writes through :func:`offline_stage` and :func:`write_wav`, ``play`` starts its
device with :func:`renderer_source`), so the library and the commands share one path.

Example, a 1 mm grating swiped at 100 mm/s for half a second::

    >>> import soundfile, tempfile, pathlib
    >>> import ultraglide
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "swipe.wav"
    >>> result = ultraglide.export_wav("grating-1mm", out, duration_s=0.5)
    >>> soundfile.info(out).samplerate, round(result.duration_s, 2)
    (96000, 0.53)
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import soundfile

from ultraglide import _wav_writer
from ultraglide.atomic import AtomicFile, write_failure
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.stage import OutputStage
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.render.engine.sources import offline_stage
from ultraglide.render.errors import RenderError
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.default_model import DEFAULT_MODEL
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.friction_models import MAX_FORCE_N, FrictionModel
from ultraglide.render.renderer import ControlBlock, RenderSettings
from ultraglide.render.renderer import Renderer as _Renderer
from ultraglide.render.trajectory import LiveTrajectory, RecordedTrajectory
from ultraglide.textures.library import as_texture
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

WAV_SUBTYPES = {"float32": "FLOAT", "int24": "PCM_24", "int16": "PCM_16"}
BLOCK_S = 1.0  # rendered and written a second at a time: memory stays flat whatever the length


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_wav` wrote: the file, its length (s), rate (Hz), sample format, the carrier
    (Hz), how often the plate's limit held the amplitude back (control samples), how often the envelope
    ramped, and what the drive limiter did.

    Attributes
    ----------
    path : pathlib.Path
        The WAV file.
    duration_s : float
        Its length (s): the path, then the output coming to rest.
    rate_hz : int
        Its sample rate (Hz).
    format : str
        Its sample format.
    carrier_hz : float
        The carrier (Hz).
    clipped_samples : int
        Control samples the plate's limit held back.
    ramps : int
        The envelope's ramps.
    limited_fraction : float
        The share of the time the drive limiter lowered the drive.
    worst_excess_um_pp : float
        The most drive (µm p-p) asked above what the limiter let through.

    Examples
    --------
    >>> import os, tempfile
    >>> result = export_wav("grating-1mm", os.path.join(tempfile.mkdtemp(), "swipe.wav"), duration_s=0.2)
    >>> result.rate_hz, result.format, result.carrier_hz, result.duration_s > 0.2     # the tail after the path
    (96000, 'float32', 25000.0, True)
    """

    path: Path
    duration_s: float
    rate_hz: int
    format: str
    carrier_hz: float
    clipped_samples: int
    ramps: int
    limited_fraction: float  # of the time the drive limiter lowered the drive
    worst_excess_um_pp: float  # most drive asked above what the limiter let through


TextureLike = Texture | str | os.PathLike | np.ndarray  # a texture, its name or file, or an array with width_mm


def as_model(model: FrictionModel | str | os.PathLike) -> FrictionModel:
    """A friction model, or one by name or file (:func:`load_model`).

    Parameters
    ----------
    model : FrictionModel, str or os.PathLike
        A model, a model's name (``stretched``, ``exponential`` ...), ``table:FILE.csv`` or a ``CAL.toml``.

    Returns
    -------
    FrictionModel

    Raises
    ------
    ModelError
        Not a model nor a name, or what :func:`load_model` refuses.

    Examples
    --------
    >>> as_model("exponential")
    ExponentialModel(tau_um_zp=1.32)
    """
    if isinstance(model, FrictionModel):
        return model
    if not isinstance(model, str | os.PathLike):
        raise ModelError(f"a model is a FrictionModel or a model's name (stretched, squeeze-film, exponential, paper, "
                         f"table:FILE.csv or CAL.toml); got {type(model).__name__}")
    return load_model(os.fspath(model))


def as_profile(profile: PlateProfile | str | os.PathLike) -> PlateProfile:
    """A plate profile, or one by bundled name or TOML file (:func:`load_profile`).

    Parameters
    ----------
    profile : PlateProfile, str or os.PathLike
        A profile, a bundled profile's name (``sim-plate``) or a TOML file.

    Returns
    -------
    PlateProfile

    Raises
    ------
    DeviceError
        Not a profile nor a name, or what :func:`load_profile` refuses.

    Examples
    --------
    >>> as_profile("sim-plate").max_amplitude_um_pp                   # µm p-p
    6.0
    """
    if isinstance(profile, PlateProfile):
        return profile
    if not isinstance(profile, str | os.PathLike):
        raise DeviceError(f"a plate profile is a PlateProfile or a profile's name or TOML file (e.g. sim-plate); got "
                          f"{type(profile).__name__}")
    return load_profile(os.fspath(profile))


class Renderer(_Renderer):
    """The renderer: finger → friction ratio → amplitude → drive envelope (µm p-p), block by block.

    :class:`ultraglide.render.renderer.Renderer`, taking names, files and arrays wherever it takes objects.
    It makes the *control* signal: the drive envelope at the control rate (:attr:`control_rate_hz`,
    12 kHz by default), µm p-p of plate amplitude; a device's output stage limits it and, for a sound card
    or a WAV file, puts it on the carrier to make the *audio* signal (:func:`render_swipe` gives both).

    Parameters
    ----------
    texture : Texture, str, os.PathLike or numpy.ndarray
        A texture, a library name, a texture or image file, or a 2-D array of friction ratios (0..1) with
        ``width_mm`` (see :func:`ultraglide.textures.library.as_texture`).
    model : FrictionModel or str
        A friction model or its name: ``dynamic`` (the default: ``stretched``, force-aware, with the published
        friction dynamics, so the renderer plans the friction felt), ``stretched``, ``squeeze-film``,
        ``exponential``, ``paper``, ``table:FILE.csv``, ``CAL.toml``, ``dynamic:NAME``, ``speed:S:NAME`` (the
        reduction weakening with sliding speed, an assumed law: rendered at the finger's speed, block by block).
    profile : PlateProfile or str
        The plate's profile or its bundled name or file (default ``sim-plate``).
    settings : RenderSettings
        Rates (Hz), times (s) and limits of the rendering.
    trajectory : SwipePath, RecordedTrajectory or None
        The finger's path for offline rendering; None: a live finger, fed with :meth:`push`.
    effects : tuple, optional
        Temporal effects (``textures.effects.Binding``) to play instead of the texture's own.
    sampler : Sampler, optional
        The lookup already built for ``texture`` (reused across renderers of the same texture).
    width_mm, height_mm : float, optional
        The physical size (mm) of a texture given as an array; height by default from square pixels.

    Raises
    ------
    UltraglideError
        A name that does not resolve (``TextureError``, ``ModelError``, ``DeviceError``), or a carrier the
        plate or the audio rate refuses (``RenderError``); each in one line saying what to give.

    Examples
    --------
    >>> import ultraglide
    >>> r = ultraglide.Renderer("grating-1mm", "stretched", "sim-plate", trajectory=ultraglide.SwipePath())
    >>> block = r.control(duration_s=0.5)             # half a second of envelope at 12 kHz
    >>> len(block.drive_um_pp), bool(block.drive_um_pp.max() <= r.profile.max_drive_um_pp)
    (6000, True)
    """

    def __init__(self, texture: TextureLike, model: FrictionModel | str = DEFAULT_MODEL,
                 profile: PlateProfile | str = "sim-plate", settings: RenderSettings = RenderSettings(),  # noqa: B008 - frozen
                 trajectory: RecordedTrajectory | SwipePath | LiveTrajectory | None = None,
                 effects: tuple | None = None, sampler: Sampler | None = None, *,
                 width_mm: float | None = None, height_mm: float | None = None) -> None:
        super().__init__(as_texture(texture, width_mm=width_mm, height_mm=height_mm), as_model(model),
                         as_profile(profile), settings, trajectory, effects, sampler)

    def set_texture(self, texture: TextureLike, *, width_mm: float | None = None,
                    height_mm: float | None = None) -> None:
        """Render another texture (an object, a name, a file, or an array with ``width_mm``) from the next block
        on; its lookup tables are built here.

        Parameters
        ----------
        texture : Texture, str, os.PathLike or array_like
            A texture, a library name or file, or an array of friction ratios.
        width_mm, height_mm : float, optional
            An array's physical size, mm (the height: square pixels by default).

        Raises
        ------
        TextureError
            A name or file that is no texture, or an array without its size.

        Examples
        --------
        >>> import numpy as np
        >>> renderer = Renderer("grating-1mm")
        >>> renderer.set_texture("grating-2mm")
        >>> renderer.texture.name
        'grating-2mm'
        >>> renderer.set_texture(np.full((20, 40), 0.5), width_mm=80.0)        # 2 mm pixels: 40 mm high
        >>> renderer.texture.width_mm, renderer.texture.height_mm
        (80.0, 40.0)
        """
        super().set_texture(as_texture(texture, width_mm=width_mm, height_mm=height_mm))

    def set_model(self, model: FrictionModel | str) -> None:
        """Use another friction model (an object or a name) from the next block on.

        Parameters
        ----------
        model : FrictionModel or str
            A model, or its name (``stretched``, ``exponential``, ``squeeze-film``, ``paper``, ``table:FILE.csv``,
            ``CAL.toml``).

        Raises
        ------
        ModelError
            An unknown name.

        Examples
        --------
        >>> renderer = Renderer("grating-1mm")
        >>> renderer.set_model("exponential")
        >>> type(renderer.model).__name__
        'ExponentialModel'
        """
        super().set_model(as_model(model))


def export_duration_s(renderer: Renderer) -> float:
    """How long an export of ``renderer``'s path lasts: the path, then the output coming to rest (s).

    Parameters
    ----------
    renderer : Renderer
        A renderer with a recorded or synthetic path.

    Returns
    -------
    float
        The path's duration plus the renderer's ``tail_s`` (s).

    Raises
    ------
    RenderError
        A renderer that follows a live finger (it has no end).

    Examples
    --------
    >>> renderer = Renderer("grating-1mm", trajectory=SwipePath(duration_s=0.1))
    >>> export_duration_s(renderer) == 0.1 + renderer.tail_s
    True
    """
    trajectory = renderer.trajectory
    if isinstance(trajectory, LiveTrajectory):
        raise RenderError("a renderer that follows a live finger has no end: give it a trajectory to export")
    return trajectory.end_s - trajectory.start_s + renderer.tail_s


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity where the system has one).

    Returns
    -------
    int
        1 or more.

    Examples
    --------
    >>> available_cpus() >= 1
    True
    """
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def write_wav(stage: OutputStage, path: str | os.PathLike, frames: int, format: str = "float32",
              progress: Callable[[int], None] | None = None, threads: int | None = None,
              process: bool | None = None) -> float:
    """Pull ``frames`` of audio from ``stage`` into a mono WAV at ``path``, as it is given (no temporary
    file), a second at a time. RF64 is used beyond 4 GB.

    Work is split by what it depends on: the control-rate envelope (a recursion) and the limiter run in
    order on this thread; putting each block on the carrier depends on each frame's index alone, so it
    runs in ``threads`` chunks (default: one per CPU) while this thread computes the next block, and
    the blocks are written in order. With ``process`` (the default where ``fork`` exists: Linux) the
    carrier and the writing are done by a forked writer process, otherwise by threads of this one
    (:mod:`ultraglide._wav_writer`). A few blocks are held at most, so memory does not grow with the
    length.

    Parameters
    ----------
    stage : OutputStage
        An output stage whose signal is audio (:func:`offline_stage`).
    path : str or os.PathLike
        The WAV file.
    frames : int
        How many frames to write.
    format : {"float32", "int24", "int16"}
        The samples' format.
    progress : callable, optional
        Told of the frames of each block written.
    threads : int, optional
        How many chunks to put on the carrier at once, 1 or more; one per CPU by default.
    process : bool, optional
        Write from a forked process (the default where ``fork`` exists) or from threads of this one.

    Returns
    -------
    float
        The duration written (s).

    Raises
    ------
    RenderError
        An unknown format, a stage whose signal is not audio, or fewer than one thread.

    Examples
    --------
    >>> import os, tempfile, soundfile
    >>> stage = offline_stage(Renderer("grating-1mm", trajectory=SwipePath(duration_s=0.1)))
    >>> path = os.path.join(tempfile.mkdtemp(), "swipe.wav")
    >>> write_wav(stage, path, 9600)                                    # s: 9600 frames at 96 kHz
    0.1
    >>> info = soundfile.info(path)
    >>> info.samplerate, info.frames, info.channels, info.subtype
    (96000, 9600, 1, 'FLOAT')
    """
    if format not in WAV_SUBTYPES:
        raise RenderError(f"format must be one of {', '.join(WAV_SUBTYPES)}, got {format!r}")
    if stage.signal != "audio":
        raise RenderError("a WAV file takes audio: give an output stage whose signal is audio")
    threads = available_cpus() if threads is None else int(threads)
    if threads < 1:
        raise RenderError(f"threads must be at least 1, got {threads}")
    rate = int(stage.rate_hz)
    block = int(BLOCK_S * rate)
    container = "RF64" if frames * 4 > 4_000_000_000 else "WAV"
    jobs = (stage.modulation(min(block, frames - done)) for done in range(0, frames, block))
    write = _wav_writer.write_in_process if (_wav_writer.fork_available() if process is None else process) \
        else _wav_writer.write_file
    write(jobs, os.fspath(path), rate, WAV_SUBTYPES[format], container, threads, progress or (lambda frames: None))
    return frames / rate


def _renderer(texture: TextureLike, trajectory: RecordedTrajectory | SwipePath | None, model: FrictionModel | str,
              profile: PlateProfile | str, settings: RenderSettings | None, rate_hz: int, speed_mm_s: float,
              duration_s: float, force_n: float | None, width_mm: float | None,
              height_mm: float | None) -> Renderer:
    """The offline renderer an export or a render makes: the texture, the path (a straight swipe across the middle
    by default) and the force checked as the commands check them."""
    texture = as_texture(texture, width_mm=width_mm, height_mm=height_mm)
    if settings is None:
        settings = RenderSettings(audio_rate_hz=rate_hz)
    if trajectory is None:
        trajectory = SwipePath.across(texture.width_mm, texture.height_mm, speed_mm_s=speed_mm_s, duration_s=duration_s,
                                      force_n=force_n)
    elif not isinstance(trajectory, RecordedTrajectory | SwipePath):
        raise RenderError(f"a path is a SwipePath or a RecordedTrajectory (read_touch_log), got "
                          f"{type(trajectory).__name__}")
    elif force_n is not None:
        if (trajectory.has_force if isinstance(trajectory, RecordedTrajectory) else trajectory.force_n is not None):
            raise RenderError("the trajectory brings its own force; give force_n only for one that logs none")
        if not 0 < force_n <= MAX_FORCE_N:
            raise RenderError(f"force_n must be a positive force up to {MAX_FORCE_N:g} N, a fingertip's touch range, "
                              f"got {force_n}")
        settings = dataclasses.replace(settings, default_force_n=float(force_n))
    return Renderer(texture, model, profile, settings, trajectory=trajectory)


def export_wav(texture: TextureLike, path: str | os.PathLike,
               trajectory: RecordedTrajectory | SwipePath | None = None, *,
               model: FrictionModel | str = DEFAULT_MODEL, profile: PlateProfile | str = "sim-plate",
               settings: RenderSettings | None = None, rate_hz: int = 96000, format: str = "float32",
               speed_mm_s: float = 100.0, duration_s: float = 5.0, force_n: float | None = None,
               observers: Iterable[Callable[[ControlBlock], None]] = (), width_mm: float | None = None,
               height_mm: float | None = None) -> ExportResult:
    """Render a texture along a finger's path to a WAV file: the audio signal a plate driven by a DAC would get.

    The file holds the path, then the output coming to rest; it appears whole or not at all (a temporary
    file renamed into place). Rendered a second at a time: memory stays flat whatever the length.

    Parameters
    ----------
    texture : Texture, str, os.PathLike or numpy.ndarray
        A texture, a library name, a texture or image file (an image is authored with default options),
        or a 2-D array of friction ratios (0..1) with ``width_mm``.
    path : str or os.PathLike
        The ``.wav`` file to write.
    trajectory : SwipePath or RecordedTrajectory, optional
        The finger's path (:class:`SwipePath`, or a touch log read by :func:`read_touch_log`); by default a
        straight swipe across the middle at ``speed_mm_s`` for ``duration_s``.
    model : FrictionModel or str
        The friction model or its name (``dynamic``, the default: ``stretched`` with the published friction
        dynamics; ``stretched``, ``squeeze-film``, ``exponential``, ``paper``, ``table:F.csv``, ``CAL.toml``).
    profile : PlateProfile or str
        The plate's profile or its name (default ``sim-plate``).
    settings : RenderSettings, optional
        The renderer's settings; their ``audio_rate_hz`` wins over ``rate_hz``.
    rate_hz : int
        The file's sample rate (Hz), a whole multiple of the control rate (12 kHz).
    format : {"float32", "int24", "int16"}
        The sample format; full scale (1.0) is the plate's full-scale drive.
    speed_mm_s, duration_s : float
        The default swipe's speed (mm/s) and length (s).
    force_n : float, optional
        The finger's force (N); with a recorded path, only for one that logs no force.
    observers : iterable of callables
        Each is given every control block (:class:`ultraglide.render.renderer.ControlBlock`) as it is rendered.
    width_mm, height_mm : float, optional
        The physical size (mm) of a texture given as an array.

    Returns
    -------
    ExportResult
        The file, its length (s), rate (Hz), format, carrier (Hz) and what the limits did.

    Raises
    ------
    UltraglideError
        Bad input, in one line (``TextureError``, ``ModelError``, ``DeviceError``, ``RenderError``); nothing is
        written. An ``OSError`` (a full disk) says what could not be written, and leaves nothing behind.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np, soundfile, ultraglide
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "bars.wav"
    >>> bars = np.tile([0.3, 1.0], (8, 20))                    # 40 columns: 2 mm bars over 80 mm
    >>> result = ultraglide.export_wav(bars, out, width_mm=80.0, duration_s=0.25)
    >>> soundfile.info(out).samplerate, result.carrier_hz
    (96000, 25000.0)
    """
    if format not in WAV_SUBTYPES:
        raise RenderError(f"format must be one of {', '.join(WAV_SUBTYPES)}, got {format!r}")
    path = Path(path)
    if path.suffix.lower() != ".wav":
        raise RenderError(f"the output must be a .wav file, got {path}")
    renderer = _renderer(texture, trajectory, model, profile, settings, rate_hz, speed_mm_s, duration_s, force_n,
                         width_mm, height_mm)
    renderer.observers.extend(observers)
    stage = offline_stage(renderer)
    rate = renderer.settings.audio_rate_hz
    frames = int(round(export_duration_s(renderer) * rate))
    with AtomicFile(path) as target:  # the one atomic writer: the file appears whole or not at all
        try:
            written_s = write_wav(stage, target.temporary, frames, format)
        except soundfile.LibsndfileError as error:  # a full disk or a file too large: one line naming the file
            raise write_failure(path, target.temporary, error) from None
    counters, limiter = renderer.counters, stage.limiter
    return ExportResult(path, written_s, rate, format, renderer.carrier_hz,
                        counters.clipped_samples, counters.ramps, limiter.limited_fraction, limiter.worst_excess_um_pp)


@dataclass(frozen=True, eq=False)
class Rendered:
    """A swipe rendered to arrays (:func:`render_swipe`): the audio signal and the control signal behind it.

    Two signals, two rates. The *control* signal is the drive envelope, one value per control period
    (``control_rate_hz``, 12 kHz by default), in µm p-p of plate amplitude: what a plate whose firmware
    makes the carrier is streamed. The *audio* signal is that envelope, limited, on the carrier
    (``carrier_hz``) at ``rate_hz``: what a DAC or a sound card drives a plate with, float32 in
    [-1, 1] where 1 is the plate's full-scale drive (``full_scale_um_pp``).

    Attributes
    ----------
    audio : numpy.ndarray
        The audio signal (float32, ``rate_hz``), the path and then the output coming to rest.
    rate_hz : int
        The audio signal's sample rate (Hz).
    carrier_hz : float
        The carrier (Hz): the plate's resonance unless the settings say otherwise.
    full_scale_um_pp : float
        The drive (µm p-p) that an audio sample of 1.0 stands for.
    control_rate_hz : float
        The control signal's rate (Hz).
    time_s : numpy.ndarray
        Each control sample's time (s, on the path's clock: a swipe starts at 0).
    x_mm, y_mm : numpy.ndarray
        The finger's position at each control sample (mm from the texture's top-left corner).
    touching : numpy.ndarray
        Whether the finger touches (bool).
    ratio : numpy.ndarray
        The target friction ratio under the finger (1 = the plate at rest).
    target_um_pp : numpy.ndarray
        The model's amplitude for ``planned_ratio`` at the finger's force, within the limit (µm p-p).
    envelope_um_pp : numpy.ndarray
        The amplitude the plate should make after ramps and band and slew limits (µm p-p).
    drive_um_pp : numpy.ndarray
        The drive envelope after the drive limiter (µm p-p): what the audio carries.
    limit_um_pp : float
        The plate's amplitude limit (µm p-p, its profile's ``max_amplitude_um_pp``), which ``target_um_pp``
        and ``envelope_um_pp`` stay within.
    limited_fraction : float
        The fraction of control samples the drive limiter lowered.
    planned_ratio : numpy.ndarray
        The ratio the model's inverse was asked for: under friction dynamics (the default model) the planner's
        command, which leads the texture so the friction felt follows it; else ``ratio``.

    Examples
    --------
    >>> import ultraglide
    >>> swipe = ultraglide.render_swipe("dots", duration_s=0.2)
    >>> swipe
    Rendered(0.233 s of audio at 96000 Hz on a 25000 Hz carrier, 2794 control samples at 12000 Hz)
    >>> len(swipe.audio) == round(swipe.duration_s * swipe.rate_hz)
    True
    """

    audio: np.ndarray
    rate_hz: int
    carrier_hz: float
    full_scale_um_pp: float
    control_rate_hz: float
    time_s: np.ndarray
    x_mm: np.ndarray
    y_mm: np.ndarray
    touching: np.ndarray
    ratio: np.ndarray
    target_um_pp: np.ndarray
    envelope_um_pp: np.ndarray
    drive_um_pp: np.ndarray
    limit_um_pp: float
    limited_fraction: float
    planned_ratio: np.ndarray

    @property
    def duration_s(self) -> float:
        """The audio's length (s): its samples over its rate.

        Examples
        --------
        >>> rendered = render_swipe("grating-1mm", duration_s=0.05)
        >>> rendered.duration_s == len(rendered.audio) / 96000, rendered.duration_s > 0.05    # the swipe, then its tail
        (True, True)
        """
        return len(self.audio) / self.rate_hz

    def __repr__(self) -> str:
        return (f"Rendered({self.duration_s:.3g} s of audio at {self.rate_hz} Hz on a {self.carrier_hz:g} Hz carrier, "
                f"{len(self.time_s)} control samples at {self.control_rate_hz:g} Hz)")


def render_swipe(texture: TextureLike, path: SwipePath | RecordedTrajectory | None = None, *,
                 duration_s: float | None = None, rate_hz: int = 96000, speed_mm_s: float = 100.0,
                 force_n: float | None = None, model: FrictionModel | str = DEFAULT_MODEL,
                 profile: PlateProfile | str = "sim-plate", settings: RenderSettings | None = None,
                 width_mm: float | None = None, height_mm: float | None = None) -> Rendered:
    """Render a finger's path over a texture to arrays: the audio signal, its rate, and the control signal.

    The same path from renderer to samples as :func:`export_wav` (its file holds the same samples), kept in
    memory: for a few seconds, or a swipe to analyse; write long ones with :func:`export_wav`.

    Parameters
    ----------
    texture : Texture, str, os.PathLike or numpy.ndarray
        A texture, a library name, a texture or image file, or a 2-D array of friction ratios (0..1) with
        ``width_mm``.
    path : SwipePath or RecordedTrajectory, optional
        The finger's path; by default a straight swipe across the texture's middle at ``speed_mm_s``.
    duration_s : float, optional
        The default swipe's length (s), 1 s unless given; a path given brings its own.
    rate_hz : int
        The audio signal's sample rate (Hz), a whole multiple of the control rate (12 kHz).
    speed_mm_s : float
        The default swipe's speed (mm/s).
    force_n : float, optional
        The finger's force (N); with a recorded path, only for one that logs no force.
    model : FrictionModel or str
        The friction model or its name (default ``dynamic``: ``stretched`` with the published friction dynamics).
    profile : PlateProfile or str
        The plate's profile or its name (default ``sim-plate``).
    settings : RenderSettings, optional
        The renderer's settings; their ``audio_rate_hz`` wins over ``rate_hz``.
    width_mm, height_mm : float, optional
        The physical size (mm) of a texture given as an array.

    Returns
    -------
    Rendered
        The audio (float32 at ``rate_hz``, the path then the output coming to rest) and, at the control
        rate, the finger, the target ratio, the target amplitude, the envelope and the limited drive.

    Raises
    ------
    UltraglideError
        Bad input, in one line: a texture, model or profile that does not resolve, an array without
        ``width_mm``, a ``duration_s`` beside a path, a rate that is not a multiple of the control rate.

    Examples
    --------
    >>> import numpy as np, ultraglide
    >>> swipe = ultraglide.render_swipe("grating-1mm", duration_s=0.5)
    >>> swipe.rate_hz, swipe.control_rate_hz, swipe.carrier_hz
    (96000, 12000.0, 25000.0)
    >>> bool(swipe.envelope_um_pp.max() <= swipe.limit_um_pp), bool(np.abs(swipe.audio).max() <= 1.0)
    (True, True)
    """
    if path is not None and duration_s is not None:
        raise RenderError("a path brings its own duration: give duration_s only for the default swipe")
    duration_s = 1.0 if duration_s is None else duration_s
    if not (isinstance(duration_s, int | float) and math.isfinite(duration_s) and duration_s > 0):
        raise RenderError(f"duration_s must be a positive number of seconds, got {duration_s!r}")
    renderer = _renderer(texture, path, model, profile, settings, rate_hz, speed_mm_s, duration_s, force_n,
                         width_mm, height_mm)
    blocks: list[ControlBlock] = []
    renderer.observers.append(blocks.append)  # offline blocks are new arrays each: kept as they are
    stage = offline_stage(renderer)
    drives: list[np.ndarray] = []
    stage.observers.append(drives.append)  # the limited drive, each block the stage's to keep
    rate = renderer.settings.audio_rate_hz
    frames = int(round(export_duration_s(renderer) * rate))
    block = int(BLOCK_S * rate)
    audio = np.empty(frames, dtype=np.float32)
    for start in range(0, frames, block):
        stop = min(frames, start + block)
        stage.pull(stop - start, None, audio[start:stop])

    def joined(name: str, dtype: type = float) -> np.ndarray:
        parts = [np.broadcast_to(getattr(b, name), b.time_s.shape) for b in blocks]
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)

    return Rendered(audio, rate, renderer.carrier_hz, stage.profile.full_scale_um_pp, renderer.control_rate_hz,
                    joined("time_s"), joined("x_mm"), joined("y_mm"), joined("down", bool),
                    joined("ratio"), joined("target_um_pp"), joined("amplitude_um_pp"),
                    np.concatenate(drives) if drives else np.zeros(0), renderer.limit_um_pp,
                    stage.limiter.limited_fraction, joined("planned_ratio"))
