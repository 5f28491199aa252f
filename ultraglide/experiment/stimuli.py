"""Stimuli for threshold experiments: one texture per trial, its zones side by side.

A trial shows ``zones`` fields of ``zone_mm`` with plain glass between them; the target zone holds
the stimulus at the procedure's level, the others the reference. What the level means:

* ``contrast``: the friction contrast of TEXTURE: its map rescaled so that its stickiest point is
  at rest (ratio 1) and its most slippery at 1 − level. Reference: plain glass (or ``--reference``).
* ``wavelength``: discrimination of spatial period: TEXTURE must be a grating; the reference zones
  keep its wavelength λ0, the target has λ0 + level (mm), same contrast and shape.
* ``amplitude``: a uniform vibration of ``level`` µm p-p over the whole zone (the friction ratio the
  model gives for it at the finger's force); reference: the plate at rest.

:func:`render_offline` renders a swipe across the trial's texture through the real renderer and its
output stage (envelope, plate model, drive limiter, carrier) into a buffer, as a null device would receive it,
and measures what each zone really rendered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ultraglide.devices.profiles import PlateProfile
from ultraglide.render.engine.sources import offline_stage
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.textures import procedural
from ultraglide.textures.compose import Placement, compose
from ultraglide.textures.errors import TextureError
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

PARAMETERS = {"contrast": "friction contrast (1 - ratio)", "wavelength": "mm", "amplitude": "µm p-p"}
PX_PER_MM = 10.0
EDGE_MM = 3.0  # zone edges left out of the rendered measures (ramps, band limits)


@dataclass(frozen=True)
class Layout:
    """Zones side by side, ``gap_mm`` of plain glass around each. Sizes in mm."""

    zones: int = 2
    zone_mm: tuple[float, float] = (40.0, 40.0)
    gap_mm: float = 10.0

    @property
    def size_mm(self) -> tuple[float, float]:
        width, height = self.zone_mm
        return self.zones * width + (self.zones + 1) * self.gap_mm, height + 2 * self.gap_mm

    def zone_left_mm(self, index: int) -> float:
        return self.gap_mm + index * (self.zone_mm[0] + self.gap_mm)

    def zone_at(self, x_mm: float, y_mm: float) -> int | None:
        """The zone under a point, or None."""
        for index in range(self.zones):
            left = self.zone_left_mm(index)
            if left <= x_mm < left + self.zone_mm[0] and self.gap_mm <= y_mm < self.gap_mm + self.zone_mm[1]:
                return index
        return None


def with_contrast(texture: Texture, contrast: float) -> Texture:
    """``texture`` rescaled so its friction spans [1 − contrast, 1] (its own pattern kept)."""
    if not 0 <= contrast <= 1:
        raise TextureError(f"a friction contrast lies in 0..1, got {contrast:g}")
    if texture.kind == "gradient":
        return texture.with_(ratio_range=(1.0 - contrast, 1.0))
    values = texture.values.astype(np.float64)
    span = float(values.max() - values.min())
    normalised = (values - values.min()) / span if span > 0 else np.ones_like(values)
    return texture.with_(values=(1.0 - contrast * (1.0 - normalised)).astype(np.float32))


def plain(layout: Layout, ratio: float = 1.0) -> Texture:
    return Texture(np.full((2, 2), ratio, dtype=np.float32), *layout.zone_mm, name="plain glass")


@dataclass(frozen=True)
class StimulusDesign:
    """What varies and what the zones show. ``reference``: what the non-target zones show (None: plain
    glass, or for ``wavelength`` the grating at its own wavelength)."""

    texture: Texture
    parameter: str = "contrast"
    layout: Layout = Layout()
    reference: Texture | None = None
    model: FrictionModel | None = None  # for ``amplitude``: the ratio a vibration amplitude gives
    force_n: float = 0.5
    zone_at: object = None  # for ``contrast``: a callable giving the target zone at a level, instead of rescaling

    def __post_init__(self) -> None:
        if self.parameter not in PARAMETERS:
            raise TextureError(f"--vary must be one of {', '.join(PARAMETERS)}, got {self.parameter!r}")
        if self.parameter == "wavelength" and self.texture.authoring.get("generator") != "grating":
            raise TextureError(f"--vary wavelength needs a grating texture; {self.texture.name or 'this'} is not one")
        if self.parameter == "amplitude" and self.model is None:
            raise TextureError("--vary amplitude needs a friction model")

    @property
    def unit(self) -> str:
        return PARAMETERS[self.parameter]

    @property
    def base_wavelength_mm(self) -> float:
        return float(self.texture.authoring.get("wavelength_mm", 0.0))

    def zone_texture(self, level: float) -> Texture:
        """The target zone's texture at ``level``."""
        if self.parameter == "contrast":
            return with_contrast(self.texture, level) if self.zone_at is None else self.zone_at(level)
        if self.parameter == "wavelength":
            return self._grating(self.base_wavelength_mm + level)
        ratio = float(self.model.relative_friction(np.array([level]), self.force_n)[0]) if level > 0 else 1.0
        return plain(self.layout, ratio).with_(name=f"uniform {level:g} µm p-p")

    def _grating(self, wavelength_mm: float) -> Texture:
        a = self.texture.authoring
        low, high = float(self.texture.values.min()), float(self.texture.values.max())
        return procedural.grating(wavelength_mm, self.layout.zone_mm, a.get("angle_deg", 0.0), a.get("shape", "sine"),
                                  (low, high), px_per_mm=max(PX_PER_MM, 8 / wavelength_mm))

    def reference_texture(self) -> Texture:
        if self.reference is not None:
            return self.reference
        if self.parameter == "wavelength":
            return self._grating(self.base_wavelength_mm)
        return plain(self.layout)

    def describe(self, level: float, target: int) -> str:
        """The stimulus in words for the log."""
        what = {"contrast": f"{self.texture.name or 'texture'} at contrast {level:.4g}",
                "wavelength": f"grating of {self.base_wavelength_mm + level:.4g} mm",
                "amplitude": f"uniform {level:.4g} µm p-p"}[self.parameter]
        other = self.reference.name if self.reference is not None else (
            f"grating of {self.base_wavelength_mm:.4g} mm" if self.parameter == "wavelength" else "plain glass")
        if self.layout.zones == 1:
            return what
        return f"zone {target + 1}: {what}; others: {other}"

    def trial_texture(self, level: float, target: int) -> Texture:
        """One texture for the trial: every zone in place, plain glass between (the renderer's one
        ``set_texture`` per trial)."""
        layout = self.layout
        reference = self.reference_texture()
        stimulus = self.zone_texture(level)
        placements = [Placement(stimulus if index == target else reference, layout.zone_left_mm(index), layout.gap_mm)
                      for index in range(layout.zones)]
        return compose(layout.size_mm, placements, 1.0, px_per_mm=_density(stimulus, reference),
                       name=f"trial-{self.parameter}-{level:.4g}")


def _density(*textures: Texture) -> float:
    """Pixels per mm for the trial's canvas: the finest source's, at least ``PX_PER_MM``, at most 40."""
    pixels = [min(t.pixel_mm) for t in textures if t.rows > 2 and t.cols > 2]  # 2×2: a uniform field
    return float(min(40.0, max(PX_PER_MM, 1.0 / min(pixels)))) if pixels else PX_PER_MM


@dataclass(frozen=True)
class Rendered:
    """What a swipe across a trial's texture produced. Per zone: median plate amplitude (µm p-p)
    and the friction contrast the plate really made (the 1st to 99th percentile of the realised
    ratio, edges left out)."""

    frames: int
    peak: float  # largest |sample| of the carrier, 1 = full-scale drive
    zone_um_pp: tuple[float, ...]
    zone_contrast: tuple[float, ...]
    zone_mean_ratio: tuple[float, ...] = ()  # the mean friction ratio the plate made in each zone


def offline_sampler(texture: Texture, speed_mm_s: float = 100.0, settings: RenderSettings | None = None) -> Sampler:
    """The lookup :func:`render_offline` reads ``texture`` through at ``speed_mm_s`` (a caller rendering the
    same trial texture again passes it back in). A finger that moves at most a pixel per control sample
    reads the full-resolution level alone (:mod:`ultraglide.textures.sampling`): at twice the swipe's speed
    or less, the band-limiting pyramid's other levels would never be read, and are not built (they were
    most of a trial's set-up)."""
    settings = settings or RenderSettings()
    step_mm = 2.0 * speed_mm_s / settings.control_rate_hz
    return Sampler(texture, band_limited=settings.band_limited_lookup and step_mm > max(texture.pixel_mm))


def render_offline(texture: Texture, layout: Layout, model: FrictionModel, profile: PlateProfile,
                   speed_mm_s: float = 100.0, force_n: float = 0.5, rate_hz: int = 96000,
                   block_frames: int = 4800, sampler: Sampler | None = None) -> Rendered:
    """Render one left-to-right swipe along the zones' middle row, as fast as the machine goes, into
    a buffer (what the null device would receive), and measure each zone from the plate model.
    ``sampler``: :func:`offline_sampler` of ``texture``, if the caller keeps one."""
    width, height = layout.size_mm
    duration = (width - 2.0) / speed_mm_s
    path = SwipePath("straight", speed_mm_s, duration, (1.0, height / 2), force_n=force_n)
    settings = RenderSettings(audio_rate_hz=rate_hz, default_force_n=force_n)
    if sampler is None:
        sampler = offline_sampler(texture, speed_mm_s, settings)
    along = render_along(texture, path, model, profile, settings, sampler, block_frames)
    x, amplitude, done = along.x_mm, along.plate_um_pp, along.frames
    ratio = model.relative_friction(amplitude, force_n)
    um_pp, contrast, mean = [], [], []
    for index in range(layout.zones):
        left = layout.zone_left_mm(index)
        inside = (x >= left + EDGE_MM) & (x < left + layout.zone_mm[0] - EDGE_MM)
        if not inside.any():
            um_pp.append(0.0)
            contrast.append(0.0)
            mean.append(1.0)
            continue
        low, high = np.percentile(ratio[inside], [1, 99])
        um_pp.append(float(np.median(amplitude[inside])))
        contrast.append(float(high - low))
        mean.append(float(np.mean(ratio[inside])))
    return Rendered(done, along.peak, tuple(um_pp), tuple(contrast), tuple(mean))


@dataclass(frozen=True)
class Along:
    """What the renderer and the plate model made along a finger's path, per control sample: where the finger
    was (mm on the texture) and the plate's amplitude (µm p-p); ``frames`` carrier samples with ``peak`` the
    largest |sample| (1 = full-scale drive)."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    plate_um_pp: np.ndarray
    frames: int
    peak: float


def render_along(texture: Texture, trajectory, model: FrictionModel, profile: PlateProfile,
                 settings: RenderSettings, sampler: Sampler | None = None, block_frames: int = 4800) -> Along:
    """Render ``texture`` along ``trajectory`` (a swipe or a recorded path, positions in mm on the texture) through
    the real renderer and its output stage (drive limiter, carrier) into a buffer, as fast as the machine goes."""
    renderer = Renderer(texture, model, profile, settings, trajectory=trajectory, sampler=sampler)
    stage = offline_stage(renderer)  # the drive limiter and the carrier, as every device has them
    xs, ys, plate = [], [], []
    renderer.observers.append(lambda block: (xs.append(block.x_mm), ys.append(block.y_mm),
                                             plate.append(block.plate_um_pp)))
    total = int(np.ceil((trajectory.end_s - trajectory.start_s + renderer.tail_s) * settings.audio_rate_hz))
    peak = 0.0
    buffer = np.empty(block_frames, dtype=np.float32)
    done = 0
    while done < total:
        n = min(block_frames, total - done)
        buffer[:n] = stage.pull(n, None)
        peak = max(peak, float(np.max(np.abs(buffer[:n]))))
        done += n
    return Along(np.concatenate(xs), np.concatenate(ys), np.concatenate(plate), done, peak)
