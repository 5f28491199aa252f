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
    """Zones side by side, ``gap_mm`` of plain glass around each. Sizes in mm.

    Parameters
    ----------
    zones : int
        The zones side by side.
    zone_mm : (float, float)
        A zone's width and height, mm.
    gap_mm : float
        Plain glass around each zone, mm.

    Examples
    --------
    >>> layout = Layout(2, (20.0, 10.0), 5.0)
    >>> layout.size_mm                  # 2 × 20 + 3 × 5 wide, 10 + 2 × 5 high
    (55.0, 20.0)
    """

    zones: int = 2
    zone_mm: tuple[float, float] = (40.0, 40.0)
    gap_mm: float = 10.0

    @property
    def size_mm(self) -> tuple[float, float]:
        """The whole trial's width and height, mm: the zones and the gaps around them.

        Examples
        --------
        >>> Layout(3, (40.0, 40.0), 10.0).size_mm          # 3 × 40 + 4 × 10, 40 + 2 × 10
        (160.0, 60.0)
        """
        width, height = self.zone_mm
        return self.zones * width + (self.zones + 1) * self.gap_mm, height + 2 * self.gap_mm

    def zone_left_mm(self, index: int) -> float:
        """The left edge of zone ``index`` (0-based), mm from the trial's left edge.

        Parameters
        ----------
        index : int

        Returns
        -------
        float

        Examples
        --------
        >>> Layout(2, (20.0, 10.0), 5.0).zone_left_mm(1)    # a gap, a zone, a gap
        30.0
        """
        return self.gap_mm + index * (self.zone_mm[0] + self.gap_mm)

    def zone_at(self, x_mm: float, y_mm: float) -> int | None:
        """The zone under a point, or None.

        Parameters
        ----------
        x_mm, y_mm : float
            The point, mm from the trial's top-left corner.

        Returns
        -------
        int or None
            The zone's index (0-based); None on the glass between.

        Examples
        --------
        >>> layout = Layout(2, (20.0, 10.0), 5.0)
        >>> layout.zone_at(30.0, 10.0), layout.zone_at(27.0, 10.0), layout.zone_at(10.0, 2.0)
        (1, None, None)
        """
        for index in range(self.zones):
            left = self.zone_left_mm(index)
            if left <= x_mm < left + self.zone_mm[0] and self.gap_mm <= y_mm < self.gap_mm + self.zone_mm[1]:
                return index
        return None


def with_contrast(texture: Texture, contrast: float) -> Texture:
    """``texture`` rescaled so its friction spans [1 − contrast, 1] (its own pattern kept).

    Parameters
    ----------
    texture : Texture
    contrast : float
        The friction contrast wanted, 0..1.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        A contrast outside 0..1.

    Examples
    --------
    >>> from ultraglide.textures.library import resolve_texture
    >>> rescaled = with_contrast(resolve_texture("grating-1mm"), 0.3)
    >>> round(float(rescaled.values.min()), 6), round(float(rescaled.values.max()), 6)
    (0.7, 1.0)
    """
    if not 0 <= contrast <= 1:
        raise TextureError(f"a friction contrast lies in 0..1, got {contrast:g}")
    if texture.kind == "gradient":
        return texture.with_(ratio_range=(1.0 - contrast, 1.0))
    values = texture.values.astype(np.float64)
    span = float(values.max() - values.min())
    normalised = (values - values.min()) / span if span > 0 else np.ones_like(values)
    return texture.with_(values=(1.0 - contrast * (1.0 - normalised)).astype(np.float32))


def plain(layout: Layout, ratio: float = 1.0) -> Texture:
    """Plain glass the size of a zone, at friction ratio ``ratio`` (1: the plate at rest).

    Parameters
    ----------
    layout : Layout
    ratio : float
        The friction ratio everywhere, 0..1.

    Returns
    -------
    Texture
        A uniform 2 × 2 map of ``layout.zone_mm``.

    Examples
    --------
    >>> glass = plain(Layout(2, (20.0, 10.0), 5.0), 0.8)
    >>> glass.width_mm, glass.height_mm, glass.values.tolist()
    (20.0, 10.0, [[0.800000011920929, 0.800000011920929], [0.800000011920929, 0.800000011920929]])
    """
    return Texture(np.full((2, 2), ratio, dtype=np.float32), *layout.zone_mm, name="plain glass")


@dataclass(frozen=True)
class StimulusDesign:
    """What varies and what the zones show. ``reference``: what the non-target zones show (None: plain
    glass, or for ``wavelength`` the grating at its own wavelength).

    Parameters
    ----------
    texture : Texture
        The stimulus's texture (a grating for ``wavelength``).
    parameter : {"contrast", "wavelength", "amplitude"}
        What the level is: friction contrast, the added wavelength in mm, or a vibration in µm p-p.
    layout : Layout
    reference : Texture, optional
    model : FrictionModel, optional
        For ``amplitude``: the ratio a vibration amplitude gives.
    force_n : float
        The finger's force, N (for ``amplitude``).

    Raises
    ------
    TextureError
        An unknown parameter, ``wavelength`` of a texture that is not a grating, ``amplitude`` without a model.

    Examples
    --------
    >>> from ultraglide.textures.library import resolve_texture
    >>> design = StimulusDesign(resolve_texture("grating-1mm"), "wavelength", Layout(2, (20.0, 10.0), 5.0))
    >>> design.describe(0.25, target=0)                   # 1 mm + 0.25 mm in zone 1
    'zone 1: grating of 1.25 mm; others: grating of 1 mm'
    """

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
        """The level's unit, in words.

        Examples
        --------
        >>> from ultraglide.textures.library import resolve_texture
        >>> StimulusDesign(resolve_texture("grating-1mm"), "wavelength").unit
        'mm'
        """
        return PARAMETERS[self.parameter]

    @property
    def base_wavelength_mm(self) -> float:
        """The grating's own wavelength, mm (0 for a texture that is not a grating).

        Examples
        --------
        >>> from ultraglide.textures.library import resolve_texture
        >>> StimulusDesign(resolve_texture("grating-2mm")).base_wavelength_mm
        2.0
        """
        return float(self.texture.authoring.get("wavelength_mm", 0.0))

    def zone_texture(self, level: float) -> Texture:
        """The target zone's texture at ``level``.

        Parameters
        ----------
        level : float
            In the parameter's unit.

        Returns
        -------
        Texture

        Examples
        --------
        >>> from ultraglide.textures.library import resolve_texture
        >>> zone = StimulusDesign(resolve_texture("grating-1mm")).zone_texture(0.2)      # contrast 0.2
        >>> round(float(zone.values.min()), 6), round(float(zone.values.max()), 6)
        (0.8, 1.0)
        """
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
        """What the other zones show: the reference given, else the grating at its own wavelength (``wavelength``) or
        plain glass.

        Returns
        -------
        Texture

        Examples
        --------
        >>> from ultraglide.textures.library import resolve_texture
        >>> StimulusDesign(resolve_texture("grating-1mm")).reference_texture().values.tolist()     # at rest
        [[1.0, 1.0], [1.0, 1.0]]
        """
        if self.reference is not None:
            return self.reference
        if self.parameter == "wavelength":
            return self._grating(self.base_wavelength_mm)
        return plain(self.layout)

    def describe(self, level: float, target: int) -> str:
        """The stimulus in words for the log.

        Parameters
        ----------
        level : float
            In the parameter's unit.
        target : int
            The zone holding the stimulus, 0-based.

        Returns
        -------
        str

        Examples
        --------
        >>> from ultraglide.textures.library import resolve_texture
        >>> StimulusDesign(resolve_texture("grating-1mm")).describe(0.05, target=1)
        'zone 2: grating-1mm at contrast 0.05; others: plain glass'
        """
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
        ``set_texture`` per trial).

        Parameters
        ----------
        level : float
            In the parameter's unit.
        target : int
            The zone holding the stimulus, 0-based.

        Returns
        -------
        Texture
            ``layout.size_mm`` in size.

        Examples
        --------
        >>> from ultraglide.textures.library import resolve_texture
        >>> from ultraglide.textures.sampling import Sampler
        >>> layout = Layout(2, (20.0, 10.0), 5.0)
        >>> trial = StimulusDesign(resolve_texture("grating-1mm"), layout=layout).trial_texture(0.3, target=1)
        >>> trial.width_mm, trial.height_mm
        (55.0, 20.0)
        >>> lookup = Sampler(trial, band_limited=False)
        >>> float(lookup.ratio(15.0, 10.0)), float(lookup.ratio(2.0, 10.0))    # the plain zone 1 and the gap: at rest
        (1.0, 1.0)
        """
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
    ratio, edges left out).

    Parameters
    ----------
    frames : int
        Carrier samples rendered.
    peak : float
        The largest |sample| of the carrier, 1 = full-scale drive.
    zone_um_pp : tuple of float
        Per zone, µm p-p.
    zone_contrast : tuple of float
        Per zone, friction contrast.
    zone_mean_ratio : tuple of float
        Per zone, the mean friction ratio.

    Examples
    --------
    See :func:`render_offline`.

    >>> Rendered(96000, 0.5, (0.0, 1.2), (0.0, 0.2)).zone_mean_ratio
    ()
    """

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
    most of a trial's set-up).

    Parameters
    ----------
    texture : Texture
    speed_mm_s : float
        The swipe's speed, mm/s.
    settings : RenderSettings, optional
        For the control rate (default: the renderer's defaults).

    Returns
    -------
    Sampler

    Examples
    --------
    A 0.1 mm pixel at 12 kHz control: 2 × 100 mm/s / 12000 Hz = 0.017 mm a sample (one level); 2 × 1000 / 12000 =
    0.17 mm (the pyramid):

    >>> from ultraglide.textures.library import resolve_texture
    >>> grating = resolve_texture("grating-1mm")
    >>> offline_sampler(grating, 100.0).levels, offline_sampler(grating, 1000.0).levels > 1
    (1, True)
    """
    settings = settings or RenderSettings()
    step_mm = 2.0 * speed_mm_s / settings.control_rate_hz
    return Sampler(texture, band_limited=settings.band_limited_lookup and step_mm > max(texture.pixel_mm))


def render_offline(texture: Texture, layout: Layout, model: FrictionModel, profile: PlateProfile,
                   speed_mm_s: float = 100.0, force_n: float = 0.5, rate_hz: int = 96000,
                   block_frames: int = 4800, sampler: Sampler | None = None) -> Rendered:
    """Render one left-to-right swipe along the zones' middle row, as fast as the machine goes, into
    a buffer (what the null device would receive), and measure each zone from the plate model.

    Parameters
    ----------
    texture : Texture
        The trial's texture (:meth:`StimulusDesign.trial_texture`).
    layout : Layout
    model : FrictionModel
    profile : PlateProfile
    speed_mm_s : float
        The swipe's speed, mm/s.
    force_n : float
        The finger's force, N.
    rate_hz : int
        The carrier's sample rate, Hz.
    block_frames : int
        Samples rendered per block.
    sampler : Sampler, optional
        :func:`offline_sampler` of ``texture``, if the caller keeps one.

    Returns
    -------
    Rendered

    Examples
    --------
    Plain glass asks for no vibration; a grating of contrast 0.2 is delivered within the stimulus check's bound
    (at least half of it):

    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.physics.calibration import load_model
    >>> from ultraglide.textures.library import resolve_texture
    >>> layout = Layout(2, (20.0, 10.0), 5.0)
    >>> trial = StimulusDesign(resolve_texture("grating-1mm"), layout=layout).trial_texture(0.2, target=1)
    >>> rendered = render_offline(trial, layout, load_model("stretched"), load_profile("sim-plate"))
    >>> rendered.zone_um_pp[0], rendered.zone_contrast[0], 0.1 < rendered.zone_contrast[1] <= 0.2
    (0.0, 0.0, True)
    """
    width, height = layout.size_mm
    duration = (width - 2.0) / speed_mm_s
    path = SwipePath("straight", speed_mm_s, duration, (1.0, height / 2), force_n=force_n)
    settings = RenderSettings(audio_rate_hz=rate_hz, default_force_n=force_n)
    if sampler is None:
        sampler = offline_sampler(texture, speed_mm_s, settings)
    along = render_along(texture, path, model, profile, settings, sampler, block_frames)
    x, amplitude, done = along.x_mm, along.plate_um_pp, along.frames
    ratio = delivered_ratio(model, amplitude, settings.control_rate_hz, force_n, speed_mm_s)
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


def delivered_ratio(model: FrictionModel, plate_um_pp: np.ndarray, rate_hz: float, force_n,
                    speed_mm_s) -> np.ndarray:
    """The friction ratio a finger gets from the plate's amplitude: the model's settled ratio, or, for a model with
    friction dynamics, the ratio felt (which lags the amplitude: falls in milliseconds, recovers in tens). A speed
    law's weakening of the settled ratio (``speed:S:NAME``) is not applied here: the ratio is the law's at its
    reference speed.

    Parameters
    ----------
    model : FrictionModel
    plate_um_pp : numpy.ndarray
        The plate's amplitude, µm p-p, one a control sample from the finger's first touch.
    rate_hz : float
        The control rate, Hz.
    force_n : float or numpy.ndarray
        The finger's force, N.
    speed_mm_s : float or numpy.ndarray
        The finger's sliding speed, mm/s (the recovery slows at lower speeds).

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    A 20 ms burst at 6 µm p-p: the static law's ratio drops at once to 0.168, the felt ratio falls over the 5 ms
    onset, to 0.168 + (1 − 0.168) e^(−4) = 0.183 after four time constants:

    >>> import numpy as np
    >>> from ultraglide.render.physics.calibration import load_model
    >>> burst = np.r_[np.zeros(12), np.full(240, 6.0)]                  # 1 ms at rest, then the burst, at 12 kHz
    >>> static = delivered_ratio(load_model("stretched"), burst, 12000.0, 0.5, 100.0)
    >>> felt = delivered_ratio(load_model("dynamic"), burst, 12000.0, 0.5, 100.0)
    >>> round(float(static[12]), 3), round(float(felt[12]), 3), round(float(felt[-1]), 3)
    (0.168, 0.986, 0.183)
    """
    if getattr(model, "dynamics", None) is None:
        return model.relative_friction(plate_um_pp, force_n)
    return model.felt(plate_um_pp, rate_hz, force_n, speed_mm_s)


@dataclass(frozen=True)
class Along:
    """What the renderer and the plate model made along a finger's path, per control sample: where the finger
    was (mm on the texture) and the plate's amplitude (µm p-p); ``frames`` carrier samples with ``peak`` the
    largest |sample| (1 = full-scale drive).

    Parameters
    ----------
    x_mm, y_mm : numpy.ndarray
        The finger's position per control sample, mm.
    plate_um_pp : numpy.ndarray
        The plate's amplitude per control sample, µm p-p.
    frames : int
    peak : float

    Examples
    --------
    See :func:`render_along`.

    >>> import numpy as np
    >>> Along(np.zeros(3), np.zeros(3), np.zeros(3), 24, 0.0).frames
    24
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    plate_um_pp: np.ndarray
    frames: int
    peak: float


def render_along(texture: Texture, trajectory, model: FrictionModel, profile: PlateProfile,
                 settings: RenderSettings, sampler: Sampler | None = None, block_frames: int = 4800) -> Along:
    """Render ``texture`` along ``trajectory`` (a swipe or a recorded path, positions in mm on the texture) through
    the real renderer and its output stage (drive limiter, carrier) into a buffer, as fast as the machine goes.

    Parameters
    ----------
    texture : Texture
    trajectory : SwipePath or RecordedTrajectory
    model : FrictionModel
    profile : PlateProfile
    settings : RenderSettings
    sampler : Sampler, optional
    block_frames : int
        Samples rendered per block.

    Returns
    -------
    Along

    Examples
    --------
    A 0.1 s swipe at 100 mm/s from x = 1 mm: 100 / 12000 mm per control sample, ending 10 mm on:

    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.paths import SwipePath
    >>> from ultraglide.render.physics.calibration import load_model
    >>> from ultraglide.render.renderer import RenderSettings
    >>> from ultraglide.textures.library import resolve_texture
    >>> along = render_along(resolve_texture("grating-1mm"), SwipePath("straight", 100.0, 0.1, (1.0, 5.0)),
    ...                      load_model("stretched"), load_profile("sim-plate"), RenderSettings())
    >>> round(float(along.x_mm[1] - along.x_mm[0]), 6), round(100 / 12000, 6), float(along.x_mm[-1])
    (0.008333, 0.008333, 11.0)
    >>> 0 < along.peak <= 1.0
    True
    """
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
