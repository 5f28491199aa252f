"""The dry run: each trial rendered offline through the real renderer, answered by a simulated observer.

Every trial's swipe (left to right across all its zones, at the configured speed and force) is rendered
to the null device's buffer as fast as the machine goes; what the plate model says each zone really
did is logged beside the answer (``rendered_um_pp``, ``rendered_contrast`` of the target zone), so a
dry run also shows whether the plate can render the levels the procedure asks for.
"""

from __future__ import annotations

from collections import OrderedDict

from ultraglide.devices.profiles import PlateProfile
from ultraglide.experiment.observer import SimObserver
from ultraglide.experiment.responders import Answer
from ultraglide.experiment.stimuli import StimulusDesign, offline_sampler, render_offline
from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

CACHE_BYTES = 256 * 2**20  # trial textures and their lookups kept for levels the procedure comes back to


class TrialCache:
    """Trial textures and their lookups for one design, built once for each level and target (a procedure
    comes back to the same levels: 80 staircase trials use about 20; sessions of one design, such as a
    pilot's seeds, share most of theirs), at most :data:`CACHE_BYTES` kept, least recently used dropped
    first. Another design empties it.

    Examples
    --------
    >>> from ultraglide.experiment.stimuli import Layout, StimulusDesign
    >>> from ultraglide.textures.library import resolve_texture
    >>> cache = TrialCache()
    >>> design = StimulusDesign(resolve_texture("grating-1mm"), layout=Layout(2, (20.0, 10.0), 5.0))
    >>> first = cache.trial(design, 0.2, 1, 100.0)
    >>> cache.trial(design, 0.2, 1, 100.0)[0] is first[0], cache.trial(design, 0.3, 1, 100.0)[0] is first[0]
    (True, False)
    """

    def __init__(self):
        self._trials: OrderedDict[tuple, tuple[Texture, Sampler, int]] = OrderedDict()  # least recent first
        self._bytes = 0
        self._design: StimulusDesign | None = None  # the design the cached trials belong to

    def trial(self, design: StimulusDesign, level: float, target: int, speed_mm_s: float) -> tuple[Texture, Sampler]:
        """The trial's texture and the lookup a swipe at ``speed_mm_s`` reads it through.

        Parameters
        ----------
        design : StimulusDesign
        level : float
            In the design's unit.
        target : int
            The zone holding the stimulus, 0-based.
        speed_mm_s : float
            The swipe's speed, mm/s.

        Returns
        -------
        (Texture, Sampler)

        Examples
        --------
        >>> from ultraglide.experiment.stimuli import Layout, StimulusDesign
        >>> from ultraglide.textures.library import resolve_texture
        >>> design = StimulusDesign(resolve_texture("grating-1mm"), layout=Layout(2, (20.0, 10.0), 5.0))
        >>> texture, sampler = TrialCache().trial(design, 0.2, 0, 100.0)
        >>> texture.width_mm, sampler.texture is texture                  # 2 × 20 + 3 × 5 mm
        (55.0, True)
        """
        if design is not self._design:
            self._trials.clear()
            self._bytes, self._design = 0, design
        key = (float(level), target, float(speed_mm_s))
        if key in self._trials:
            self._trials.move_to_end(key)
            return self._trials[key][:2]
        texture = design.trial_texture(level, target)
        sampler = offline_sampler(texture, speed_mm_s)
        size = texture.values.nbytes + 2 * sum(a.nbytes for pyramid in sampler.pyramids for a in pyramid)
        while self._trials and self._bytes + size > CACHE_BYTES:
            self._bytes -= self._trials.popitem(last=False)[1][2]
        if size <= CACHE_BYTES:
            self._trials[key] = (texture, sampler, size)
            self._bytes += size
        return texture, sampler


class SimResponder:
    """The threshold sessions' dry-run responder: each trial rendered offline (:func:`render_offline`), answered by a
    simulated observer.

    Parameters
    ----------
    observer : SimObserver
    model : FrictionModel
    profile : PlateProfile
    speed_mm_s : float
        The swipe's speed, mm/s.
    force_n : float
        The finger's force, N.
    trials : TrialCache, optional
        Shared with other sessions of the same design (by default the responder's own).

    Examples
    --------
    Without lapses, a contrast 100 times the threshold is always found, and the log gets what the plate delivered:

    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.experiment.stimuli import Layout, StimulusDesign
    >>> from ultraglide.render.physics.calibration import load_model
    >>> from ultraglide.textures.library import resolve_texture
    >>> responder = SimResponder(SimObserver(threshold=0.003, lapse=0.0), load_model("stretched"),
    ...                          load_profile("sim-plate"), 100.0, 0.5)
    >>> design = StimulusDesign(resolve_texture("grating-1mm"), layout=Layout(2, (20.0, 10.0), 5.0))
    >>> answer = responder.present(1, 0.3, 1, design)
    >>> answer.response, 0.15 < answer.rendered_contrast <= 0.3, responder.rendered_frames > 0
    (1, True, True)
    """
    def __init__(self, observer: SimObserver, model: FrictionModel, profile: PlateProfile, speed_mm_s: float,
                 force_n: float, trials: TrialCache | None = None):
        """``trials``: a cache of trial textures to share with other sessions of the same design (by default
        the responder's own)."""
        self.observer, self.model, self.profile = observer, model, profile
        self.speed_mm_s, self.force_n = speed_mm_s, force_n
        self.breaks: list[int] = []
        self.rendered_frames = 0
        self.trials = trials if trials is not None else TrialCache()

    def take_break(self, trial: int) -> bool:
        """No pause for a simulated observer; the break is logged (break_before) all the same.

        Parameters
        ----------
        trial : int
            The trial that follows.

        Returns
        -------
        bool
            Always True.

        Examples
        --------
        >>> responder = SimResponder(SimObserver(threshold=0.1), None, None, 100.0, 0.5)
        >>> responder.take_break(21), responder.breaks
        (True, [21])
        """
        self.breaks.append(trial)
        return True

    def present(self, trial: int, level: float, target: int, design: StimulusDesign) -> Answer:
        """Render the trial offline and answer it.

        Parameters
        ----------
        trial : int
            The trial's number.
        level : float
            In the design's unit.
        target : int
            The zone holding the stimulus, 0-based.
        design : StimulusDesign

        Returns
        -------
        Answer
            With ``rendered_um_pp`` (µm p-p) and ``rendered_contrast`` of the target zone.

        Examples
        --------
        Plain glass in the target zone (contrast 0) asks the plate for nothing:

        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.experiment.stimuli import Layout, StimulusDesign
        >>> from ultraglide.render.physics.calibration import load_model
        >>> from ultraglide.textures.library import resolve_texture
        >>> responder = SimResponder(SimObserver(threshold=0.1), load_model("stretched"), load_profile("sim-plate"),
        ...                          100.0, 0.5)
        >>> design = StimulusDesign(resolve_texture("grating-1mm"), layout=Layout(2, (20.0, 10.0), 5.0))
        >>> answer = responder.present(1, 0.0, 0, design)
        >>> answer.rendered_um_pp, answer.rendered_contrast
        (0.0, 0.0)
        """
        texture, sampler = self.trials.trial(design, level, target, self.speed_mm_s)
        rendered = render_offline(texture, design.layout, self.model, self.profile, self.speed_mm_s, self.force_n,
                                  sampler=sampler)
        self.rendered_frames += rendered.frames
        response, rt_s = self.observer.respond(trial, level, max(design.layout.zones, 1), target)
        return Answer(response, rt_s, rendered.zone_um_pp[target], rendered.zone_contrast[target])
