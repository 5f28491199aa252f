"""The engine process's main thread once the device plays: commands from the app's pipe, the device's status
published ten times a second, idle garbage collection, and the way out (ramp to rest, rest the hardware, close
the records, the last status); and the probe that times the simulated plate for ``ultraglide latency``.
"""

from __future__ import annotations

import gc
import os
import threading
import time

import numpy as np
from ultraglide.render.engine import shm
from ultraglide.render.engine.parts import texture_of
from ultraglide.render.engine.realtime import CpuWakeLatency

from ultraglide.errors import UltraglideError, describe

STATUS_PERIOD_S = 0.1
PROBE_THRESHOLD_UM_PP = 0.05
PROBE_PERIOD_S = 0.0002
# what the engine reports to the app as one line (a plain ValueError too: a bad texture spec from a script)
USER_ERRORS = (UltraglideError, OSError, ValueError)


class PlateProbe(threading.Thread):
    """Watches the simulated plate's amplitude and publishes when it last rose above a threshold
    (for ``ultraglide latency`` on ``sim``: the end-to-end measurement).

    Parameters
    ----------
    simulator : PlateSimulator
        The simulated plate whose amplitude (µm p-p) is watched.
    fast : numpy.ndarray
        The shared memory's fast header, where the amplitude and the time of its last rise (perf_counter s) go.

    Examples
    --------
    The simulated plate at rest: the probe publishes its amplitude, 0 µm, and no rise:

    >>> import time
    >>> import numpy as np
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> device = open_device("sim", load_profile("sim-plate"))
    >>> fast = np.zeros(shm.HEADER); fast[shm.PLATE_PROBE_UM_PP] = -1.0
    >>> probe = PlateProbe(device.plate.simulator, fast); probe.start()
    >>> deadline = time.monotonic() + 30.0
    >>> while fast[shm.PLATE_PROBE_UM_PP] < 0.0 and time.monotonic() < deadline:
    ...     time.sleep(0.001)
    >>> probe.stop_event.set(); probe.join(); device.stop()
    >>> float(fast[shm.PLATE_PROBE_UM_PP]), float(fast[shm.PROBE_RISE_S])
    (0.0, 0.0)
    """

    def __init__(self, simulator, fast: np.ndarray):
        super().__init__(name="plate-probe", daemon=True)
        self.simulator = simulator
        self.fast = fast
        self.stop_event = threading.Event()

    def run(self) -> None:
        """Publish the simulated plate's amplitude (µm p-p) every probe period, and when it last rose above the
        threshold (perf_counter s), until stopped.

        Examples
        --------
        Run in this thread on a plate at 2 µm p-p that asks the probe to stop once read: one publication, and a rise
        (2 µm is above the threshold):

        >>> import time
        >>> import numpy as np
        >>> class Plate:
        ...     @property
        ...     def amplitude_um_pp(self):
        ...         probe.stop_event.set()
        ...         return 2.0
        >>> fast = np.zeros(shm.HEADER)
        >>> probe = PlateProbe(Plate(), fast)
        >>> before = time.perf_counter()
        >>> probe.run()
        >>> float(fast[shm.PLATE_PROBE_UM_PP]), bool(before <= fast[shm.PROBE_RISE_S] <= time.perf_counter())
        (2.0, True)
        """
        above = False
        while not self.stop_event.wait(PROBE_PERIOD_S):
            amplitude = self.simulator.amplitude_um_pp
            self.fast[shm.PLATE_PROBE_UM_PP] = amplitude
            if amplitude > PROBE_THRESHOLD_UM_PP and not above:
                self.fast[shm.PROBE_RISE_S] = time.perf_counter()
            above = amplitude > PROBE_THRESHOLD_UM_PP


def device_status(device, stage=None) -> dict:
    """The device's own status, with its fault counts over the run when it keeps them, and the limiter's.

    Parameters
    ----------
    device : Device
        The opened device.
    stage : EngineSource, optional
        The source the device plays: its limiter's status and summary, and the closed loop's.

    Returns
    -------
    dict
        The status; a status that fails to build is ``{"errors": [what went wrong]}`` (never raised: it must
        not stop the engine).

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> device_status(open_device("null", load_profile("sim-plate")))
    {'device': 'null', 'rate_hz': 96000, 'blocks': 0, 'late_blocks': 0, 'errors': []}
    >>> device_status(None)["errors"]
    ["status: AttributeError: 'NoneType' object has no attribute 'status'"]
    """
    try:
        status = device.status()
        if stage is not None:
            status.update(stage.limiter.status())
            status["limiter"] = stage.limiter.summary()
        counts = getattr(device, "fault_counts", None)
        if counts is not None:
            status["fault_counts"] = counts()
        loop = getattr(stage, "loop", None)
        if loop is not None:
            status.update(loop.status())
        return status
    except Exception as error:  # noqa: BLE001 - a status that fails to build must not stop the engine
        return {"errors": [f"status: {type(error).__name__}: {error}"]}


def renderer_status(renderer) -> dict:
    """What the renderer renders with: texture, model, the default force (N); the temporal effects started.

    Parameters
    ----------
    renderer : Renderer

    Returns
    -------
    dict
        ``texture``, ``model`` (names), ``force_n`` (N), ``effects_started`` (a count).

    Examples
    --------
    >>> from ultraglide import Renderer
    >>> renderer_status(Renderer("grating-1mm"))
    {'texture': 'grating-1mm', 'model': 'dynamic', 'force_n': 0.5, 'effects_started': 0}
    """
    player = renderer.effects
    return {"texture": renderer.texture.name, "model": getattr(renderer.model, "name", str(renderer.model)),
            "force_n": renderer.default_force_n, "effects_started": 0 if player is None else player.started}


def close_device(device) -> str | None:
    """Stop the device; what went wrong that a person can act on, or None.

    E.g. a recording that did not fit on the disk. Resting the hardware is best effort on the way out:
    nothing here raises.

    Parameters
    ----------
    device : Device or None
        The device to stop (None: nothing opened).

    Returns
    -------
    str or None
        One line saying what failed, or None.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> close_device(open_device("null", load_profile("sim-plate"))) is None, close_device(None) is None
    (True, True)
    >>> close_device(object())
    "the device failed while stopping: AttributeError: 'object' object has no attribute 'stop'"
    """
    if device is None:
        return None
    try:
        device.stop()
    except USER_ERRORS as error:
        return describe(error)
    except Exception as error:  # noqa: BLE001 - reported, never raised past the hardware's rest
        return f"the device failed while stopping: {type(error).__name__}: {error}"
    return None


def serve(config, conn, shared, renderer, source, device, stop_requested, threads: str) -> None:
    """The engine's command loop, until a stop: rare commands, the device's status ten times a second, idle collection.

    The CPUs are kept quick to wake while the block path renders (released while it serves zeros at rest).
    Commands come from the app's pipe as tuples: ``("texture", spec)``, ``("model", spec)``, ``("force", N)``,
    ``("pause", bool)``, ``("trigger", name, value)``, ``("effects", json or None)``, ``("stop",)``; each is
    answered ``("ok", value)`` or ``("error", one line)``. A stop (the command, ``stop_requested``, or the
    pipe closed) ends in :func:`finish`.

    Parameters
    ----------
    config : EngineConfig
        The engine's configuration (its CPU wake-up latency, µs, and whether it runs in real time).
    conn : multiprocessing.connection.Connection
        The engine's end of the app's pipe.
    shared : SharedBlock
        The shared memory the status is published in.
    renderer : Renderer
        The renderer the commands change.
    source : EngineSource
        The block path the device pulls.
    device : Device
        The device playing.
    stop_requested : threading.Event
        Set by the stop signals' handlers.
    threads : str
        The other threads' scheduling, in words, for the status.

    Returns
    -------
    None

    Examples
    --------
    A force command answered, then a stop, on the null device (not started: the loop serves the pipe alone):

    >>> import multiprocessing, threading
    >>> from ultraglide import Renderer
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> from ultraglide.render.engine import EngineConfig
    >>> from ultraglide.render.engine.process import EngineSource
    >>> from ultraglide.render.engine.shm import SharedBlock
    >>> shared, renderer = SharedBlock.create(), Renderer("grating-1mm")
    >>> device = open_device("null", load_profile("sim-plate"))
    >>> source = EngineSource(renderer, shared, device, False)
    >>> app, engine = multiprocessing.Pipe()
    >>> app.send(("force", 0.8)); app.send(("stop",))
    >>> serve(EngineConfig(realtime_priority=False), engine, shared, renderer, source, device, threading.Event(),
    ...       "other threads: normal")
    >>> app.recv(), app.recv()[0], renderer.default_force_n
    (('ok', None), 'stopped', 0.8)
    >>> shared.close()
    """
    wake = CpuWakeLatency(config.cpu_wake_latency_us if config.realtime_priority else None)
    try:
        _serve_commands(config, conn, shared, renderer, source, device, stop_requested, threads, wake)
    finally:
        wake.close()


def _serve_commands(config, conn, shared, renderer, source, device, stop_requested, threads: str, wake) -> None:
    errors = USER_ERRORS
    next_status = 0.0
    next_collect = time.monotonic() + 1.0
    while True:
        now = time.monotonic()
        wake.hold(not source._first and not source._resting)  # rendering (not before the first block, nor at rest)
        if now >= next_status:
            shared.write_slow({**device_status(device, source), **renderer_status(renderer),
                               "priority": f"{source.priority}; {threads}; {wake.words()}", "pid": os.getpid()})
            next_status = now + STATUS_PERIOD_S
        if now >= next_collect:
            gc.collect(0)  # young objects only: short; the block thread waits at most the switch interval
            next_collect = now + 1.0
        if stop_requested.is_set():
            finish(shared, source, device, None, wake)
            return
        try:
            if not conn.poll(STATUS_PERIOD_S / 2):
                continue
            command, *args = conn.recv()
        except (EOFError, OSError):  # the parent is gone: rest the plate and leave
            finish(shared, source, device, None, wake)
            return
        if command == "stop":
            finish(shared, source, device, conn, wake)
            return
        try:
            if command == "texture":
                renderer.set_texture(texture_of(args[0]))
            elif command == "model":
                from ultraglide.render.physics.calibration import load_model

                model = load_model(args[0])
                if source.loop is not None:
                    source.loop.set_model(model)
                else:
                    renderer.set_model(model)
            elif command == "force":
                renderer.set_default_force(float(args[0]))
            elif command == "pause":
                renderer.pause(bool(args[0]))
            elif command == "trigger":
                conn.send(("ok", renderer.trigger(str(args[0]), float(args[1]))))
                continue
            elif command == "effects":
                from ultraglide.textures.effects import from_json

                renderer.set_effects(None if args[0] is None else from_json(args[0]))
            else:
                raise ValueError(f"unknown engine command {command!r}")
            conn.send(("ok", None))
        except errors as error:
            conn.send(("error", describe(error)))


def finish(shared, source, device, conn, wake) -> None:
    """Ramp to rest, rest the hardware, publish the last status; tell the parent if it is there.

    Parameters
    ----------
    shared : SharedBlock
        The shared memory: the last status, and the state ``stopped``.
    source : EngineSource
        The block path (told it is stopping; its records closed).
    device : Device or None
        The device, stopped (:func:`close_device`).
    conn : multiprocessing.connection.Connection or None
        The engine's end of the app's pipe: ``("stopped", status)`` is sent on it (None: the parent is gone).
    wake : CpuWakeLatency
        The CPU wake-up request, withdrawn.

    Returns
    -------
    None

    Examples
    --------
    >>> import multiprocessing
    >>> from ultraglide import Renderer
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> from ultraglide.render.engine import shm
    >>> from ultraglide.render.engine.process import EngineSource
    >>> shared = shm.SharedBlock.create()
    >>> device = open_device("null", load_profile("sim-plate"))
    >>> source = EngineSource(Renderer("grating-1mm"), shared, device, False)
    >>> app, engine = multiprocessing.Pipe()
    >>> finish(shared, source, device, engine, CpuWakeLatency(None))
    >>> shm.STATES[int(shared.fast[shm.STATE])], app.recv()[0], shared.read_slow()["texture"]
    ('stopped', 'stopped', 'grating-1mm')
    >>> shared.close()
    """
    source._stopping = True
    failure = close_device(device)
    for record in (source.record, source.sensor_record):
        if record is None:
            continue
        record_failure = record.close()
        failure = failure or record_failure
        if record.dropped and not failure:
            failure = f"{record.path}: {record.dropped} rows were lost (the writer fell behind); the rest was written"
    wake.close()
    status = {**device_status(device, source), **renderer_status(source.renderer),
              "priority": f"{source.priority}; {source.threads}; {wake.words()}", "pid": os.getpid()}
    if failure:
        status["output_error"] = failure
    shared.write_slow(status)
    fast = shared.fast
    fast[shm.SEQ] += 1
    fast[shm.STATE] = shm.STATES.index("stopped")
    fast[shm.SEQ] += 1
    if conn is not None:
        try:
            conn.send(("stopped", status))
        except (OSError, EOFError):
            pass
