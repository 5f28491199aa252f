"""The experiment package's error: a design, an observer spec or a stimulus that cannot be used."""

from __future__ import annotations

from ultraglide.errors import UltraglideError


class ExperimentError(UltraglideError, ValueError):
    """A design, a simulated observer's spec or a stimulus refused; the message is one line saying what is wrong
    and what to do.

    Examples
    --------
    >>> from ultraglide.experiment import SimObserver
    >>> SimObserver.parse("sim:slope=3")
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.ExperimentError: --observer needs threshold=T (in the varied parameter's units)
    """


class StimulusCheckError(ExperimentError):
    """A stimulus that does not deliver what the design asks (see :func:`ultraglide.experiment.check_stimuli`).

    Examples
    --------
    >>> from ultraglide.experiment.check import CheckReport, refuse
    >>> refuse(CheckReport({}, ["stimulus 'g' delivers a friction contrast of 0.01"]))
    Traceback (most recent call last):
    ...
    ultraglide.experiment.errors.StimulusCheckError: stimulus 'g' delivers a friction contrast of 0.01; change the ...
    >>> issubclass(StimulusCheckError, ExperimentError)
    True
    """
