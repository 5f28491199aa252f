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
    (96000, 0.52)
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import soundfile

from ultraglide import _wav_writer
from ultraglide.atomic import AtomicFile, write_failure
from ultraglide.devices.output.stage import OutputStage
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.render.engine.sources import offline_stage
from ultraglide.render.errors import RenderError
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.friction_models import MAX_FORCE_N, FrictionModel
from ultraglide.render.renderer import ControlBlock, Renderer, RenderSettings
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.texture import Texture

WAV_SUBTYPES = {"float32": "FLOAT", "int24": "PCM_24", "int16": "PCM_16"}
BLOCK_S = 1.0  # rendered and written a second at a time: memory stays flat whatever the length


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_wav` wrote: the file, its length (s), rate (Hz), sample format, the carrier
    (Hz), how often the plate's limit held the amplitude back (control samples), how often the envelope
    ramped, and what the drive limiter did."""

    path: Path
    duration_s: float
    rate_hz: int
    format: str
    carrier_hz: float
    clipped_samples: int
    ramps: int
    limited_fraction: float  # of the time the drive limiter lowered the drive
    worst_excess_um_pp: float  # most drive asked above what the limiter let through


def _as_texture(texture: Texture | str | os.PathLike) -> Texture:
    return texture if isinstance(texture, Texture) else resolve_texture(os.fspath(texture))


def _as_model(model: FrictionModel | str) -> FrictionModel:
    return model if isinstance(model, FrictionModel) else load_model(str(model))


def _as_profile(profile: PlateProfile | str) -> PlateProfile:
    return profile if isinstance(profile, PlateProfile) else load_profile(str(profile))


def export_duration_s(renderer: Renderer) -> float:
    """How long an export of ``renderer``'s path lasts: the path, then the output coming to rest (s)."""
    trajectory = renderer.trajectory
    return trajectory.end_s - trajectory.start_s + renderer.tail_s


def available_cpus() -> int:
    """The CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def write_wav(stage: OutputStage, path: str | os.PathLike, frames: int, format: str = "float32",
              progress: Callable[[int], None] | None = None, threads: int | None = None,
              process: bool | None = None) -> float:
    """Pull ``frames`` of audio from ``stage`` into a mono WAV at ``path``, as it is given (no temporary
    file), a second at a time. Returns the duration written (s). RF64 is used beyond 4 GB.

    Work is split by what it depends on: the control-rate envelope (a recursion) and the limiter run in
    order on this thread; putting each block on the carrier depends on each frame's index alone, so it
    runs in ``threads`` chunks (default: one per CPU) while this thread computes the next block, and
    the blocks are written in order. With ``process`` (the default where ``fork`` exists: Linux) the
    carrier and the writing are done by a forked writer process, otherwise by threads of this one
    (:mod:`ultraglide._wav_writer`). A few blocks are held at most, so memory does not grow with the
    length. ``progress`` is told of the frames of each block written."""
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


def export_wav(texture: Texture | str | os.PathLike, path: str | os.PathLike,
               trajectory: RecordedTrajectory | SwipePath | None = None, *,
               model: FrictionModel | str = "stretched", profile: PlateProfile | str = "sim-plate",
               settings: RenderSettings | None = None, rate_hz: int = 96000, format: str = "float32",
               speed_mm_s: float = 100.0, duration_s: float = 5.0, force_n: float | None = None,
               observers: Iterable[Callable[[ControlBlock], None]] = ()) -> ExportResult:
    """Render a texture along a finger's path to a WAV file: what a plate driven by a DAC would get.

    ``texture``: a :class:`Texture`, a texture file, an image (authored with default options) or a
    library name. ``trajectory``: a recorded path (:func:`read_touch_log`) or a :class:`SwipePath`;
    by default a straight swipe across the middle at ``speed_mm_s`` (mm/s) for ``duration_s`` (s)
    at ``force_n`` (N); with a recorded path that logs no force, ``force_n`` is its force (a path that
    logs its own force and a ``force_n`` are refused together). ``model``: a model or its name
    (``stretched``, the force-aware default; ``squeeze-film``, ``exponential``, ``paper``, ``table:F.csv``,
    ``CAL.toml`` ...); ``profile``: the plate's profile or its name. ``settings`` overrides the
    renderer's (its ``audio_rate_hz`` wins over ``rate_hz``). ``format``: ``float32``, ``int24`` or
    ``int16``, full scale = the plate's full-scale drive. ``observers`` are given each control block.
    The file appears whole or not at all (a temporary file renamed into place).
    """
    texture = _as_texture(texture)
    if settings is None:
        settings = RenderSettings(audio_rate_hz=rate_hz)
    if trajectory is None:
        trajectory = SwipePath.across(texture.width_mm, texture.height_mm, speed_mm_s=speed_mm_s, duration_s=duration_s,
                                       force_n=force_n)
    elif force_n is not None:
        if (trajectory.has_force if isinstance(trajectory, RecordedTrajectory) else trajectory.force_n is not None):
            raise RenderError("the trajectory brings its own force; give force_n only for one that logs none")
        if not 0 < force_n <= MAX_FORCE_N:
            raise RenderError(f"force_n must be a positive force up to {MAX_FORCE_N:g} N, a fingertip's touch range, "
                              f"got {force_n}")
        settings = dataclasses.replace(settings, default_force_n=float(force_n))
    if format not in WAV_SUBTYPES:
        raise RenderError(f"format must be one of {', '.join(WAV_SUBTYPES)}, got {format!r}")
    path = Path(path)
    if path.suffix.lower() != ".wav":
        raise RenderError(f"the output must be a .wav file, got {path}")
    renderer = Renderer(texture, _as_model(model), _as_profile(profile), settings, trajectory=trajectory)
    renderer.observers.extend(observers)
    stage = offline_stage(renderer)
    frames = int(round(export_duration_s(renderer) * settings.audio_rate_hz))
    with AtomicFile(path) as target:  # the one atomic writer: the file appears whole or not at all
        try:
            written_s = write_wav(stage, target.temporary, frames, format)
        except soundfile.LibsndfileError as error:  # a full disk or a file too large: one line naming the file
            raise write_failure(path, target.temporary, error) from None
    counters, limiter = renderer.counters, stage.limiter
    return ExportResult(path, written_s, settings.audio_rate_hz, format, renderer.carrier_hz,
                        counters.clipped_samples, counters.ramps, limiter.limited_fraction, limiter.worst_excess_um_pp)
