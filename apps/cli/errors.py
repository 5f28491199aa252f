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


# the error classes each loader and checker raises for input it refuses: (module, class)
INPUT_ERRORS = (("ultraglide.textures.errors", "TextureError"), ("ultraglide.render.physics.errors", "ModelError"),
                ("ultraglide.render.errors", "RenderError"), ("ultraglide.experiment.errors", "ExperimentError"),
                ("ultraglide.devices.rig", "RigError"), ("ultraglide.devices.profiles", "ProfileError"),
                ("ultraglide.devices.errors", "CarrierError"))


def _loaded(module: str, name: str) -> type | None:
    """A class of a module already imported, else None: an error of that class implies its module is loaded, so
    reporting an error imports nothing (under a memory limit, or a process on its way out)."""
    loaded = sys.modules.get(module)
    return getattr(loaded, name, None) if loaded is not None else None


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
        trajectories and render settings, experiment designs, rig files, plate profiles, a carrier the plate or
        the rate refuses); 1 for anything else (a device, an output refused, an ``OSError``, the engine failing).

    Examples
    --------
    >>> from ultraglide.render.physics.errors import ModelError
    >>> exit_status(ModelError("cal.toml: not a valid TOML file")), exit_status(UsageError("-o needs .toml"))
    (2, 2)
    >>> from ultraglide.devices.errors import DeviceError
    >>> exit_status(DeviceError("the port went away")), exit_status(PermissionError(13, "Permission denied"))
    (1, 1)
    >>> from ultraglide.render.engine.engine import EngineError   # a RenderError, but the engine's, not the input's
    >>> exit_status(EngineError("the engine has stopped"))
    1
    """
    own = getattr(error, "exit_status", None)
    if own:
        return int(own)
    engine = _loaded("ultraglide.render.engine.engine", "EngineError")  # the engine failing is not the input
    if engine is not None and isinstance(error, engine):
        return EXIT_ERROR
    inputs = (UsageError, *(found for found in (_loaded(*where) for where in INPUT_ERRORS) if found is not None))
    return EXIT_USAGE if isinstance(error, inputs) else EXIT_ERROR


__all__ = ["EXIT_ERROR", "EXIT_USAGE", "EXTRAS", "INPUT_ERRORS", "USER_ERRORS", "UsageError", "describe", "exit_status",
           "missing_extra", "require"]
