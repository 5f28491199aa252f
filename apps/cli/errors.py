"""Which exceptions are a person's mistake (one line, exit 1) rather than our bug (a traceback)."""

from __future__ import annotations

from ultraglide.errors import UltraglideError, describe


class UsageError(UltraglideError, ValueError):
    """Options that make no sense together, found after parsing."""


USER_ERRORS = (UltraglideError, OSError)  # reported as one line; anything else is a bug and keeps its traceback

__all__ = ["USER_ERRORS", "UsageError", "describe"]
