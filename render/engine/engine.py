"""The real-time engine in its own process: touches in, status out, the device kept fed whatever the UI does.

The renderer and the device run in a process of their own (:mod:`render.engine.process`; forked from an app
with one thread, else spawned), so drawing, event handling and garbage in the UI never hold the GIL the
block path needs. Two doors:

* **in**: :meth:`Engine.touch` writes a touch report into a shared-memory ring (never waits);
  rare commands (texture, model, force, pause, stop) go over a pipe;
* **out**: :meth:`Engine.status` reads a seqlock'd snapshot from shared memory: counters, block
  times, the recent history for a live chart, and the device's own status.

Example (what an app needs; the demo draws ``status.history`` and prints ``status.words()``)::

    from ultraglide.render.engine import Engine, EngineConfig
    with Engine.start(EngineConfig(texture="grating-1mm", device="null")) as engine:
        engine.wait_ready(30)
        engine.touch(time.perf_counter(), 10.0, 25.0)        # mm; force from the config
        status = engine.status()
        status.history.time_s, status.history.commanded_um_pp   # the live chart
        print(status.words())          # "null running | 1234 blocks, 0 late, 0 underruns | ..."
        engine.set_texture("bumps"); engine.pause(True); engine.set_force(0.4)
    # leaving the block stops it: ramps to rest, rests the hardware, joins the process

Time is ``time.perf_counter`` seconds in both processes (one monotonic clock on Linux).
If the parent dies, the engine sees its pipe close, ramps to rest, rests the hardware and exits.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from ultraglide.render.engine import shm
from ultraglide.render.engine.process import engine_main, forked_engine_main
from ultraglide.render.engine.realtime import keep_huge_pages_out
from ultraglide.render.engine.shm import SharedBlock, ring_order
from ultraglide.render.engine.status import EngineStatus, status_from_shared
from ultraglide.render.engine.supervisor import FROZEN_AFTER_S, Supervisor
from ultraglide.render.errors import RenderError
from ultraglide.render.physics.default_model import DEFAULT_MODEL

if TYPE_CHECKING:
    from ultraglide.textures.texture import Texture

START_TIMEOUT_S = 120.0  # spawning, importing numpy/scipy/numba and loading a texture on a loaded machine
COMMAND_TIMEOUT_S = 30.0


class EngineError(RenderError):
    """The engine could not start, or refused a command; the message is one line for a person.

    A :class:`RenderError`; :class:`EngineLost`, its subclass, says the engine died or froze while it drove the
    device.

    Examples
    --------
    >>> from ultraglide.errors import UltraglideError
    >>> issubclass(EngineError, RenderError), issubclass(EngineLost, EngineError), issubclass(EngineError,
    ...                                                                                     UltraglideError)
    (True, True, True)
    """


class EngineLost(EngineError):
    """The engine's process died or froze while it drove the device; the app made the device safe
    (:mod:`render.engine.supervisor`). The message says what happened in one line; ``loss`` has it all;
    ``exit_status`` is the run's (7).

    Parameters
    ----------
    loss : EngineLoss
        What happened and what was done (:class:`~ultraglide.render.engine.supervisor.EngineLoss`).

    Examples
    --------
    >>> from ultraglide.render.engine.supervisor import EngineLoss
    >>> loss = EngineLoss("died", "its process was killed by SIGKILL", 10.0, 0.05, ("the plate disabled",), 10.03)
    >>> error = EngineLost(loss)
    >>> error.exit_status, error.loss.kind
    (7, 'died')
    >>> str(error)
    'the engine was lost: its process was killed by SIGKILL; noticed 50 ms after its last sign of life; made safe by
    ultraglide 30 ms after: the plate disabled'
    """

    def __init__(self, loss):
        super().__init__(loss.words())
        self.loss = loss
        self.exit_status = loss.exit_status


@dataclass(frozen=True)
class EngineConfig:
    """What the engine renders and where. Plain picklable values only (they cross to the engine process).

    ``texture``: a library name or a file, or a ``Texture`` composed in memory (pickled across);
    ``model``: a model name or file; ``profile``: a plate profile;
    ``device``: a device URL (sim, serial:PORT, audio[...], wav:PATH, null). ``rate_hz`` is the audio rate
    of the wav and null sinks (an audio device picks its own). ``probe_plate`` watches the simulated
    plate's amplitude (``sim`` only; for latency measurement). ``realtime_priority`` runs the block thread
    in real time where the OS allows and keeps the kernel's huge-page work away from the engine and from
    the process that starts it, and, while the block path renders, asks idle CPUs to wake within
    ``cpu_wake_latency_us`` (:mod:`render.engine.realtime`; None makes no such request). ``closed_loop`` makes the
    friction the plate's force sensors measure follow the texture (a plate driver with normal and lateral force
    sensors; its amplitude loop too, where it has one), and ``finger`` puts a simulated finger on the ``sim``
    device (:mod:`render.engine.finger_setup`; with ``closed_loop`` on ``sim`` the default one if none is given;
    the default finger lags, unless asked otherwise, only where ``model`` has friction dynamics).

    Parameters
    ----------
    texture : str or Texture
        A library name or a file, or a texture in memory.
    model : str
        A friction model's name or file.
    profile : str
        A plate profile's name or file.
    device : str
        A device URL.
    default_force_n : float
        The force (N) assumed when touches carry none.
    carrier_hz : float, optional
        The carrier (Hz); the plate's resonance by default.
    rate_hz : int
        The wav and null sinks' audio rate (Hz).
    control_rate_hz : float
        The envelope's rate (Hz).
    lookahead_s : float
        How far ahead (s) a live finger is predicted.
    precompensate : bool
        Pre-compensate the plate's slow response.
    predictor : str
        How a live finger's path is predicted.
    start_paused : bool
        Start at rest until resumed.
    realtime_priority : bool
        Real-time scheduling for the block thread where the OS allows.
    probe_plate : bool
        Watch the simulated plate's amplitude (``sim``; for latency).
    cpu_wake_latency_us : int, optional
        The bound (µs) asked of idle CPUs while rendering; None: no request.
    track_resonance : bool
        A plate driver follows its plate's drifting resonance.
    closed_loop : bool
        The friction measured by the plate follows the texture.
    finger : FingerConfig, optional
        A simulated finger on ``sim``.
    envelope_csv, sensors_csv : str, optional
        Record the envelope, or the plate's sensor samples, as they come.
    frozen_after_s : float
        How long (s) the engine may be silent before it is taken for frozen.

    Examples
    --------
    >>> config = EngineConfig(texture="wood", device="null")
    >>> config.model, config.profile, config.rate_hz                      # the defaults: dynamic, sim-plate, Hz
    ('dynamic', 'sim-plate', 96000)
    """

    texture: object = "grating-1mm"  # str or textures.texture.Texture
    model: str = DEFAULT_MODEL
    profile: str = "sim-plate"
    device: str = "sim"
    default_force_n: float = 0.5
    carrier_hz: float | None = None
    rate_hz: int = 96000
    control_rate_hz: float = 12000.0
    lookahead_s: float = 0.0
    precompensate: bool = True
    plan: bool = True  # with a model that has friction dynamics: plan the friction felt (render/planning.py)
    predictor: str = "lsq"
    start_paused: bool = False
    realtime_priority: bool = True
    probe_plate: bool = False
    cpu_wake_latency_us: int | None = 0  # asked of idle CPUs while rendering (with realtime_priority); None: not
    track_resonance: bool = False  # a plate driver follows its plate's drifting resonance (characterisation)
    closed_loop: bool = False  # friction measured by the plate follows the texture (render/engine/friction_loop.py)
    finger: object = None  # finger_setup.FingerConfig: a simulated finger on the in-process sim (None: none, or the
    # default one when closed_loop asks for sensors)
    envelope_csv: str | None = None  # record the envelope as it plays (render/engine/envelope_record.py)
    sensors_csv: str | None = None  # record the plate's sensor samples as they come (render/engine/sensor_record.py)
    frozen_after_s: float = FROZEN_AFTER_S  # the app's supervisor takes an engine silent this long for frozen (a device
    # pulling blocks less often, an audio stream with blocks over 0.1 s, needs more; render/engine/supervisor.py)


class Engine:
    """A running engine process; see the module docstring. Use from one thread of the app.

    Made by :meth:`start` (or :meth:`launch`), not by calling the class. Touches go in through :meth:`touch`, rare
    commands through :meth:`set_texture`, :meth:`set_force`, :meth:`pause`; :meth:`status` reads what it does.
    Leaving a ``with`` block (or :meth:`stop`) ramps to rest, rests the hardware and ends the process; an app
    supervisor watches the process meanwhile and makes the device safe if it dies or freezes (:attr:`loss`).

    Attributes
    ----------
    config : EngineConfig
        What it renders and where.
    started_s : float
        When its process was up (``time.perf_counter`` s).
    final_status : EngineStatus or None
        The last status, once stopped.

    Raises
    ------
    EngineError
        From :meth:`start` and the commands: a bad texture, model, profile or device, or an engine that does not
        answer; in one line.
    EngineLost
        The engine's process died or froze while it drove the device (the device was made safe).

    Examples
    --------
    >>> import time
    >>> config = EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)
    >>> with Engine.start(config) as engine:
    ...     engine.wait_ready(60.0)
    ...     engine.touch(time.perf_counter(), 10.0, 25.0)      # perf_counter s, x and y in mm
    ...     engine.status().state
    True
    'running'
    >>> engine.final_status.state
    'stopped'
    """

    def __init__(self, process, conn, shared: SharedBlock, config: EngineConfig, info: dict):
        self.process = process
        self.conn = conn
        self.shared = shared
        self.config = config
        self.info = info
        self.ready_info: dict | None = None
        self.final_status: EngineStatus | None = None
        self.started_s = time.perf_counter()  # when its process was up (perf_counter s): the run's times count from it
        self._failure: str | None = None
        self._stopped = False
        # the app's watch over the process and its heartbeats (render/engine/supervisor.py)
        self.supervisor = Supervisor(process, shared, config.device, (config.envelope_csv, config.sensors_csv),
                                     config.frozen_after_s, realtime=config.realtime_priority).start()

    # ---- life --------------------------------------------------------------------------------------
    @classmethod
    def start(cls, config: EngineConfig, timeout_s: float = START_TIMEOUT_S) -> Engine:
        """Spawn the engine; returns once its inputs are loaded and its device is open.
        Raises :class:`EngineError` (one line) if the texture, model, profile or device is bad.
        With ``config.realtime_priority`` the calling process (the UI beside the engine) gets transparent
        huge pages turned off too: khugepaged collapsing its memory holds a CPU the block thread needs.

        Parameters
        ----------
        config : EngineConfig
            What to render and where.
        timeout_s : float
            How long (s) to wait for it to load its inputs and open its device.

        Returns
        -------
        Engine

        Raises
        ------
        EngineError
            A bad texture, model, profile or device, or no answer within ``timeout_s``, in one line.

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.wait_ready(60.0)
        ...     engine.set_force(0.4)                                           # N
        ...     engine.set_texture("checkerboard-5mm")
        ...     engine.pause(True)
        >>> final = engine.final_status                                   # what stop() returned
        >>> final.state, final.force_n, final.texture
        ('stopped', 0.4, 'checkerboard-5mm')
        """
        return cls.launch(config).wait(timeout_s)

    @classmethod
    def launch(cls, config: EngineConfig) -> EngineLaunch:
        """Start the engine's process and return at once, while it loads its inputs and opens its device;
        :meth:`EngineLaunch.wait` then gives the engine (what :meth:`start` does in one call). An app that waits
        on a thread of its own launches here first, on its one thread, so that the engine is forked (with what the
        app has imported) rather than spawned.

        Returns
        -------
        EngineLaunch

        Examples
        --------
        >>> config = EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)
        >>> launch = Engine.launch(config)                    # returns at once; the engine loads meanwhile
        >>> with launch.wait(60.0) as engine:
        ...     engine.config is config
        True
        """
        if config.realtime_priority:
            keep_huge_pages_out()
        forked = _fork_is_safe()
        context = multiprocessing.get_context("fork" if forked else "spawn")
        # stop signals held from the segment's making to the process's start: a segment half made (named to the
        # resource tracker, not yet made) would be called leaked, and a spawn cut halfway by Ctrl-C would leave
        # the child a traceback of its own
        held = _hold_stop_signals()
        shared = None
        try:
            shared = SharedBlock.create()
            parent, child = context.Pipe()
            target, args = (forked_engine_main, (config, shared.name, child, parent)) if forked else \
                (engine_main, (config, shared.name, child))
            process = context.Process(target=target, args=args, daemon=True, name="ultraglide-engine")
            with _main_module_hidden(), _heap_frozen(forked):
                process.start()
        except BaseException:
            if shared is not None:
                shared.close()
            _release_stop_signals(held)
            raise
        launched = EngineLaunch(process, parent, shared, config)
        try:
            _release_stop_signals(held)  # a stop signal that came during the start arrives here
            child.close()
        except BaseException:
            launched.abandon()
            raise
        return launched

    def wait_ready(self, timeout_s: float = START_TIMEOUT_S) -> None:
        """Wait until the kernels are compiled and the device runs (it has taken its first block, so the
        status says running or paused); EngineError if it failed or did not within ``timeout_s``.

        Parameters
        ----------
        timeout_s : float
            How long to wait (s).

        Raises
        ------
        EngineError
            It failed, or was not running within ``timeout_s``.

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.wait_ready(60.0)
        ...     engine.status().state in ("running", "paused")
        True
        """
        deadline = time.monotonic() + timeout_s
        if self.ready_info is None:
            if self._failure is not None:
                raise EngineError(self._failure)
            with self._lost_if_gone():
                kind, payload = _receive(self.conn, self.process, timeout_s)
            self._take(kind, payload)
            if self._failure is not None:
                raise EngineError(self._failure)
        while self.shared.words is not None and shm.STATES[int(self.shared.fast[shm.STATE])] == "starting":
            if not self.process.is_alive():
                with self._lost_if_gone():
                    raise EngineError(f"the engine process ended unexpectedly (exit code {self.process.exitcode})")
            if time.monotonic() > deadline:
                raise EngineError(f"the device {self.config.device} took no block within {timeout_s:g} s")
            time.sleep(0.002)

    @property
    def loss(self):
        """None while the engine is well; once its process died or froze (and the device was made safe), the
        :class:`~render.engine.supervisor.EngineLoss`: what happened, in words (``loss.lines(engine.started_s)``).

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.wait_ready(60.0)
        ...     engine.loss is None
        True
        """
        return self.supervisor.loss if self.supervisor.lost.is_set() else None

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds``, or raise :class:`EngineLost` as soon as the engine is lost (within 100 ms of its death,
        250 ms of its freeze, the device already safe).

        Parameters
        ----------
        seconds : float
            How long to wait (s).

        Raises
        ------
        EngineLost
            The engine died or froze meanwhile.

        Examples
        --------
        >>> import time
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     before = time.monotonic()
        ...     engine.sleep(0.05)
        ...     time.monotonic() - before >= 0.05
        True
        """
        if self.supervisor.wait(max(0.0, seconds)):
            raise EngineLost(self.supervisor.loss)

    @contextlib.contextmanager
    def _lost_if_gone(self):
        """An EngineError because the process ended becomes :class:`EngineLost` once the supervisor has made the
        device safe; any other stays as it is."""
        try:
            yield
        except EngineError:
            if self.process.is_alive():
                raise
            loss = self.supervisor.close()
            if loss is None:
                raise
            raise EngineLost(loss) from None

    @property
    def ready(self) -> bool:
        """True once the engine's process has its renderer and device up (it said so); never blocks.

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.wait_ready(60.0)
        ...     engine.ready
        True
        """
        if self.ready_info is None and self._failure is None and self.conn.poll(0):
            with contextlib.suppress(EngineError):
                self._take(*_receive(self.conn, self.process, 0.0))
        return self.ready_info is not None

    def _take(self, kind: str, payload) -> None:
        if kind == "ready":
            self.ready_info = payload
        elif kind == "failed":
            self._failure = payload
        else:
            raise EngineError(f"the engine answered {kind!r} out of turn")

    def stop(self, timeout_s: float = COMMAND_TIMEOUT_S) -> EngineStatus | None:
        """Ramp to rest, rest the hardware, end the process; returns the last status. Idempotent.
        Raises :class:`EngineError` afterwards if the device's output failed (e.g. a WAV recording that
        did not fit on the disk: nothing was saved).

        Parameters
        ----------
        timeout_s : float
            How long (s) to wait for each step.

        Returns
        -------
        EngineStatus or None
            The last status.

        Raises
        ------
        EngineError
            The device's output failed (nothing was saved).

        Examples
        --------
        >>> engine = Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False))
        >>> final = engine.stop()
        >>> final.state, engine.stop() is final, engine.alive          # a second stop gives the same status
        ('stopped', True, False)
        """
        if self._stopped:
            return self.final_status
        self._stopped = True
        atexit.unregister(self.stop)
        output_error = None
        supervisor = self.supervisor
        try:
            answered = False
            if self.process.is_alive():
                with contextlib.suppress(OSError, EOFError, EngineError):
                    if self.ready_info is None and self._failure is None:
                        self.wait_ready(timeout_s)
                    self.conn.send(("stop",))
                    while True:
                        kind, payload = _receive(self.conn, self.process, timeout_s)
                        if kind == "stopped":
                            output_error = (payload or {}).get("output_error")
                            answered = True
                            break
            if not answered and self.process.is_alive() and self._failure is None:
                supervisor.kill(f"it did not stop within {timeout_s:g} s of being asked")  # made safe from here
            supervisor.close()  # a process that ended without stopping: the device made safe, the loss kept
            self.final_status = self._last_status()
        finally:
            supervisor.close()
            _reap(self.process, timeout_s)
            self.conn.close()
            self.shared.close()
        if output_error:  # the hardware is at rest and the process has ended; the output itself failed
            raise EngineError(output_error)
        return self.final_status

    def __enter__(self) -> Engine:
        return self

    def __repr__(self) -> str:
        """``Engine<sim, running, 1234 blocks>``: its device, state and blocks rendered so far."""
        try:
            status = self.final_status or self.status(history_s=0.0)
        except (OSError, ValueError, TypeError):  # its shared memory already closed
            return f"Engine<{self.config.device}, stopped>"
        return f"Engine<{self.config.device}, {status.state}, {status.blocks} blocks>"

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def alive(self) -> bool:
        """Whether the engine's process is running.

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.alive
        True
        >>> engine.alive                                     # the process has ended with the block
        False
        """
        return self.process.is_alive()

    # ---- in ----------------------------------------------------------------------------------------
    def touch(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None = None, down: bool = True) -> bool:
        """A touch report (perf_counter s, mm, N or None for the default). Never waits; False if the
        ring was full (the engine has stalled) and the report was dropped, or the engine was lost (:attr:`loss`).

        Parameters
        ----------
        t_s : float
            When (``time.perf_counter`` s).
        x_mm, y_mm : float
            Where (mm on the texture).
        force_n : float, optional
            The normal force (N); the default force when None.
        down : bool
            Whether the finger touches.

        Returns
        -------
        bool
            False if the report was dropped.

        Examples
        --------
        One report, seen by the engine's block path (its count in the status):

        >>> import time
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.touch(time.perf_counter(), 10.0, 25.0)
        ...     deadline = time.monotonic() + 30.0
        ...     while engine.status().touches < 1 and time.monotonic() < deadline:
        ...         engine.sleep(0.01)
        True
        >>> engine.final_status.touches, engine.final_status.last_touch[:2]
        (1, (10.0, 25.0))
        """
        if self.supervisor.loss is not None:
            return False
        return self.shared.push_touch(t_s, x_mm, y_mm, math.nan if force_n is None else force_n, 1.0 if down else 0.0)

    def set_texture(self, spec: str | os.PathLike | Texture) -> None:
        """Render another texture: a library name or a file (EngineError if it cannot be loaded), or a
        ``Texture`` built in memory (sent pickled: a 2000 × 1500 texture is 12 MB, some 10 ms).

        Parameters
        ----------
        spec : str, os.PathLike or Texture
            A library name, a file, or a texture.

        Raises
        ------
        EngineError
            The engine refused it or did not answer, in one line.
        EngineLost
            The engine died or froze (the device was made safe).

        Examples
        --------
        A texture made in memory (a flat map at ratio 0.8, 20 × 20 mm):

        >>> import numpy as np
        >>> from ultraglide.textures.texture import Texture
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.set_texture(Texture(np.full((2, 2), 0.8), 20.0, 20.0, name="flat"))
        >>> engine.final_status.texture
        'flat'
        """
        self._command("texture", spec if _is_texture(spec) else str(spec))

    def set_model(self, spec: str) -> None:
        """Use another friction model (a name or a file, as ``--model``); EngineError if it cannot be loaded.

        Parameters
        ----------
        spec : str
            A model's name or file.

        Raises
        ------
        EngineError
            The engine refused it or did not answer, in one line.
        EngineLost
            The engine died or froze (the device was made safe).

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.set_model("exponential")
        >>> engine.final_status.model
        'exponential'
        """
        self._command("model", str(spec))

    def set_force(self, force_n: float) -> None:
        """The force assumed when touches carry none, N.

        Parameters
        ----------
        force_n : float
            N.

        Raises
        ------
        EngineError
            The engine refused it or did not answer, in one line.
        EngineLost
            The engine died or froze (the device was made safe).

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.set_force(0.8)
        >>> engine.final_status.force_n
        0.8
        """
        self._command("force", float(force_n))

    def pause(self, flag: bool = True) -> None:
        """Ramp the output to rest while paused, and back when resumed.

        Parameters
        ----------
        flag : bool
            Pause (True) or resume (False).

        Raises
        ------
        EngineError
            The engine refused it or did not answer, in one line.
        EngineLost
            The engine died or froze (the device was made safe).

        Examples
        --------
        >>> import time
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.pause(True)
        ...     deadline = time.monotonic() + 30.0
        ...     while engine.status().state != "paused" and time.monotonic() < deadline:
        ...         engine.sleep(0.01)
        ...     engine.status().state
        'paused'
        """
        self._command("pause", bool(flag))

    def trigger(self, name: str) -> bool:
        """The app's named event now (a widget's value changing): plays the effects bound to ``name``
        (``textures.effects.Trigger(on="event")``). False if no effect is bound to it.

        Parameters
        ----------
        name : str
            The event's name.

        Returns
        -------
        bool
            False if no effect is bound to it.

        Raises
        ------
        EngineError
            The engine refused it or did not answer, in one line.
        EngineLost
            The engine died or froze (the device was made safe).

        Examples
        --------
        A grating holds no effects:

        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.trigger("click")
        False
        """
        return bool(self._command("trigger", str(name), time.perf_counter()))

    def set_effects(self, description: dict | None) -> None:
        """Play these effects (``textures.effects.to_json``'s description) instead of the texture's own;
        None: the texture's own again. EngineError (one line) for a bad description.

        Parameters
        ----------
        description : dict or None
            ``textures.effects.to_json``'s description; None: the texture's own.

        Raises
        ------
        EngineError
            The engine refused it or did not answer, in one line.
        EngineLost
            The engine died or froze (the device was made safe).

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.set_effects(None)                          # the texture's own (none)
        ...     engine.set_effects({"effects": []})
        Traceback (most recent call last):
        ...
        ultraglide.render.engine.engine.EngineError: effects: effects version None is not one this ultraglide reads ...
        """
        self._command("effects", description)

    def _command(self, *message):
        if self._stopped:
            raise EngineError("the engine has stopped")
        if self.loss is not None:
            raise EngineLost(self.loss)
        with self._lost_if_gone():
            try:
                self.conn.send(message)
            except OSError as error:  # its end of the pipe closed: the process is ending
                raise EngineError(f"the engine process ended unexpectedly ({error.strerror})") from None
        while True:
            with self._lost_if_gone():
                kind, payload = _receive(self.conn, self.process, COMMAND_TIMEOUT_S)
            if kind == "ok":
                return payload
            if kind == "error":
                raise EngineError(payload)
            self._take(kind, payload)  # "ready" may still be on its way

    # ---- out ---------------------------------------------------------------------------------------
    def _last_status(self) -> EngineStatus:
        """The status once the process has ended: read through the seqlock, or, where it died mid-write (an engine
        killed or frozen while writing), as the segment holds it (:meth:`status`'s ``post_mortem``)."""
        try:
            return self.status()
        except (EngineLost, TimeoutError):
            self.process.join(2.0)  # a frozen engine was killed: its end is a moment away
            if self.process.is_alive():
                raise
            return self.status(post_mortem=True)

    def status(self, history_s: float = 5.0, post_mortem: bool = False) -> EngineStatus:
        """A consistent snapshot; ``history_s`` of history rows (at most what the ring holds).

        Parameters
        ----------
        history_s : float
            How much history (s) to include.
        post_mortem : bool
            The process has ended: read the segment as it is, without waiting for a consistent copy.

        Returns
        -------
        EngineStatus

        Examples
        --------
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.wait_ready(60.0)
        ...     status = engine.status()
        >>> status.device, status.texture, status.model, status.force_n        # the config's, and its defaults
        ('null', 'grating-1mm', 'dynamic', 0.5)
        """
        if self.shared.words is None:  # stopped: the last status read before the segment was released
            return self.final_status
        try:
            header, block_times, history_ring, _ = self.shared.read_fast(post_mortem)
            device_status = self.shared.read_slow(post_mortem)
        except TimeoutError:  # an engine stopped mid-write leaves its status half written: wait for the watch's word
            if self.supervisor.wait(1.0):
                raise EngineLost(self.supervisor.loss) from None
            raise
        status = status_from_shared(header, block_times, history_ring, device_status, int(self.shared.touch_index[2]),
                         self.config.device, history_s)
        run_p50, run_p99 = (None if v is None else v * 1e6
                            for v in shm.histogram_percentiles(self.shared.read_histogram(post_mortem), (50, 99)))
        return replace(status, run_block_p50_us=run_p50, run_block_p99_us=run_p99)

    def latencies(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each recent touch: (touch time, time its block was rendered, time that block's first sample
        is presented by the device), perf_counter s, oldest first.

        Returns
        -------
        (numpy.ndarray, numpy.ndarray, numpy.ndarray)
            Touch, render and presentation times (perf_counter s).

        Examples
        --------
        A touch, the block that rendered it (not before it) and when that block's first sample left:

        >>> import time
        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     touched = time.perf_counter()
        ...     engine.touch(touched, 10.0, 25.0)
        ...     deadline = time.monotonic() + 30.0
        ...     while len(engine.latencies()[0]) < 1 and time.monotonic() < deadline:
        ...         engine.sleep(0.01)
        ...     touch_s, rendered_s, presented_s = engine.latencies()
        True
        >>> touch_s.tolist() == [touched], bool(rendered_s[0] >= touched), bool(presented_s[0] >= rendered_s[0])
        (True, True, True)
        """
        header, _, _, latency = self.shared.read_fast()
        rows = ring_order(latency, int(header[shm.LATENCY_INDEX]))
        rows = rows[np.isfinite(rows[:, 1])]
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def plate_probe(self) -> tuple[float, float]:
        """(simulated plate amplitude µm p-p, perf_counter time it last rose above 0.05 µm); probe_plate only.

        Returns
        -------
        (float, float)
            The amplitude (µm p-p) and when (perf_counter s) it last rose above 0.05 µm.

        Examples
        --------
        Without ``probe_plate`` nothing is watched:

        >>> with Engine.start(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)) as engine:
        ...     engine.plate_probe()
        (0.0, 0.0)
        """
        fast = self.shared.fast
        return float(fast[shm.PLATE_PROBE_UM_PP]), float(fast[shm.PROBE_RISE_S])


def _is_texture(spec) -> bool:
    from ultraglide.textures.texture import Texture

    return isinstance(spec, Texture)


@contextlib.contextmanager
def _main_module_hidden():
    """Spawn without re-running the app's main module in the engine (which needs nothing from it), so
    scripts work without an ``if __name__ == "__main__"`` guard and the engine starts sooner."""
    main = sys.modules.get("__main__")
    saved = {name: main.__dict__.pop(name) for name in ("__file__", "__spec__") if main and name in main.__dict__}
    if main is not None:
        main.__spec__ = None
    try:
        yield
    finally:
        if main is not None:
            main.__dict__.pop("__spec__", None)
            main.__dict__.update(saved)


@contextlib.contextmanager
def _heap_frozen(forked: bool):
    """Fork with the app's objects in the collector's permanent generation, then give them back to the app: the
    engine's collections (a full one before it serves) then never walk them, and walking would copy every page
    that holds one into the engine: forked from a process holding a million small objects, an engine took 0.7 s
    of CPU to start and stop, 0.25 s with them frozen. An app that froze objects itself keeps its own
    arrangement (unfreezing would thaw its objects too)."""
    if not forked or gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _receive(conn, process, timeout_s: float):
    """The next message from the engine, or EngineError if it died or stayed silent."""
    deadline = time.monotonic() + timeout_s
    while True:
        if conn.poll(min(0.05, max(0.0, deadline - time.monotonic()))):
            try:
                return conn.recv()
            except (EOFError, OSError):
                raise EngineError(f"the engine process ended unexpectedly (exit code {process.exitcode})") from None
        if not process.is_alive() and not conn.poll(0):
            raise EngineError(f"the engine process ended unexpectedly (exit code {process.exitcode})")
        if time.monotonic() >= deadline:
            raise EngineError(f"the engine did not answer within {timeout_s:g} s")


class EngineLaunch:
    """An engine process started and loading its inputs (:meth:`Engine.launch`); :meth:`wait` gives the
    :class:`Engine` once its device is open, :meth:`abandon` ends it unused. Either, once, from any one thread.

    Examples
    --------
    >>> launch = Engine.launch(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False))
    >>> with launch.wait(60.0) as engine:
    ...     engine.status().device
    'null'
    >>> Engine.launch(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)).abandon()
    """

    def __init__(self, process, parent, shared: SharedBlock, config: EngineConfig):
        self._process = process
        self._parent = parent
        self._shared = shared
        self._config = config

    def wait(self, timeout_s: float = START_TIMEOUT_S) -> Engine:
        """The engine, once its inputs are loaded and its device is open; :class:`EngineError` (one line) if the
        texture, model, profile or device is bad.

        Parameters
        ----------
        timeout_s : float
            How long (s) to wait for the engine to load its inputs and open its device.

        Returns
        -------
        Engine

        Raises
        ------
        EngineError
            A bad texture, model, profile or device, or no answer within ``timeout_s``, in one line.

        Examples
        --------
        >>> launch = Engine.launch(EngineConfig(texture="no-such-texture", device="null", realtime_priority=False))
        >>> launch.wait(60.0)
        Traceback (most recent call last):
        ...
        ultraglide.render.engine.engine.EngineError: ...no-such-texture...
        """
        try:
            kind, payload = _receive(self._parent, self._process, timeout_s)
        except BaseException:  # its error, or a stop signal while it loaded (Ctrl-C, SIGTERM made exceptions)
            died = not self._process.is_alive()
            self.abandon()
            if died:  # it died loading: what it opened is closed, what it wrote is not
                from ultraglide.devices.after_loss import finish_log, rest_after_loss

                rest_after_loss(self._config.device, self._process.pid)
                for log in (self._config.envelope_csv, self._config.sensors_csv):
                    if log:
                        finish_log(log)
            raise
        if kind != "up":
            _reap(self._process)
            self._shared.close()
            raise EngineError(payload)
        engine = Engine(self._process, self._parent, self._shared, self._config, payload)
        atexit.register(engine.stop)  # an app that forgets stop() still rests the plate on its way out
        return engine

    def abandon(self) -> None:
        """End the engine before it serves: one still loading finds nobody to answer, rests its device and ends.

        Examples
        --------
        The engine's process ended, none of this process's children left:

        >>> import multiprocessing
        >>> before = len(multiprocessing.active_children())
        >>> launch = Engine.launch(EngineConfig(texture="grating-1mm", device="null", realtime_priority=False))
        >>> launch.abandon()
        >>> len(multiprocessing.active_children()) == before
        True
        """
        self._parent.close()
        _reap(self._process)
        self._shared.close()  # the segment unlinked: none left for the resource tracker to call leaked


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _fork_is_safe() -> bool:
    """Whether the engine may be forked from this process rather than spawned: on Linux, from a process with no
    thread but its main one (a lock another thread held at the fork would stay held in the engine forever).
    A forked engine starts with what the app has imported and compiled (numpy, numba's kernels: 0.8 s of CPU
    and half a second sooner); ``ULTRAGLIDE_ENGINE_START=spawn`` asks for a fresh interpreter always."""
    return (sys.platform == "linux" and threading.active_count() == 1
            and os.environ.get("ULTRAGLIDE_ENGINE_START", "fork") != "spawn")


def _hold_stop_signals():
    """Hold the stop signals while the engine's segment is made and its process started: their handlers (Ctrl-C's
    KeyboardInterrupt, the app's SIGTERM) only record them until :func:`_release_stop_signals`, which delivers
    them again. A spawn cut halfway leaves the new process its own traceback (``EOFError`` reading what it was
    sent). Handlers run in the main thread only (a signal mask would not do: another thread takes the signal);
    elsewhere, nothing to hold."""
    if threading.current_thread() is not threading.main_thread():
        return None
    received: list[int] = []
    previous = {signum: signal.signal(signum, lambda number, _: received.append(number)) for signum in STOP_SIGNALS}
    return previous, received


def _release_stop_signals(held) -> None:
    if held is None:
        return
    previous, received = held
    for signum, handler in previous.items():
        signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
    for signum in dict.fromkeys(received):
        signal.raise_signal(signum)


def _reap(process, timeout_s: float = 10.0) -> None:
    process.join(timeout_s)
    if process.is_alive():
        process.terminate()  # SIGTERM: the engine rests its hardware on the way out
        process.join(timeout_s)
    if process.is_alive():
        process.kill()
        process.join(1.0)
