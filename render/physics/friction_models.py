"""Friction models: amplitude and force → friction ratio, and back.

Every model maps a vibration amplitude (µm peak-to-peak) and a normal force (N) to the friction
ratio mu/mu0 (1 = plate at rest), and inverts that: which amplitude gives a target ratio. All
functions are vectorised over numpy arrays; the inverse is the real-time hot path.

Examples
--------
>>> from ultraglide.render.physics.friction_models import ExponentialModel
>>> model = ExponentialModel()
>>> result = model.amplitude_um_pp([1.0, 0.5, 0.01], force_n=0.5, limit_um_pp=5.0)
>>> result.amplitude_um_pp.round(2).tolist(), result.clamped
([0.0, 3.11, 5.0], 1)

Ratios the plate cannot reach (below the ratio at the amplitude limit) are clamped to the limit
and counted in ``clamped``; ratios above 1 mean rest (0 µm). No amplitude ever exceeds
``limit_um_pp`` or the model's own validity range ``max_amplitude_um_pp``. Forces may be one
number or one per sample (a pressure-sensing panel); forces below 10 mN count as 10 mN (the
finger is lifting), forces above 10 N (a fingertip's touch range) as 10 N.
NaN, infinite or negative forces, ratios or amplitudes raise :class:`ModelError` with one line.

Every model states its force law and where it holds (:meth:`FrictionModel.force_law`,
:meth:`FrictionModel.valid_force_range_n`): assumed from the paper's detachment law, fitted by a
calibration on a range of forces, or absent. Asked about a force outside that range (10 mN and
lighter excepted: the finger is lifting), a model says so once, as a :class:`ForceRangeWarning`.
"""

from ultraglide.render.physics.empirical_models import (
    ASSUMED_FORCE_EXPONENT,
    FORCE_EXPONENT_RANGE,
    MONNOYER_SCALE_UM_PP,
    MONNOYER_TAU_UM_ZP,
    REFERENCE_FORCE_N,
    RESIDUAL_RANGE,
    SCALE_RANGE_UM_PP,
    SHAPE_RANGE,
    TAU_RANGE_UM_ZP,
    ExponentialModel,
    StretchedExponentialModel,
)
from ultraglide.render.physics.model_base import (
    CEILING_UM_PP,
    DEFAULT_FORCE_N,
    MAX_FORCE_N,
    MIN_FORCE_N,
    RATIO_GRID_POINTS,
    FitRange,
    FrictionModel,
    Inversion,
    UniformTable,
    check_amplitude,
    check_force,
    check_ratio,
)
from ultraglide.render.physics.paper_model import PaperModel
from ultraglide.render.physics.table_model import TableModel

__all__ = [
    "ASSUMED_FORCE_EXPONENT", "CEILING_UM_PP", "DEFAULT_FORCE_N", "FORCE_EXPONENT_RANGE", "MAX_FORCE_N", "MIN_FORCE_N",
    "MONNOYER_SCALE_UM_PP", "MONNOYER_TAU_UM_ZP", "RATIO_GRID_POINTS", "REFERENCE_FORCE_N", "RESIDUAL_RANGE",
    "SCALE_RANGE_UM_PP", "SHAPE_RANGE", "TAU_RANGE_UM_ZP", "ExponentialModel", "FitRange",
    "FrictionModel", "Inversion", "PaperModel", "StretchedExponentialModel", "TableModel", "UniformTable",
    "check_amplitude", "check_force", "check_ratio",
]
