"""Experiments on the researcher's terms: designs in code or TOML, stimuli checked, sessions, analyses.

The public API of experiments (``ultraglide.experiment``), free of windows: a design (:class:`Design` from
:func:`load_design` or :func:`design_from_dict`, or built of :class:`Stimulus`, :class:`Condition` and
:class:`Block`), its trial plan (:func:`plan`), the stimulus check (:func:`check_stimuli`), a session run with a
simulated observer or any responder (:func:`run`, returning a :class:`Session` whose ``trials`` are a
pandas-friendly list of dicts), and analyses as functions of that table (:func:`fit_psychometric`,
:func:`threshold_posterior`, :func:`proportions`, :func:`mean_response`). The participant's window lives in
``ultraglide.apps.experiment.window``; ``ultraglide experiment run DESIGN.toml`` opens it. The participant's page in
a browser (the service's) is ``ultraglide.apps.experiment.browser.BrowserResponder``; ``--serve`` serves it.

Examples
--------
>>> from ultraglide.experiment import Block, Condition, Design, Stimulus, run, fit_psychometric
>>> design = Design("grating contrast", {"g": Stimulus("g", "grating-1mm")},
...                 {"g": Condition("g", "g", levels=(0.02, 0.05, 0.1, 0.2))},
...                 (Block("main", "constant", ("g",), repeats=5),), seed=2)
>>> session = run(design, observer="sim:threshold=0.08,slope=3")
>>> [fit["condition"] for fit in fit_psychometric(session.trials, bootstrap=50)]
['g']
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

# public name -> the module that defines it, imported on first use (PEP 562, ultraglide.lazy): the commands'
# parsers import a module of this package without loading scipy
_EXPORTS = {
    "as_frame": "ultraglide.experiment.analysis",
    "fit_psychometric": "ultraglide.experiment.analysis",
    "mean_response": "ultraglide.experiment.analysis",
    "proportions": "ultraglide.experiment.analysis",
    "reaction_time_summary": "ultraglide.experiment.analysis",
    "read_trials": "ultraglide.experiment.analysis",
    "threshold_posterior": "ultraglide.experiment.analysis",
    "CheckReport": "ultraglide.experiment.check",
    "StimulusFigures": "ultraglide.experiment.check",
    "check_stimuli": "ultraglide.experiment.check",
    "zone_texture": "ultraglide.experiment.check",
    "DESIGN_COLUMNS": "ultraglide.experiment.columns",
    "THRESHOLD_COLUMNS": "ultraglide.experiment.columns",
    "Block": "ultraglide.experiment.design",
    "Condition": "ultraglide.experiment.design",
    "Design": "ultraglide.experiment.design",
    "Stimulus": "ultraglide.experiment.design",
    "Trial": "ultraglide.experiment.design",
    "design_from_dict": "ultraglide.experiment.design",
    "design_from_toml": "ultraglide.experiment.design",
    "load_design": "ultraglide.experiment.design",
    "plan": "ultraglide.experiment.design",
    "to_toml": "ultraglide.experiment.design",
    "ExperimentError": "ultraglide.experiment.errors",
    "StimulusCheckError": "ultraglide.experiment.errors",
    "SimObserver": "ultraglide.experiment.observer",
    "Answer": "ultraglide.experiment.responders",
    "Responder": "ultraglide.experiment.responders",
    "Presentation": "ultraglide.experiment.runner",
    "Session": "ultraglide.experiment.runner",
    "run": "ultraglide.experiment.runner",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:
    from ultraglide.experiment.analysis import (
        as_frame,
        fit_psychometric,
        mean_response,
        proportions,
        reaction_time_summary,
        read_trials,
        threshold_posterior,
    )
    from ultraglide.experiment.check import CheckReport, StimulusFigures, check_stimuli, zone_texture
    from ultraglide.experiment.columns import DESIGN_COLUMNS, THRESHOLD_COLUMNS
    from ultraglide.experiment.design import (
        Block,
        Condition,
        Design,
        Stimulus,
        Trial,
        design_from_dict,
        design_from_toml,
        load_design,
        plan,
        to_toml,
    )
    from ultraglide.experiment.errors import ExperimentError, StimulusCheckError
    from ultraglide.experiment.observer import SimObserver
    from ultraglide.experiment.responders import Answer, Responder
    from ultraglide.experiment.runner import Presentation, Session, run

__all__ = ["Answer", "Block", "CheckReport", "Condition", "DESIGN_COLUMNS", "Design", "ExperimentError",
           "Presentation", "Responder", "Session", "SimObserver", "Stimulus", "StimulusCheckError",
           "StimulusFigures", "THRESHOLD_COLUMNS", "Trial", "as_frame", "check_stimuli", "design_from_dict",
           "design_from_toml", "fit_psychometric", "load_design", "mean_response", "plan", "proportions",
           "reaction_time_summary", "read_trials", "run", "threshold_posterior", "to_toml", "zone_texture"]
