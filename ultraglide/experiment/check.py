"""Stimuli built from a design, and checked before anyone feels them.

:func:`zone_texture` makes a stimulus's zone: its texture sampled over the zone (scaled, turned), rescaled to its
friction contrast and shifted to its mean. :func:`check_stimuli` renders every stimulus along the path
participants use (the zone's swipe: left to right along its middle, at the design's speed and force) through the
real renderer, its output stage and the plate model, and compares what the plate delivers with what the design
asked:

* the friction **contrast** delivered (1st to 99th percentile of the realised ratio, edges left out) against the
  contrast asked (the stimulus's ``contrast``, else its map's own): less than :data:`MIN_CONTRAST_KEPT` of it is
  refused. The path's own contrast (the map's values under the swipe, before rendering) says whether the swipe
  crosses the texture's features at all; the ratio of delivered to path contrast is the renderer's and the
  drive limit's effect;
* the **mean friction** delivered against the path's mean asked: further than :data:`MAX_MEAN_ERROR` is refused;
* **pairs** (A and B of a forced choice or same-different condition) meant to differ in some properties only: if
  their contrasts are declared equal, the delivered contrasts must agree within :data:`MAX_PAIR_CONTRAST_RATIO`;
  if their means are (both unset counts as equal), the delivered means within :data:`MAX_PAIR_MEAN_DIFFERENCE`.

Varied stimuli (staircases, QUEST+, constant stimuli of contrast) are checked at the highest level they may take.

Under a model with the finger's friction dynamics (``model = "dynamic"``; experiments render with the static
``stretched`` law unless told), the ratio judged is the one *felt*: the plate's amplitude through the dynamics at
the swipe's speed (:func:`ultraglide.experiment.stimuli.delivered_ratio`), not the ratio the planner commands.
A 1 mm grating swept at 100 mm/s keeps a tenth of its contrast felt and is refused; a 20 mm one keeps most of it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass

import numpy as np

from ultraglide.experiment.design import ADAPTIVE, Design, Stimulus
from ultraglide.experiment.errors import ExperimentError, StimulusCheckError

MIN_CONTRAST_KEPT = 0.5  # delivered / asked friction contrast below this: refused
MIN_ASKED_CONTRAST = 0.01  # below this a stimulus asks for no contrast to check
MAX_MEAN_ERROR = 0.05  # |delivered - asked| mean friction ratio
MAX_PAIR_CONTRAST_RATIO = 1.25  # larger / smaller delivered contrast of a pair declared equal in contrast
MAX_PAIR_MEAN_DIFFERENCE = 0.03  # delivered mean ratios of a pair declared equal in mean
EDGE_MM = 3.0
MAX_PX_PER_MM = 40.0


def load_source(stimulus: Stimulus):
    """The stimulus's texture (a library name or a file; an image is authored with the defaults); ExperimentError
    naming the stimulus if it cannot be loaded.

    Parameters
    ----------
    stimulus : Stimulus

    Returns
    -------
    Texture

    Raises
    ------
    ExperimentError
        One line naming ``stimuli.NAME.texture`` and what is wrong.

    Examples
    --------
    >>> load_source(Stimulus("g", "grating-2mm")).authoring["wavelength_mm"]
    2.0
    >>> load_source(Stimulus("x", "no-such-texture"))
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: stimuli.x.texture: ...
    """
    from ultraglide.errors import UltraglideError
    from ultraglide.textures.library import resolve_texture

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an image authored on the fly: the design asked for it
        try:
            return resolve_texture(stimulus.texture)
        except (UltraglideError, OSError) as error:
            from ultraglide.errors import describe

            raise ExperimentError(f"stimuli.{stimulus.name}.texture: {describe(error)}") from None


def zone_texture(stimulus: Stimulus, zone_mm: tuple[float, float], contrast: float | None = None, source=None):
    """The zone's texture for ``stimulus`` (its ``contrast`` replaced by ``contrast`` when given).

    Parameters
    ----------
    stimulus : Stimulus
    zone_mm : (float, float)
        The zone's width and height, mm.
    contrast : float, optional
        A friction contrast (0..1) instead of the stimulus's own (a varied stimulus at a level).
    source : Texture, optional
        The stimulus's texture, already loaded.

    Returns
    -------
    Texture
        ``zone_mm`` in size, named after the stimulus.

    Raises
    ------
    ExperimentError
        A gradient texture, or a mean the contrast cannot fit within 0..1.

    Examples
    --------
    A contrast of 0.4 shifted to a mean of 0.7: a sine spans 0.5..0.9 about its mean:

    >>> zone = zone_texture(Stimulus("g", "grating-1mm", contrast=0.4, mean=0.7), (20.0, 10.0))
    >>> zone.width_mm, zone.height_mm, round(float(zone.values.mean()), 3)
    (20.0, 10.0, 0.7)
    >>> round(float(zone.values.min()), 2), round(float(zone.values.max()), 2)
    (0.5, 0.9)
    """
    return ZoneSource(stimulus, zone_mm, source).texture(contrast)


class ZoneSource:
    """A stimulus's texture loaded and sampled over its zone (scaled, turned), and its effects read, once: its zone at
    any contrast (:meth:`texture`, what :func:`zone_texture` gives, bit for bit) costs the arithmetic alone.

    Parameters
    ----------
    stimulus : Stimulus
    zone_mm : (float, float)
        The zone's width and height, mm.
    source : Texture, optional
        The stimulus's texture, already loaded.

    Raises
    ------
    ExperimentError
        The texture cannot be loaded, is a gradient texture, or its effects cannot be read.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.experiment import Stimulus, zone_texture
    >>> grating = Stimulus("g", "grating-1mm", mean=0.6)
    >>> zone = ZoneSource(grating, (20.0, 20.0))
    >>> values = zone.texture(0.4).values              # a sine grating: 0.6 ± 0.2
    >>> round(float(values.mean()), 3), round(float(values.max() - values.min()), 3)
    (0.6, 0.4)
    >>> bool(np.array_equal(values, zone_texture(grating, (20.0, 20.0), 0.4).values))
    True
    """

    def __init__(self, stimulus: Stimulus, zone_mm: tuple[float, float], source=None):
        from ultraglide.textures.sampling import Sampler

        if source is None:
            source = load_source(stimulus)
        if source.kind == "gradient":
            raise ExperimentError(f"stimulus {stimulus.name!r}: {stimulus.texture} is a gradient texture; a design's "
                                  "stimuli are friction maps")
        width, height = zone_mm
        px_per_mm = float(min(MAX_PX_PER_MM, max(10.0, stimulus.scale / min(source.pixel_mm))))
        cols, rows = max(2, round(width * px_per_mm)), max(2, round(height * px_per_mm))
        x, y = np.meshgrid((np.arange(cols) + 0.5) * width / cols, (np.arange(rows) + 0.5) * height / rows)
        angle = math.radians(stimulus.rotation_deg)
        cx, cy = width / 2, height / 2
        u = cx + ((x - cx) * math.cos(angle) + (y - cy) * math.sin(angle)) / stimulus.scale
        v = cy + (-(x - cx) * math.sin(angle) + (y - cy) * math.cos(angle)) / stimulus.scale
        direction = (np.full_like(u, math.cos(angle)), np.full_like(u, -math.sin(angle)))
        self.sampled = Sampler(source, band_limited=False).ratio(u, v, direction=direction).astype(np.float64)
        self.sampled.flags.writeable = False
        self.stimulus, self.zone_mm = stimulus, (float(width), float(height))
        self.effects = _effects(stimulus)

    def ratios(self, contrast: float | None = None) -> np.ndarray:
        """The zone's friction ratios at ``contrast`` (0..1; None: the stimulus's own) shifted to its mean, before
        the check that they lie in 0..1 and the clip of its rounding: rows × columns, float64.

        Parameters
        ----------
        contrast : float, optional
            A friction contrast, 0..1.

        Returns
        -------
        numpy.ndarray

        Examples
        --------
        A sine grating at contrast 0.4 about a mean of 0.6: 0.4..0.8, not yet checked against 0..1:

        >>> from ultraglide.experiment import Stimulus
        >>> ratios = ZoneSource(Stimulus("g", "grating-1mm", mean=0.6), (20.0, 20.0)).ratios(0.4)
        >>> round(float(ratios.min()), 3), round(float(ratios.mean()), 3), round(float(ratios.max()), 3)
        (0.4, 0.6, 0.8)
        """
        values = self.sampled
        wanted = self.stimulus.contrast if contrast is None else contrast
        if wanted is not None:
            span = float(values.max() - values.min())
            normalised = (values - values.min()) / span if span > 0 else np.ones_like(values)
            values = 1.0 - wanted * (1.0 - normalised)
        if self.stimulus.mean is not None:
            values = values - values.mean() + self.stimulus.mean
        return values

    def fit(self, contrast: float | None = None) -> tuple[float, float, float, float, float]:
        """Where the zone's ratios lie at ``contrast`` (None: the stimulus's own) and what would bring them within
        0..1.

        Returns
        -------
        (float, float, float, float, float)
            The lowest and highest friction ratio, the largest contrast that fits at the stimulus's mean (1 without
            one), the lowest and the highest mean that fit at this contrast.

        Examples
        --------
        >>> from ultraglide.experiment import Stimulus
        >>> low, high, largest, least, most = ZoneSource(Stimulus("g", "grating-1mm", mean=0.8), (20.0, 20.0)).fit(0.6)
        >>> [round(v, 2) for v in (low, high, largest, least, most)]     # 0.8 ± 0.3; 2 (1 - 0.8); 0.3..0.7
        [0.5, 1.1, 0.4, 0.3, 0.7]
        """
        values = self.ratios(contrast)
        wanted = self.stimulus.contrast if contrast is None else contrast
        spread = float(values.max() - values.min())  # the zone's friction contrast at this level
        below = float(values.mean() - values.min())  # its lowest ratio's distance below its mean
        above = spread - below
        largest = 1.0
        if self.stimulus.mean is not None and spread > 0:
            now = wanted if wanted is not None else spread
            mean = self.stimulus.mean
            largest = min(1.0, now * min(mean / below if below > 0 else math.inf,
                                         (1.0 - mean) / above if above > 0 else math.inf))
        return float(values.min()), float(values.max()), largest, below, 1.0 - above

    def texture(self, contrast: float | None = None):
        """The zone at ``contrast`` (a friction contrast, 0..1; None: the stimulus's own).

        Returns
        -------
        Texture
            The zone's size, named after the stimulus, with its effects.

        Raises
        ------
        ExperimentError
            The stimulus's mean puts its ratios outside 0..1 at this contrast.

        Examples
        --------
        >>> from ultraglide.experiment import Stimulus
        >>> zone = ZoneSource(Stimulus("g", "grating-1mm", mean=0.8), (20.0, 10.0))
        >>> texture = zone.texture(0.2)
        >>> texture.width_mm, texture.height_mm, round(float(texture.values.max()), 3)      # 0.8 ± 0.1
        (20.0, 10.0, 0.9)
        >>> zone.texture(0.6)                                        # 0.8 ± 0.3 reaches 1.1
        Traceback (most recent call last):
        ...
        ultraglide.experiment.errors.ExperimentError: stimulus 'g': a mean friction ratio of 0.8 puts its ratios at ...
        """
        from ultraglide.textures.texture import Texture

        stimulus = self.stimulus
        values = self.ratios(contrast)
        if stimulus.mean is not None:
            if values.min() < -1e-9 or values.max() > 1 + 1e-9:
                raise ExperimentError(f"stimulus {stimulus.name!r}: a mean friction ratio of {stimulus.mean:g} puts "
                                      f"its ratios at {values.min():.3f}..{values.max():.3f}, outside 0..1; lower its "
                                      "contrast or move its mean")
            values = np.clip(values, 0.0, 1.0)
        wanted = stimulus.contrast if contrast is None else contrast
        width, height = self.zone_mm
        return Texture(values.astype(np.float32), width, height, outside="fixed", outside_ratio=1.0,
                       name=stimulus.name, source=str(stimulus.texture),
                       authoring={"stimulus": asdict(stimulus), "contrast": wanted}, effects=self.effects)


def _effects(stimulus: Stimulus) -> tuple:
    """The stimulus's temporal effects (none without a file); ExperimentError naming it when they cannot be read."""
    if stimulus.effects is None:
        return ()
    from ultraglide.errors import UltraglideError, describe
    from ultraglide.textures.effects_file import load_effects

    try:
        return load_effects(stimulus.effects)
    except (UltraglideError, OSError) as error:
        raise ExperimentError(f"stimuli.{stimulus.name}.effects: {describe(error)}") from None


@dataclass(frozen=True)
class StimulusFigures:
    """What one stimulus delivers along the path. Contrasts and means are friction ratios' (1 = at rest).

    Parameters
    ----------
    stimulus : str
    level : float or None
        The level checked (a varied stimulus), else None.
    asked_contrast, path_contrast, delivered_contrast : float
        The friction contrast asked, the map's own along the path (before rendering), and the plate's.
    asked_mean, delivered_mean : float
        The map's mean friction ratio along the path, and the plate's.
    delivered_um_pp : float
        The plate's median amplitude on the zone, µm p-p.
    peak_drive : float
        The largest |carrier sample|, 1 = full scale.

    Examples
    --------
    See :func:`measure`.

    >>> StimulusFigures("g", 0.2, 0.2, 0.2, 0.19, 0.9, 0.9, 1.1, 0.4).label
    'g at level 0.2'
    """

    stimulus: str
    level: float | None  # the level checked (a varied stimulus), else None
    asked_contrast: float
    path_contrast: float  # the map's own contrast along the swipe (before rendering)
    delivered_contrast: float
    asked_mean: float  # the map's mean along the swipe
    delivered_mean: float
    delivered_um_pp: float
    peak_drive: float  # largest |carrier sample|, 1 = full scale

    @property
    def label(self) -> str:
        """The stimulus's name, with its level where one was checked.

        Examples
        --------
        >>> StimulusFigures("g", None, 0.3, 0.3, 0.28, 0.85, 0.85, 1.5, 0.4).label
        'g'
        """
        return self.stimulus if self.level is None else f"{self.stimulus} at level {self.level:g}"

    def as_dict(self) -> dict:
        """The figures as plain data, with the label.

        Returns
        -------
        dict

        Examples
        --------
        >>> StimulusFigures("g", None, 0.3, 0.3, 0.28, 0.85, 0.85, 1.5, 0.4).as_dict()["delivered_um_pp"]
        1.5
        """
        return {**asdict(self), "label": self.label}


@dataclass
class CheckReport:
    """Every stimulus's figures, and what failed (one sentence each).

    Parameters
    ----------
    figures : dict of str to StimulusFigures
    failures : list of str
    felt : bool
        The figures are the friction felt through the model's friction dynamics (a dynamic model), not the
        plate's settled ratio.

    Examples
    --------
    >>> report = CheckReport({}, ["stimulus 'g' delivers too little"])
    >>> report.passed, report.as_dict()["failures"]
    (False, ["stimulus 'g' delivers too little"])
    """

    figures: dict[str, StimulusFigures]
    failures: list[str]
    felt: bool = False

    @property
    def passed(self) -> bool:
        """True when nothing failed.

        Examples
        --------
        >>> CheckReport({}, []).passed
        True
        """
        return not self.failures

    def as_dict(self) -> dict:
        """The report as plain data: ``passed``, ``failures``, each stimulus's figures, and the criteria.

        Returns
        -------
        dict

        Examples
        --------
        >>> CheckReport({}, []).as_dict()["criteria"]["min_contrast_kept"] == MIN_CONTRAST_KEPT
        True
        """
        return {"passed": self.passed, "failures": list(self.failures), "felt": self.felt,
                "stimuli": {key: value.as_dict() for key, value in self.figures.items()},
                "criteria": {"min_contrast_kept": MIN_CONTRAST_KEPT, "max_mean_error": MAX_MEAN_ERROR,
                             "max_pair_contrast_ratio": MAX_PAIR_CONTRAST_RATIO,
                             "max_pair_mean_difference": MAX_PAIR_MEAN_DIFFERENCE}}


class Rig:
    """The design's friction model, plate profile, swipe speed and finger force, loaded once.

    Parameters
    ----------
    design : Design

    Raises
    ------
    UltraglideError
        A model or a plate profile that cannot be loaded.

    Examples
    --------
    >>> from ultraglide.experiment import design_from_dict
    >>> rig = Rig(design_from_dict({"stimuli": {"g": {"texture": "grating-1mm"}},
    ...     "conditions": [{"name": "g", "stimulus": "g"}], "blocks": [{"task": "rating", "conditions": ["g"]}],
    ...     "rig": {"zone_mm": [20, 10], "speed_mm_s": 80}}))
    >>> rig.profile.name, rig.zone_mm, rig.speed_mm_s, rig.paths
    ('sim-plate', (20.0, 10.0), 80.0, {})
    """

    def __init__(self, design: Design):
        from ultraglide.devices.rig import load_plate
        from ultraglide.render.physics.calibration import load_model

        self.model = load_model(design.model)
        self.profile = load_plate(design.profile)
        self.speed_mm_s, self.force_n = design.speed_mm_s, design.force_n
        self.zone_mm, self.gap_mm = tuple(design.zone_mm), design.gap_mm
        self.paths = {path: _recorded_path(path, index, self.zone_mm) for index, path in enumerate(design.check_paths)}


MAX_PATH_S = 600.0  # a recorded path the check renders: at most 10 minutes


def _recorded_path(path: str, index: int, zone_mm: tuple[float, float]):
    """A touch log the check renders along, whole in memory: ``(t_s, x_mm, y_mm, force_n or None)``; ExperimentError
    naming ``rig.check_paths[index]`` when it cannot be read or leaves the zone entirely."""
    from ultraglide.errors import UltraglideError, describe
    from ultraglide.render.touch_log import read_touch_log

    where = f"rig.check_paths[{index}]"
    try:
        trajectory = read_touch_log(path)
    except (UltraglideError, OSError) as error:
        raise ExperimentError(f"{where}: {describe(error)}") from None
    if trajectory.end_s - trajectory.start_s > MAX_PATH_S:
        raise ExperimentError(f"{where}: {path} lasts {trajectory.end_s - trajectory.start_s:.0f} s; a path to check "
                              f"stimuli along lasts at most {MAX_PATH_S:.0f} s: cut it")
    t, x, y, force = trajectory.records()
    inside = (x >= EDGE_MM) & (x <= zone_mm[0] - EDGE_MM) & (y >= 0) & (y <= zone_mm[1])
    if not inside.any():
        raise ExperimentError(f"{where}: {path} never enters the zone ({zone_mm[0]:g} × {zone_mm[1]:g} mm, positions "
                              "in mm from its top-left corner): record it on the zone, or shift it there")
    return t, x, y, force


def measure(texture, rig: Rig, stimulus: str, level: float | None, asked_contrast: float) -> StimulusFigures:
    """Render ``texture`` (a zone) alone along the zone's swipe and measure what it delivers.

    Parameters
    ----------
    texture : Texture
        The zone (:func:`zone_texture`).
    rig : Rig
    stimulus : str
        Its name, for the figures.
    level : float or None
        The level it stands for (a varied stimulus), else None.
    asked_contrast : float
        The friction contrast the design asks.

    Returns
    -------
    StimulusFigures

    Examples
    --------
    A sine grating rescaled to 0.7..1: the path's mean (0.7 + 1) / 2 = 0.85 and contrast 0.3; the plate keeps more
    than the check's half of it:

    >>> from ultraglide.experiment import design_from_dict
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm", "contrast": 0.3}},
    ...     "conditions": [{"name": "g", "stimulus": "g"}], "blocks": [{"task": "rating", "conditions": ["g"]}],
    ...     "rig": {"zone_mm": [20, 10]}})
    >>> rig = Rig(design)
    >>> found = measure(zone_texture(design.stimuli["g"], rig.zone_mm), rig, "g", None, 0.3)
    >>> round(found.asked_mean, 2), round(found.path_contrast, 2), 0.15 < found.delivered_contrast <= 0.3
    (0.85, 0.3, True)
    """
    from ultraglide.experiment.stimuli import Layout, render_offline
    from ultraglide.textures.compose import Placement, compose

    layout = Layout(1, rig.zone_mm, rig.gap_mm)
    px = float(min(MAX_PX_PER_MM, max(10.0, 1.0 / min(texture.pixel_mm))))
    canvas = compose(layout.size_mm, [Placement(texture, layout.zone_left_mm(0), layout.gap_mm)], 1.0, px_per_mm=px,
                     name=f"check-{stimulus}")
    rendered = render_offline(canvas, layout, rig.model, rig.profile, rig.speed_mm_s, rig.force_n)
    from ultraglide.textures.sampling import Sampler

    # the map under the swipe's very line (the zone's middle, as the renderer looks it up: between two rows of a
    # checkerboard whose squares meet there, the mean of both)
    x = np.arange(EDGE_MM, texture.width_mm - EDGE_MM, 0.05) if texture.width_mm > 2 * EDGE_MM + 1 else np.arange(
        0.0, texture.width_mm, 0.05)
    y = np.full_like(x, texture.height_mm / 2)
    row = Sampler(texture, band_limited=False).ratio(x, y, direction=(np.ones_like(x), np.zeros_like(x)))
    row = row.astype(np.float64)
    low, high = np.percentile(row, [1, 99])
    return StimulusFigures(stimulus, level, float(asked_contrast), float(high - low), rendered.zone_contrast[0],
                           float(row.mean()), rendered.zone_mean_ratio[0], rendered.zone_um_pp[0], rendered.peak)


def measure_path(texture, rig: Rig, stimulus: str, level: float | None, asked_contrast: float,
                 path: str) -> StimulusFigures:
    """Render ``texture`` (a zone) alone along the recorded path ``path`` of the rig and measure what it delivers
    where the finger was on the zone (its edges left out).

    Parameters
    ----------
    texture : Texture
        The zone (:func:`zone_texture`).
    rig : Rig
        Holding ``path`` among its ``paths`` (the design's ``check_paths``).
    stimulus : str
    level : float or None
    asked_contrast : float
    path : str
        The touch log (``t_s,x_mm,y_mm[,force_n]``, mm from the zone's top-left corner).

    Returns
    -------
    StimulusFigures

    Examples
    --------
    A touch log written with ``csv``: 100 mm/s across a 20 × 10 mm zone along its middle, as the swipe goes:

    >>> import csv, pathlib, tempfile
    >>> from ultraglide.experiment import design_from_dict
    >>> log = pathlib.Path(tempfile.mkdtemp()) / "touch.csv"
    >>> with open(log, "w", newline="") as handle:
    ...     csv.writer(handle).writerows([["t_s", "x_mm", "y_mm"]] + [[k / 100, k, 5.0] for k in range(21)])
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm", "contrast": 0.3}},
    ...     "conditions": [{"name": "g", "stimulus": "g"}], "blocks": [{"task": "rating", "conditions": ["g"]}],
    ...     "rig": {"zone_mm": [20, 10], "check_paths": [str(log)]}})
    >>> rig = Rig(design)
    >>> found = measure_path(zone_texture(design.stimuli["g"], rig.zone_mm), rig, "g", None, 0.3, str(log))
    >>> round(found.asked_mean, 2), round(found.path_contrast, 2), 0.15 < found.delivered_contrast <= 0.3
    (0.85, 0.3, True)
    """
    from ultraglide.experiment.stimuli import Layout, delivered_ratio, offline_sampler, render_along
    from ultraglide.render.renderer import RenderSettings
    from ultraglide.render.trajectory import RecordedTrajectory
    from ultraglide.textures.compose import Placement, compose
    from ultraglide.textures.sampling import Sampler

    layout = Layout(1, rig.zone_mm, rig.gap_mm)
    px = float(min(MAX_PX_PER_MM, max(10.0, 1.0 / min(texture.pixel_mm))))
    canvas = compose(layout.size_mm, [Placement(texture, layout.zone_left_mm(0), layout.gap_mm)], 1.0, px_per_mm=px,
                     name=f"check-{stimulus}")
    t, x, y, force = rig.paths[path]
    offset = layout.zone_left_mm(0), layout.gap_mm  # the zone's corner on the canvas
    trajectory = RecordedTrajectory(t, x + offset[0], y + offset[1], force)
    settings = RenderSettings(default_force_n=rig.force_n)
    speed = float(np.percentile(np.hypot(np.diff(x), np.diff(y)) / np.maximum(np.diff(t), 1e-6), 95)) if len(t) > 2 \
        else rig.speed_mm_s
    along = render_along(canvas, trajectory, rig.model, rig.profile, settings,
                         offline_sampler(canvas, max(speed, 1.0), settings))
    zx, zy = along.x_mm - offset[0], along.y_mm - offset[1]
    on_zone = (zx >= EDGE_MM) & (zx < rig.zone_mm[0] - EDGE_MM) & (zy >= 0) & (zy < rig.zone_mm[1])
    forces = np.full(len(zx), rig.force_n)
    moving = np.hypot(np.gradient(zx), np.gradient(zy))
    ratio = delivered_ratio(rig.model, along.plate_um_pp, settings.control_rate_hz, forces,
                            np.maximum(moving * settings.control_rate_hz, 1.0))
    direction = (np.gradient(zx) / np.maximum(moving, 1e-12), np.gradient(zy) / np.maximum(moving, 1e-12))
    asked = Sampler(texture, band_limited=False).ratio(np.clip(zx, 0, rig.zone_mm[0]), np.clip(zy, 0, rig.zone_mm[1]),
                                                       direction=direction).astype(np.float64)
    if not on_zone.any():
        return StimulusFigures(stimulus, level, float(asked_contrast), 0.0, 0.0, 1.0, 1.0, 0.0, along.peak)
    path_low, path_high = np.percentile(asked[on_zone], [1, 99])
    low, high = np.percentile(ratio[on_zone], [1, 99])
    return StimulusFigures(stimulus, level, float(asked_contrast), float(path_high - path_low), float(high - low),
                           float(asked[on_zone].mean()), float(ratio[on_zone].mean()),
                           float(np.median(along.plate_um_pp[on_zone])), along.peak)


def _asked_contrast(texture, stimulus: Stimulus, level: float | None) -> float:
    if level is not None:
        return float(level)
    if stimulus.contrast is not None:
        return float(stimulus.contrast)
    return float(texture.values.max() - texture.values.min())


def check_stimuli(design: Design, rig: Rig | None = None) -> CheckReport:
    """Render every stimulus of ``design`` along the zone's swipe and compare what it delivers with what was asked
    (see the module docstring for the criteria).

    Parameters
    ----------
    design : Design
    rig : Rig, optional
        The design's model and profile, if already loaded.

    Returns
    -------
    CheckReport
        Its ``failures`` name the stimulus and the figure, one sentence each; :func:`refuse` raises the first.

    Examples
    --------
    >>> from ultraglide.experiment import design_from_dict, check_stimuli
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm", "contrast": 0.3}},
    ...     "conditions": [{"name": "g", "stimulus": "g"}],
    ...     "blocks": [{"task": "rating", "conditions": ["g"], "repeats": 2}]})
    >>> report = check_stimuli(design)
    >>> report.passed, round(report.figures["g"].path_contrast, 2)
    (True, 0.3)
    """
    rig = rig or Rig(design)
    figures: dict[str, StimulusFigures] = {}
    failures: list[str] = []
    sources: dict[str, ZoneSource] = {}

    def zone_source(name: str) -> ZoneSource:
        if name not in sources:
            sources[name] = ZoneSource(design.stimuli[name], rig.zone_mm)
        return sources[name]

    refuse_unfit(design, zone_source)

    def texture_of(name: str, level: float | None):
        return zone_source(name).texture(level)

    felt = getattr(rig.model, "dynamics", None) is not None  # the figures are felt (stimuli.delivered_ratio)

    def check(name: str, level: float | None) -> StimulusFigures:
        key = name if level is None else f"{name}@{level:g}"
        if key not in figures:
            texture = texture_of(name, level)
            stimulus = design.stimuli[name]
            asked = _asked_contrast(texture, stimulus, level)
            for path in rig.paths:
                along = measure_path(texture, rig, name, level, asked, path)
                figures[f"{key} along {path}"] = along
                _judge(along, f"along the recorded path {path}", "the path does not cross its features", failures,
                       felt)
            found = measure(texture, rig, name, level, asked)
            figures[key] = found
            _judge(found, "along the swipe", "the swipe along the zone's middle does not cross its features", failures,
                   felt)
        return figures[key]

    for block in design.blocks:
        for name in block.conditions:
            condition = design.conditions[name]
            varied = block.task in ADAPTIVE + ("constant", "adjustment")
            top = max(condition.levels) if block.task == "constant" else condition.range[1]
            if varied and condition.vary == "contrast":
                check(condition.stimulus, top)
            elif varied and condition.vary == "amplitude":  # a uniform vibration: the drive limit's effect on it
                key = f"uniform@{top:g}um"
                if key not in figures:
                    figures[key] = found = _uniform(rig, top)
                    if abs(found.delivered_mean - found.asked_mean) > MAX_MEAN_ERROR:
                        failures.append(f"stimulus {found.label!r} delivers a mean friction ratio of "
                                        f"{found.delivered_mean:.3f} where {top:g} µm p-p asks {found.asked_mean:.3f} "
                                        f"({found.delivered_um_pp:.2f} µm p-p delivered: the plate's limit)")
            else:
                check(condition.stimulus, None)
            if condition.reference is not None:
                check(condition.reference, None)
            if block.task == "magnitude":
                check(block.modulus_stimulus, None)
            if block.task in ("afc", "same_different"):
                _check_pair(design, name, figures, failures)
    return CheckReport(figures, failures, felt)


def refuse_unfit(design: Design, zone_source) -> None:
    """Refuse a design one of whose stimuli cannot be built at a level it may take: its ``mean`` puts its friction
    ratios outside 0..1 there (a design's contrast and mean are what the plate is asked for, exactly: neither is
    clipped). A varied stimulus is judged at the top of its range or its largest level, its spread largest there;
    every other at its own contrast. Nothing is rendered: it comes before the check's renders and any trial.

    Parameters
    ----------
    design : Design
    zone_source : callable
        ``zone_source(name)``: the stimulus's :class:`ZoneSource`.

    Raises
    ------
    ExperimentError
        One line naming the first such stimulus, the level, the largest contrast that fits at its mean and the
        means that fit at that level.

    Examples
    --------
    >>> from ultraglide.experiment import design_from_dict
    >>> design = design_from_dict({"stimuli": {"g": {"texture": "grating-1mm", "mean": 0.8}},
    ...     "conditions": [{"name": "c", "stimulus": "g", "range": [0.05, 0.6]}],
    ...     "blocks": [{"task": "staircase", "conditions": ["c"], "trials": 4}]})
    >>> try:
    ...     refuse_unfit(design, lambda name: ZoneSource(design.stimuli[name], design.zone_mm))
    ... except ExperimentError as error:
    ...     print(str(error)[:60])
    stimulus 'g' at level 0.6 (the top of conditions.c.range): a
    """
    for block in design.blocks:
        for name in block.conditions:
            condition = design.conditions[name]
            if block.task in ADAPTIVE + ("constant", "adjustment") and condition.vary == "contrast":
                if block.task == "constant":
                    level, what = max(condition.levels), f"the largest of conditions.{name}.levels"
                    change = f"lower conditions.{name}.levels to at most {{}}"
                else:
                    level, what = condition.range[1], f"the top of conditions.{name}.range"
                    change = f"lower the top of conditions.{name}.range to {{}}"
                _refuse_unfit(zone_source(condition.stimulus), level, what, change)
            else:
                _refuse_unfit(zone_source(condition.stimulus))
            for other in (condition.reference, block.modulus_stimulus if block.task == "magnitude" else None):
                if other is not None:
                    _refuse_unfit(zone_source(other))


def _refuse_unfit(source: ZoneSource, level: float | None = None, what: str = "", change: str = "") -> None:
    low, high, largest, low_mean, high_mean = source.fit(level)
    if low >= -1e-9 and high <= 1 + 1e-9:
        return
    stimulus = source.stimulus
    key = f"stimuli.{stimulus.name}"
    contrast = level if level is not None else stimulus.contrast
    asked = f"a friction contrast of {contrast:g}" if contrast is not None else (
        f"its map's own contrast ({high - low:.3f})")
    fits = f"{math.floor(largest * 1000) / 1000:.3f}"
    if level is None:
        change = (f"lower {key}.contrast to {{}}" if stimulus.contrast is not None else
                  f"give {key} a contrast of at most {{}}")
    at = f" at level {level:g} ({what})" if level is not None else ""
    raise ExperimentError(f"stimulus {stimulus.name!r}{at}: {asked} around a mean friction ratio of "
                          f"{stimulus.mean:g} puts its ratios at {low:.3f}..{high:.3f}, outside 0..1; at that mean its "
                          f"contrast fits up to {fits}: {change.format(fits)}, or set {key}.mean within "
                          f"{math.ceil(low_mean * 1000) / 1000:.3f}..{math.floor(high_mean * 1000) / 1000:.3f}")


def _judge(found: StimulusFigures, along: str, uncrossed: str, failures: list[str], felt: bool = False) -> None:
    """The contrast and mean criteria on one stimulus's figures along one path (a sentence each in ``failures``);
    ``felt``: the figures are the friction felt through the model's friction dynamics."""
    if found.asked_contrast >= MIN_ASKED_CONTRAST and (
            found.delivered_contrast < MIN_CONTRAST_KEPT * found.asked_contrast):
        on_path = found.path_contrast / found.asked_contrast  # what the path's line holds of it
        rendered = found.delivered_contrast / max(found.path_contrast, 1e-12)  # what the plate keeps of that
        taken = ("the finger's friction dynamics, the renderer and the drive limit take it away: judged as felt"
                 if felt else "the renderer and the drive limit take it away")
        where = uncrossed if on_path <= rendered else taken
        failures.append(f"stimulus {found.label!r} delivers a friction contrast of {found.delivered_contrast:.4f} "
                        f"{along} where the design asks {found.asked_contrast:.4f} ({where})")
    if abs(found.delivered_mean - found.asked_mean) > MAX_MEAN_ERROR:
        why = "felt through the finger's friction dynamics" if felt else "the plate cannot reach it"
        failures.append(f"stimulus {found.label!r} delivers a mean friction ratio of {found.delivered_mean:.3f} where "
                        f"its map asks {found.asked_mean:.3f} {along} ({why})")


def _uniform(rig: Rig, amplitude_um_pp: float) -> StimulusFigures:
    """A zone vibrating uniformly at ``amplitude_um_pp``, measured along the swipe (``vary = "amplitude"``)."""
    from ultraglide.textures.texture import Texture

    ratio = float(rig.model.relative_friction(np.array([amplitude_um_pp]), rig.force_n)[0]) if amplitude_um_pp > 0 \
        else 1.0
    texture = Texture(np.full((2, 2), ratio, dtype=np.float32), *rig.zone_mm, name="uniform")
    found = measure(texture, rig, "uniform vibration", amplitude_um_pp, 0.0)
    return StimulusFigures(f"uniform vibration of {amplitude_um_pp:g} µm p-p", None, 0.0, found.path_contrast,
                           found.delivered_contrast, ratio, found.delivered_mean, found.delivered_um_pp,
                           found.peak_drive)


def _check_pair(design: Design, condition_name: str, figures: dict, failures: list[str]) -> None:
    condition = design.conditions[condition_name]
    a, b = design.stimuli[condition.stimulus], design.stimuli[condition.reference]
    fa, fb = figures[a.name], figures[b.name]
    keys = ("texture", "contrast", "mean", "scale", "rotation_deg")
    differs = [key for key in keys if getattr(a, key) != getattr(b, key)]
    meant = ", ".join(differs) or "nothing"
    if a.contrast == b.contrast and min(fa.delivered_contrast, fb.delivered_contrast) > 0:
        ratio = max(fa.delivered_contrast, fb.delivered_contrast) / min(fa.delivered_contrast, fb.delivered_contrast)
        if ratio > MAX_PAIR_CONTRAST_RATIO:
            failures.append(f"condition {condition_name!r}: {a.name!r} and {b.name!r} are meant to differ in {meant} "
                            f"only, but their delivered contrasts differ too: {fa.delivered_contrast:.4f} and "
                            f"{fb.delivered_contrast:.4f}")
    if a.mean == b.mean and abs(fa.delivered_mean - fb.delivered_mean) > MAX_PAIR_MEAN_DIFFERENCE:
        failures.append(f"condition {condition_name!r}: {a.name!r} and {b.name!r} are meant to differ in {meant} only, "
                        f"but their delivered mean friction ratios differ too: {fa.delivered_mean:.3f} and "
                        f"{fb.delivered_mean:.3f} (give both the same mean)")


def refuse(report: CheckReport) -> None:
    """Raise :class:`StimulusCheckError` with the report's first failure (and how many more), if any.

    Parameters
    ----------
    report : CheckReport

    Raises
    ------
    StimulusCheckError
        The report failed.

    Examples
    --------
    >>> refuse(CheckReport({}, []))                      # passed: nothing raised
    >>> refuse(CheckReport({}, ["stimulus 'a' is weak", "stimulus 'b' is weak"]))
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.StimulusCheckError: stimulus 'a' is weak (and 1 more problems); change the design, ...
    """
    if report.failures:
        more = f" (and {len(report.failures) - 1} more problems)" if len(report.failures) > 1 else ""
        raise StimulusCheckError(report.failures[0] + more + "; change the design, or accept it with the warning "
                                 "recorded (--accept-check)")
