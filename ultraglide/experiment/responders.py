"""The participant-interface seam: what presents a trial and brings back the answer.

A session (:func:`ultraglide.experiment.run`) talks to its participant through one object with two methods,
so a simulated observer, the pygame window (``ultraglide.apps.experiment.window``) and the participant's page in a
browser through the service (``ultraglide.apps.experiment.browser``) are interchangeable:

* ``present(trial: Trial) -> Answer``: make the trial's stimuli felt (or render them offline), ask the trial's
  question with its response labels, and return the answer;
* ``take_break(trial: int, message: str) -> bool``: a pause before ``trial``; False stops the session.

The threshold sessions of ``ultraglide experiment threshold|constant`` use the older ``present(trial, level,
target, design)`` of the same :class:`Answer`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


@dataclass
class Answer:
    """A trial's answer. ``response``: the chosen interval (0-based) in forced choice, 1/0 for yes/no and
    same/different (1 = "different"), the scale's value for a rating, the number given in magnitude
    estimation; ``rt_s``: reaction time, s (NaN when unknown); ``quit``: the participant stopped the session."""

    response: float
    rt_s: float
    rendered_um_pp: float | None = None
    rendered_contrast: float | None = None
    quit: bool = False
    friction: dict | None = None  # what the trial played: target_ratio, measured_ratio, commanded_um_pp, loop


class Responder(Protocol):
    """The seam a participant's interface implements (see the module docstring)."""

    def present(self, trial) -> Answer: ...

    def take_break(self, trial: int, message: str) -> bool: ...
