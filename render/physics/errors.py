"""Errors of the physics that a person can act on; the message says what to do."""

from ultraglide.errors import UltraglideError


class ModelError(UltraglideError, ValueError):
    """A friction model, calibration or measurement file that cannot be used; a ``ValueError`` too.

    Examples
    --------
    >>> from ultraglide.render.physics.empirical_models import ExponentialModel
    >>> ExponentialModel().amplitude_um_pp(float("nan"))    # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.render.physics.errors.ModelError: friction ratio must be a finite number >= 0 ..., got nan
    """


class ForceRangeWarning(UltraglideError, UserWarning):
    """A model was asked about a force outside the range it was fitted on or holds on (said once per model).

    A ``UserWarning``, given with :func:`warnings.warn`: the model still answers, extrapolating its force law.

    Examples
    --------
    >>> import warnings
    >>> from ultraglide.render.physics.empirical_models import StretchedExponentialModel
    >>> model = StretchedExponentialModel()
    >>> with warnings.catch_warnings(record=True) as said:
    ...     warnings.simplefilter("always")
    ...     _ = model.relative_friction(1.0, force_n=4.0), model.relative_friction(1.0, force_n=5.0)  # N
    >>> [warning.category.__name__ for warning in said]                 # once per model
    ['ForceRangeWarning']
    """


class QuasiStaticWarning(UltraglideError, UserWarning):
    """The lateral analysis ran at a frequency where the ridges' inertia makes it an estimate.

    Examples
    --------
    At 100 kHz, above the ridge layer's shear resonance (about 33 kHz):

    >>> import warnings
    >>> from ultraglide.render.physics.lateral import simulate_lateral
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = simulate_lateral(3.0, 0.4, frequency_hz=100000.0, cycles=1, steps_per_cycle=100)
    >>> caught[0].category is QuasiStaticWarning, "only a quasi-static estimate" in str(caught[0].message)
    (True, True)
    """
