"""The experiment package's error: a design, an observer spec or a stimulus that cannot be used."""

from __future__ import annotations

from ultraglide.errors import UltraglideError


class ExperimentError(UltraglideError, ValueError):
    """A design, a simulated observer's spec or a stimulus refused; the message is one line saying what is wrong
    and what to do."""


class StimulusCheckError(ExperimentError):
    """A stimulus that does not deliver what the design asks (see :func:`ultraglide.experiment.check_stimuli`)."""
