"""The dry run: each trial rendered offline through the real renderer, answered by a simulated observer.

Every trial's swipe (left to right across all its zones, at the configured speed and force) is rendered
to the null device's buffer as fast as the machine goes; what the plate model says each zone really
did is logged beside the answer (``rendered_um_pp``, ``rendered_contrast`` of the target zone), so a
dry run also shows whether the plate can render the levels the procedure asks for.
"""

from __future__ import annotations

from functools import lru_cache

from ultraglide.apps.experiment.observer import SimObserver
from ultraglide.apps.experiment.session import Answer
from ultraglide.apps.experiment.stimuli import StimulusDesign, render_offline
from ultraglide.devices.profiles import PlateProfile
from ultraglide.render.physics.friction_models import FrictionModel


class SimResponder:
    def __init__(self, observer: SimObserver, model: FrictionModel, profile: PlateProfile, speed_mm_s: float,
                 force_n: float):
        self.observer, self.model, self.profile = observer, model, profile
        self.speed_mm_s, self.force_n = speed_mm_s, force_n
        self.breaks: list[int] = []
        self.rendered_frames = 0
        self._texture = lru_cache(maxsize=32)(self._make_texture)
        self._design: StimulusDesign | None = None

    def _make_texture(self, level: float, target: int):
        return self._design.trial_texture(level, target)

    def take_break(self, trial: int) -> bool:
        """No pause for a simulated observer; the break is logged (break_before) all the same."""
        self.breaks.append(trial)
        return True

    def present(self, trial: int, level: float, target: int, design: StimulusDesign) -> Answer:
        self._design = design
        rendered = render_offline(self._texture(level, target), design.layout, self.model, self.profile,
                                  self.speed_mm_s, self.force_n)
        self.rendered_frames += rendered.frames
        response, rt_s = self.observer.respond(trial, level, max(design.layout.zones, 1), target)
        return Answer(response, rt_s, rendered.zone_um_pp[target], rendered.zone_contrast[target])
