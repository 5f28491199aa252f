"""Which exceptions are a person's mistake (one line) rather than our bug (a traceback), and their exit status.

A person's input that cannot be used (an option, a value, a file the command reads) is usage: exit 2, as
argparse's own refusals. Anything else a person can fix (a device, a port, an output that cannot be written, a
resource that ran out) is 1. An error that carries its own ``exit_status`` (a lost engine's 7, a touch panel's
usage) keeps it. See :func:`exit_status`.
"""

from __future__ import annotations

import sys

from ultraglide.errors import UltraglideError, describe


class UsageError(UltraglideError, ValueError):
    """Options that make no sense together, found after parsing."""


# what an optional dependency's import is called -> (the distribution, the extra that installs it)
EXTRAS = {"pygame": ("pygame-ce", "demo"), "matplotlib": ("matplotlib", "figures")}


def missing_extra(error: ImportError) -> str | None:
    """One line naming the extra to install, for an optional dependency that is not there; None for any other
    import error (a bug, which keeps its traceback)."""
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return None
    wanted = EXTRAS.get(error.name.partition(".")[0])
    if wanted is None:
        return None
    package, extra = wanted
    return (f"this needs {package}, which ultraglide's '{extra}' extra installs: pip install 'ultraglide[{extra}]' "
            f"(or 'ultraglide[all]')")


def require(module: str) -> None:
    """Before any work: raise ModuleNotFoundError for an optional dependency that is not installed (the command
    says which extra installs it), rather than after a session's trials, when the figures are drawn."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise ModuleNotFoundError(f"No module named {module!r}", name=module)


USER_ERRORS = (UltraglideError, OSError)  # reported as one line; anything else is a bug and keeps its traceback

EXIT_ERROR = 1  # a person can fix it: a device, an output that cannot be written, a resource
EXIT_USAGE = 2  # the input cannot be used: an option, a value, a file the command reads


def _input_errors() -> tuple[type[BaseException], ...]:
    """The error classes each loader and checker raises for input it refuses (imported when an error is being
    reported, not at every command's start)."""
    from ultraglide.devices.profiles import ProfileError
    from ultraglide.devices.rig import RigError
    from ultraglide.render.errors import RenderError
    from ultraglide.render.physics.errors import ModelError
    from ultraglide.textures.errors import TextureError

    from ultraglide.experiment.errors import ExperimentError

    return UsageError, TextureError, ModelError, RenderError, ExperimentError, RigError, ProfileError


def exit_status(error: BaseException) -> int:
    """The exit status for an error reported in one line.

    Parameters
    ----------
    error : BaseException
        One of :data:`USER_ERRORS`.

    Returns
    -------
    int
        The error's own ``exit_status`` when it has one (a lost engine's 7); 2 (usage) for input the command
        cannot use: :class:`UsageError` and the loaders' errors (textures, friction models and calibrations,
        trajectories and render settings, experiment designs, rig files, plate profiles); 1 for anything else
        (a device, an output refused, an ``OSError``, the engine failing).

    Examples
    --------
    >>> from ultraglide.render.physics.errors import ModelError
    >>> exit_status(ModelError("cal.toml: not a valid TOML file")), exit_status(UsageError("-o needs .toml"))
    (2, 2)
    >>> from ultraglide.devices.errors import DeviceError
    >>> exit_status(DeviceError("the port went away")), exit_status(PermissionError(13, "Permission denied"))
    (1, 1)
    """
    own = getattr(error, "exit_status", None)
    if own:
        return int(own)
    engine = sys.modules.get("ultraglide.render.engine.engine")  # an engine's failure is not the input's
    if engine is not None and isinstance(error, engine.EngineError):
        return EXIT_ERROR
    return EXIT_USAGE if isinstance(error, _input_errors()) else EXIT_ERROR


__all__ = ["EXIT_ERROR", "EXIT_USAGE", "EXTRAS", "USER_ERRORS", "UsageError", "describe", "exit_status",
           "missing_extra", "require"]
