"""Re-exports imported on first use (PEP 562): the ``__getattr__`` and ``__dir__`` a package's ``__init__`` uses
to offer the public names of its modules without importing them all when it is imported.

Every room of ``devices/``, ``ultraglide.experiment`` and ``ultraglide`` itself re-export this way, so that
``import ultraglide`` and the command's parsers stay quick. This module imports nothing of ours: every layer,
``devices`` and ``textures`` included, may import it (tests/test_layers.py counts it among the root's leaves).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping
from typing import Any


def lazy_exports(package: str, exports: Mapping[str, str],
                 namespace: MutableMapping[str, Any]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of a package that re-exports names lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``; a module given in ``exports`` without a dot is a module of this package.
    exports : Mapping[str, str]
        Public name -> the module that defines it: ``"stage"`` (a module of ``package``) or a whole dotted name
        (``"ultraglide.textures.texture"``).
    namespace : MutableMapping[str, Any]
        The package's ``globals()``: a name is kept there once imported, so it is looked up once.

    Returns
    -------
    tuple of (callable, callable)
        ``__getattr__(name)``, which imports the module that defines ``name`` and returns the name (an
        ``AttributeError`` for a name not exported, as Python raises for a missing attribute), and ``__dir__()``,
        the package's names and its exports, sorted.

    Examples
    --------
    >>> import types
    >>> room = types.ModuleType("room")
    >>> room.__getattr__, room.__dir__ = lazy_exports("room", {"join": "os.path"}, vars(room))
    >>> "join" in vars(room), "join" in dir(room)
    (False, True)
    >>> room.join("textures", "wood.npz")
    'textures/wood.npz'
    >>> "join" in vars(room)
    True
    >>> room.split
    Traceback (most recent call last):
    ...
    AttributeError: module 'room' has no attribute 'split'
    """
    where = {name: module if "." in module else f"{package}.{module}" for name, module in exports.items()}

    def __getattr__(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(where))

    return __getattr__, __dir__
