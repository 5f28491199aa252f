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
    estimation; ``rt_s``: reaction time, s (NaN when unknown); ``quit``: the participant stopped the session.

    Parameters
    ----------
    response : float
    rt_s : float
        Reaction time, s.
    rendered_um_pp, rendered_contrast : float, optional
        What the target zone delivered (µm p-p; friction contrast), where the responder measured it.
    quit : bool
    friction : dict, optional
        What the trial played: ``target_ratio``, ``measured_ratio``, ``commanded_um_pp``, ``loop``.

    Examples
    --------
    >>> Answer(1, 0.8)
    Answer(response=1, rt_s=0.8, rendered_um_pp=None, rendered_contrast=None, quit=False, friction=None)
    """

    response: float
    rt_s: float
    rendered_um_pp: float | None = None
    rendered_contrast: float | None = None
    quit: bool = False
    friction: dict | None = None  # what the trial played: target_ratio, measured_ratio, commanded_um_pp, loop


class Responder(Protocol):
    """The seam a participant's interface implements (see the module docstring).

    Examples
    --------
    A responder that always picks the first interval, run without the stimulus check: it is right where the plan
    put the target first.

    >>> from ultraglide.experiment import design_from_dict, plan, run
    >>> class FirstZone:
    ...     def present(self, shown):
    ...         return Answer(0, 0.5)
    ...     def take_break(self, trial, message):
    ...         return True
    >>> design = design_from_dict({"stimuli": {"a": {"texture": "grating-1mm"}, "b": {"texture": "grating-2mm"}},
    ...     "conditions": [{"name": "ab", "a": "a", "b": "b"}],
    ...     "blocks": [{"task": "afc", "conditions": ["ab"], "repeats": 6}]})
    >>> session = run(design, responder=FirstZone(), check=False)
    >>> [row["correct"] for row in session.trials] == [int(trial.target == 0) for trial in plan(design)]
    True
    """

    def present(self, trial) -> Answer:
        """Make the trial felt, ask its question and return the answer.

        Parameters
        ----------
        trial : Presentation
            The trial, its level, question, answer labels and textures (:class:`ultraglide.experiment.Presentation`).

        Returns
        -------
        Answer

        Examples
        --------
        >>> from ultraglide.experiment.simulated import SimulatedParticipant
        >>> from ultraglide.experiment.design import Trial
        >>> from ultraglide.experiment.runner import Presentation
        >>> from types import SimpleNamespace
        >>> participant = SimulatedParticipant("sim:threshold=0.1,lapse=0", SimpleNamespace(model=None, profile=None,
        ...                                    speed_mm_s=100.0, force_n=0.5))
        >>> trial = Trial(1, "main", "same_different", "ab", False, 0, None, ("a", "a"))
        >>> shown = Presentation(trial, None, "Same or different?", ("Same", "Different"), 1, None, None, None,
        ...                      (None, None))
        >>> participant.present(shown).response           # no difference: P(different) = the false-alarm rate, 0
        0
        """
        ...

    def take_break(self, trial: int, message: str) -> bool:
        """A pause before ``trial``, with ``message`` shown; False stops the session.

        Parameters
        ----------
        trial : int
            The number of the trial that follows.
        message : str
            The design's break message, in the participant's language.

        Returns
        -------
        bool

        Examples
        --------
        >>> from types import SimpleNamespace
        >>> from ultraglide.experiment.simulated import SimulatedParticipant
        >>> rig = SimpleNamespace(model=None, profile=None, speed_mm_s=100.0, force_n=0.5)
        >>> participant = SimulatedParticipant("sim:threshold=0.1", rig)
        >>> participant.take_break(11, "Take a break."), participant.breaks
        (True, [11])
        """
        ...
