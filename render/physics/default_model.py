"""The friction model every rendering command and the API use unless told otherwise (a module of its own, so a
command's options can name it without importing the models).

``dynamic`` is the ``stretched`` law (force-aware, with a floor of 0.10, the mean measured at 6 µm p-p by
Wiertlewski et al. 2016) with the published friction dynamics (friction falls in about 5 ms when the vibration
starts and recovers over about 70 ms at 22 mm/s when it stops: Meyer et al. 2014), so the renderer plans the
friction felt (:mod:`ultraglide.render.planning`).

Experiments (``ultraglide experiment``, :mod:`ultraglide.experiment`) render with :data:`EXPERIMENT_MODEL`, the
static ``stretched`` law, unless a design's ``[rig] model`` or ``--model`` says otherwise: their stimulus check
refuses a stimulus it judges undeliverable, and under friction dynamics it judges the friction felt, whose time
constants are our reading of Meyer et al. 2014 and whose speed law is assumed. A design opts in with
``model = "dynamic"``.

Examples
--------
>>> from ultraglide.render.physics.calibration import load_model
>>> model = load_model(DEFAULT_MODEL)
>>> model.name, model.dynamics is not None
('dynamic', True)
"""

DEFAULT_MODEL = "dynamic"
EXPERIMENT_MODEL = "stretched"
