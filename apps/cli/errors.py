"""Which exceptions are a person's mistake (one line, exit 1) rather than our bug (a traceback)."""

from __future__ import annotations

import importlib


class UsageError(ValueError):
    """Options that make no sense together, found after parsing."""


_ERROR_CLASSES = (
    ("ultraglide.render.physics.errors", "ModelError"),
    ("ultraglide.render.errors", "RenderError"),
    ("ultraglide.textures.errors", "TextureError"),
    ("ultraglide.devices.errors", "DeviceError"),
)




def user_errors() -> tuple[type[BaseException], ...]:
    """The exception types to report as one line; imported lazily to keep start-up fast."""
    found: list[type[BaseException]] = [UsageError, OSError]
    for module_name, class_name in _ERROR_CLASSES:
        try:
            found.append(getattr(importlib.import_module(module_name), class_name))
        except (ImportError, AttributeError):
            continue
    return tuple(found)


def describe(error: BaseException) -> str:
    """One line for an error: OSErrors name the file and the reason (see :func:`devices.errors.describe`)."""
    from ultraglide.devices.errors import describe as describe_error

    return describe_error(error)
