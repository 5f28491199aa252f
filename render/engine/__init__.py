"""The real-time engine: joins a renderer to a device, in its own process, fed touches through shared memory.

:class:`Engine` (:mod:`.engine`) is what an app uses; :mod:`.process` is the engine's own process,
:mod:`.shm` the shared memory between the two, :mod:`.status` what it reports, :mod:`.sources` a
renderer as a device's source, :mod:`.realtime` what it asks of the OS.
"""

from ultraglide.render.engine.engine import Engine, EngineConfig, EngineError, EngineLost
from ultraglide.render.engine.status import EngineStatus, History

__all__ = ["Engine", "EngineConfig", "EngineError", "EngineLost", "EngineStatus", "History"]
