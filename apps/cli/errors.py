"""Which exceptions are a person's mistake (one line, exit 1) rather than our bug (a traceback)."""

from __future__ import annotations

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

__all__ = ["EXTRAS", "USER_ERRORS", "UsageError", "describe", "missing_extra", "require"]
