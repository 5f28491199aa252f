"""The engine's own process: the renderer and the device, fed through shared memory.

:func:`engine_main` is what :class:`render.engine.Engine` spawns (:func:`forked_engine_main` when it
forks). Its main thread loads the inputs, opens the device, answers rare commands from the pipe and
publishes the device's status; the device's own thread (PortAudio's callback, the serial writer, the
paced sink) pulls blocks from :class:`EngineSource`, whose ``pull`` is the block path: drain the touch
ring into the renderer, render, publish the block's figures. The block path never waits on the UI or on
the command thread.

If the pipe to the parent closes (the parent died) or SIGTERM arrives, the engine ramps to rest,
rests the hardware and exits.
"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import signal
import sys
import threading
import time

import numpy as np
from ultraglide.devices.output.stage import OutputStage
from ultraglide.render.engine import shm
from ultraglide.render.engine.parts import check_sensors, load_parts
from ultraglide.render.engine.realtime import keep_huge_pages_out, raise_other_threads, raise_priority
from ultraglide.render.engine.serving import USER_ERRORS, PlateProbe, close_device, device_status, serve
from ultraglide.render.engine.shm import SharedBlock
from ultraglide.render.engine.sources import EnvelopeSource

from ultraglide.errors import describe

SWITCH_INTERVAL_S = 0.0002  # the GIL changes hands this often, so the block thread waits at most this on the others
RESTING_CAPACITY = 65536  # the longest block served as zeros while at rest (frames)


class EngineSource(OutputStage):
    """The block path: the device's output stage (limiter, carrier for audio) with the touch ring drained
    before each block and the block's figures published after it. Devices take it as their stage.

    Parameters
    ----------
    renderer : Renderer
        What renders the blocks.
    shared : SharedBlock
        The shared memory: touches read from it, each block's figures published to it.
    device : Device
        The device that pulls the blocks (its signal and rate).
    raise_priority_ : bool
        Raise the block thread's priority at its first block.
    profile : PlateProfile, optional
        The plate's, for the limiter (default: the renderer's).

    Examples
    --------
    A touch through the shared memory, then blocks pulled as the null device pulls them (96 kHz audio,
    fractions of full scale):

    >>> import time
    >>> from ultraglide import Renderer
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> shared = SharedBlock.create()
    >>> source = EngineSource(Renderer("grating-1mm"), shared, open_device("null", load_profile("sim-plate")), False)
    >>> shared.push_touch(time.perf_counter(), 10.0, 10.0, float("nan"), 1.0)
    True
    >>> blocks = [source.pull(960, None) for _ in range(20)]
    >>> blocks[-1].dtype, int(shared.fast[shm.BLOCKS]), shm.STATES[int(shared.fast[shm.STATE])]
    (dtype('float32'), 20, 'running')
    >>> 0.0 < float(abs(blocks[-1]).max()) <= 1.0
    True
    >>> shared.close()
    """

    def __init__(self, renderer, shared: SharedBlock, device, raise_priority_: bool = True, profile=None):
        """``profile``: the plate's, for the limiter (default: the renderer's; a renderer that sees the plate
        through its amplitude loop has another view of it)."""
        carrier_hz = getattr(device, "carrier_hz", None) or renderer.carrier_hz
        super().__init__(EnvelopeSource(renderer, realtime_capacity=4096), profile or renderer.profile,
                         device.signal, device.rate_hz, carrier_hz)
        self.renderer = renderer
        self.shared = shared
        self.device = device
        self.priority = "not yet running"
        self.threads = "other threads: normal"
        self._raise = raise_priority_
        self._first = True
        self._stopping = False
        self._resting = False
        dtype = np.float32 if device.signal == "audio" else np.float64
        self._rest = np.zeros(RESTING_CAPACITY, dtype=dtype)
        self._out = np.zeros(RESTING_CAPACITY, dtype=dtype)  # what a rendered block is written into
        self._views: dict[int, np.ndarray] = {}  # of _out, one per block length (a device asks for one or two)
        self.loop = None  # the friction loop (closed loop): told each block's targets, in stream order
        self.record = None  # an EnvelopeRecord: each rendered block's columns, written off the block path
        self.sensor_record = None  # a SensorRecord: the device's SENSORS as they come
        self._no_target = np.full(RESTING_CAPACITY, np.nan)

    def _view(self, n: int) -> np.ndarray:
        view = self._views.get(n)
        if view is None:
            view = self._out[:n]
            if len(self._views) < 64:
                self._views[n] = view
        return view

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
        """The next ``n`` values of the device's signal, with the touches that came drained first and the block's
        figures published to the shared memory after; paused with everything at rest, zeros without running the
        renderer (a device's heartbeat goes on).

        Parameters
        ----------
        n : int
            Values, at the device's rate.
        now_s : float or None
            When the first reaches the plate, perf_counter s.

        Returns
        -------
        numpy.ndarray
            The device's signal (float32 audio in [-1, 1] for the null device).

        Examples
        --------
        No touch: the plate at rest, every block published (its count in the shared memory):

        >>> import time
        >>> from ultraglide import Renderer
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> shared = SharedBlock.create()
        >>> device = open_device("null", load_profile("sim-plate"))
        >>> source = EngineSource(Renderer("grating-1mm"), shared, device, False)
        >>> blocks = [source.pull(960, None) for _ in range(3)]
        >>> float(abs(blocks[-1]).max()), int(shared.fast[shm.BLOCKS])
        (0.0, 3)
        >>> shared.close()
        """
        started = time.perf_counter()
        if self._first:
            self._first = False
            if self._raise:
                self.priority = raise_priority()
        touched = self._drain()
        if not touched and n <= len(self._rest) and self._at_rest():
            # paused with everything at zero: the plate gets zeros (a device's heartbeat goes on) and the
            # renderer is not run; the first touch or resume renders again from here
            if not self._resting:
                self._rest[:] = 0.0  # a device may have written into what it was given
            self._resting = True
            if self.loop is not None:
                self.loop.record(self._no_target[:n], False)
            self.frames += n
            control = n * self.decimation if self.signal == "control" else n // self.upsampling
            self.limiter.samples += control  # time at rest counts
            self._publish(started, time.perf_counter(), now_s, 0, 0)
            return self._rest[:n]
        renderer = self.renderer
        if self._resting:
            self._resting = False
            renderer._next_time = None  # its clock starts again at this block, not counted as late
        clipped_before = renderer.counters.clipped_samples
        # the device copies or sends the block before it pulls the next: the same buffer serves every block
        out = super().pull(n, now_s, self._view(n) if n <= len(self._out) else None)
        if self.loop is not None:
            self._tell_loop(n)
        if self.record is not None:
            self._record(n, out)
        done = time.perf_counter()
        self._publish(started, done, now_s, touched, renderer.counters.clipped_samples - clipped_before)
        return out

    @property
    def force_reference(self) -> tuple[float, float] | None:
        """The friction loop's (force N, force exponent) for the block just pulled (None: open loop), for a device
        that corrects the force as values play (SETPOINTS_FORCE).

        Returns
        -------
        (float, float) or None
            The force (N) and the force exponent; None in open loop.

        Examples
        --------
        >>> import time
        >>> from ultraglide import Renderer
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> shared = SharedBlock.create()
        >>> device = open_device("null", load_profile("sim-plate"))
        >>> source = EngineSource(Renderer("grating-1mm"), shared, device, False)
        >>> print(source.force_reference)                               # no friction loop
        None
        >>> shared.close()
        """
        return self.loop.inverse.force_reference if self.loop is not None else None

    def skip(self, n: int) -> None:
        """Values the device's writer skipped (see ``OutputStage.skip``): no target for them.

        Parameters
        ----------
        n : int
            Values skipped.

        Examples
        --------
        >>> import time
        >>> from ultraglide import Renderer
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> shared = SharedBlock.create()
        >>> device = open_device("null", load_profile("sim-plate"))
        >>> source = EngineSource(Renderer("grating-1mm"), shared, device, False)
        >>> _ = source.pull(960, None)
        >>> source.skip(96)
        >>> source.frames
        1056
        >>> shared.close()
        """
        super().skip(n)
        if self.loop is not None:
            self.loop.skip(n)

    def _record(self, n: int, out: np.ndarray) -> None:
        block = self.renderer.last_block
        k = self.decimation if self.signal == "control" else 1
        if block is None or len(block.time_s) != n * k:
            return
        sent = out if self.signal == "control" else block.drive_um_pp  # an audio stage's output is the carrier
        if k == 1:
            self.record.add(block.time_s, self.frames - n, block.x_mm, block.y_mm, block.down, block.ratio,
                            block.target_um_pp, sent, block.planned_ratio)
            return
        # a device value per row (each the mean of k control samples): its first sample's time, place and press
        down = block.down if np.ndim(block.down) == 0 else block.down[::k]
        self.record.add(block.time_s[::k], self.frames - n, block.x_mm[::k], block.y_mm[::k], down,
                        block.ratio.reshape(n, k).mean(axis=1), block.target_um_pp.reshape(n, k).mean(axis=1), sent,
                        None if block.planned_ratio is None else block.planned_ratio.reshape(n, k).mean(axis=1))

    def _tell_loop(self, n: int) -> None:
        """The block's targets (in the order the device streams them) and the finger's speed on the panel."""
        block = self.renderer.last_block
        loop = self.loop
        k = self.decimation if self.signal == "control" else 1  # control samples a device value stands for
        if block is None or len(block.ratio) != n * k:  # a block served otherwise (a stop's tail): no targets
            loop.record(self._no_target[:n], False)
            return
        loop.record_control(block.ratio, block.down, k, block.planned_ratio)
        x, y = block.x_mm, block.y_mm
        m = n * k
        if m > 1:  # from the block's first sample to its last
            distance = math.hypot(float(x[m - 1] - x[0]), float(y[m - 1] - y[0]))
            loop.panel_speed_mm_s = distance * self.renderer.settings.control_rate_hz / (m - 1)

    def _at_rest(self) -> bool:
        """Paused, and the renderer, the stage and the limiter's model of the plate all at zero."""
        renderer = self.renderer
        block = renderer.last_block
        return (renderer.paused and not self._stopping and block is not None and renderer.envelope.at_rest
                and block.drive_um_pp[-1] < 1e-6 and self._last_drive < 1e-6
                and self.limiter.fast_plate_um_pp < 1e-6
                and (len(self._pending) == 0 or float(self._pending.max()) < 1e-6))

    def _drain(self) -> float:
        """Push the touches that arrived since the last block; returns how many."""
        index = self.shared.touch_index
        head = int(index[0])
        tail = int(index[1])
        if head == tail:
            return 0
        touches = self.shared.touches
        latency = self.shared.latency
        fast = self.shared.fast
        row = int(fast[shm.LATENCY_INDEX])
        for k in range(tail, head):
            t, x, y, force, down = touches[k % shm.TOUCH_SLOTS].tolist()  # plain floats: a tenth of the unpacking
            self.renderer.push(t, x, y, None if math.isnan(force) else force, down > 0.5)
            fast[shm.LAST_TOUCH_X] = x
            fast[shm.LAST_TOUCH_Y] = y
            fast[shm.LAST_TOUCH_FORCE] = force
            fast[shm.LAST_TOUCH_DOWN] = down
            latency[row % shm.LATENCY_ROWS, 0] = t
            latency[row % shm.LATENCY_ROWS, 1] = math.nan  # filled in when the block is rendered
            row += 1
        index[1] = head
        self._latency_from = int(fast[shm.LATENCY_INDEX])
        self._latency_to = row
        return head - tail

    def _publish(self, started: float, done: float, now_s: float | None, touched: int, clipped: int) -> None:
        fast = self.shared.fast
        renderer = self.renderer
        counters = renderer.counters
        block = renderer.last_block
        fast[shm.HEARTBEAT_S] = done  # (its time first: a count seen advanced has its time written)
        fast[shm.HEARTBEAT] += 1  # the supervisor's sign that the block path runs (outside the seqlock: one word)
        fast[shm.SEQ] += 1  # odd: being written
        blocks = int(fast[shm.BLOCKS])
        fast[shm.BLOCKS] = blocks + 1
        fast[shm.LATE_BLOCKS] = counters.late_blocks
        fast[shm.CONTROL_SAMPLES] = counters.control_samples
        fast[shm.CLIPPED] = counters.clipped_samples
        fast[shm.DRIVE_CLIPPED] = counters.drive_clipped_samples
        fast[shm.RAMPS] = counters.ramps
        fast[shm.LAST_BLOCK_S] = done
        fast[shm.STATE] = 3 if self._stopping else (2 if renderer.paused else 1)
        if self._resting:  # served as zeros, not rendered: counted apart, out of the block times
            fast[shm.RESTING_BLOCKS] += 1
        else:
            timed = int(fast[shm.BLOCK_TIME_INDEX])
            self.shared.block_times[timed % shm.BLOCK_TIMES] = done - started
            self.shared.histogram[shm.histogram_bin(done - started)] += 1
            fast[shm.BLOCK_TIME_INDEX] = timed + 1
        if block is not None:
            row = self.shared.history[int(fast[shm.HISTORY_INDEX]) % shm.HISTORY_ROWS]
            resting = self._resting
            row[0] = (done if resting else block.time_s[0]) if now_s is None else now_s
            row[1] = block.ratio[-1]
            row[2] = 0.0 if resting else block.amplitude_um_pp[-1]
            telemetry = getattr(self.device, "telemetry", None)
            row[3] = (0.0 if resting else block.plate_um_pp[-1]) if telemetry is None else telemetry.measured_um_pp
            row[4] = clipped
            row[5] = math.nan if self.loop is None else self.loop.measured_ratio
            down = block.down
            row[6] = 0.0 if resting else float(down[-1] if isinstance(down, np.ndarray) and down.ndim else down)
            fast[shm.HISTORY_INDEX] += 1
        if touched:
            latency = self.shared.latency
            # when the block's first sample leaves the device: an audio stream says (callback time plus its
            # output latency); paced sinks and plate drivers pull samples already due, so: now
            present = done if now_s is None or now_s < done else now_s
            for k in range(self._latency_from, self._latency_to):
                latency[k % shm.LATENCY_ROWS, 1] = done
                latency[k % shm.LATENCY_ROWS, 2] = present
            fast[shm.LATENCY_INDEX] = self._latency_to
            fast[shm.TOUCHES] += touched
        fast[shm.SEQ] += 1  # even: whole

    def request_stop(self) -> None:
        """Ask the envelope source to ramp down to rest; the state published says stopping from now.

        Examples
        --------
        The state published says stopping from the next block:

        >>> import time
        >>> from ultraglide import Renderer
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.devices.urls import open_device
        >>> shared = SharedBlock.create()
        >>> device = open_device("null", load_profile("sim-plate"))
        >>> source = EngineSource(Renderer("grating-1mm"), shared, device, False)
        >>> source.request_stop()
        >>> _ = source.pull(960, None)
        >>> shm.STATES[int(shared.fast[shm.STATE])]
        'stopping'
        >>> shared.close()
        """
        self._stopping = True
        super().request_stop()


class EngineBeat(threading.Thread):
    """Advances ``ENGINE_BEAT`` in the shared memory every ``period_s`` while the engine's process runs Python: with
    the block path's ``HEARTBEAT``, how the app's supervisor tells a frozen engine (neither advances: stopped by
    SIGSTOP, or stuck holding the interpreter) from a device that pulls no block for a while (a plate's handshake
    after a reconnection, the tail of a stop).

    Parameters
    ----------
    fast : numpy.ndarray
        The shared memory's fast header.
    period_s : float
        How often the beat advances, s.

    Examples
    --------
    >>> import time
    >>> import numpy as np
    >>> fast = np.zeros(shm.HEADER)
    >>> beat = EngineBeat(fast, period_s=0.001); beat.start()
    >>> deadline = time.monotonic() + 30.0
    >>> while fast[shm.ENGINE_BEAT] < 3 and time.monotonic() < deadline:
    ...     time.sleep(0.001)
    >>> beat.stop(); bool(fast[shm.ENGINE_BEAT] >= 3), beat.fast is None
    (True, True)
    """

    def __init__(self, fast: np.ndarray, period_s: float = 0.02):
        super().__init__(name="engine-beat", daemon=True)
        self.fast = fast
        self.period_s = period_s
        self._stop_event = threading.Event()

    def run(self) -> None:
        """Advance the beat every ``period_s`` until stopped.

        Examples
        --------
        Started as a thread, it advances the beat until stopped:

        >>> import time
        >>> import numpy as np
        >>> fast = np.zeros(shm.HEADER)
        >>> beat = EngineBeat(fast, period_s=0.001)
        >>> beat.start()
        >>> deadline = time.monotonic() + 30.0
        >>> while fast[shm.ENGINE_BEAT] < 1 and time.monotonic() < deadline:
        ...     time.sleep(0.001)
        >>> beat.stop(); bool(fast[shm.ENGINE_BEAT] >= 1)
        True
        """
        fast = self.fast
        while not self._stop_event.wait(self.period_s):
            fast[shm.ENGINE_BEAT_S] = time.perf_counter()  # (its time first: a count seen advanced has its time)
            fast[shm.ENGINE_BEAT] += 1

    def stop(self) -> None:
        """End the thread and drop its view of the segment (a view held would keep the segment from closing).

        Examples
        --------
        >>> import numpy as np
        >>> beat = EngineBeat(np.zeros(shm.HEADER), period_s=0.01)
        >>> beat.start(); beat.stop()
        >>> beat.is_alive(), beat.fast
        (False, None)
        """
        self._stop_event.set()
        self.join(timeout=1.0)
        self.fast = None


def forked_engine_main(config, shared_name: str, conn, app_end) -> None:
    """The engine's entry point when forked from the app.

    First it becomes what a spawned engine is: without the app's end of the pipe (or the app's going would not
    close it), its signal handlers or signal wake-up file; then :func:`engine_main`.

    Parameters
    ----------
    config : EngineConfig
        What to render and where.
    shared_name : str
        The name of the shared memory segment the app made.
    conn : multiprocessing.connection.Connection
        The engine's end of the pipe.
    app_end : multiprocessing.connection.Connection
        The app's end, closed in the engine.

    Returns
    -------
    None

    Examples
    --------
    >>> import multiprocessing
    >>> from ultraglide.render.engine import EngineConfig
    >>> context = multiprocessing.get_context("fork")
    >>> shared = SharedBlock.create()
    >>> app, engine = context.Pipe()
    >>> config = EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)
    >>> child = context.Process(target=forked_engine_main, args=(config, shared.name, engine, app))
    >>> child.start(); engine.close()
    >>> [app.recv()[0] for _ in range(2)]
    ['up', 'ready']
    >>> app.send(("stop",)); app.recv()[0]
    'stopped'
    >>> child.join(); child.exitcode
    0
    >>> shared.close()
    """
    app_end.close()
    signal.set_wakeup_fd(-1)
    for signum in signal.valid_signals():
        if callable(signal.getsignal(signum)) and signum != signal.SIGINT:  # the app's handlers (engine_main sets
            signal.signal(signum, signal.SIG_DFL)  # SIGTERM's and SIGINT's)
    engine_main(config, shared_name, conn)


def _rest_unserved(device, source) -> None:
    """A device that will not be served: made safe, and the run's records (envelope, sensors) dropped unfinished."""
    close_device(device)
    for record in (getattr(source, "record", None), getattr(source, "sensor_record", None)):
        if record is not None:
            record.discard()


def engine_main(config, shared_name: str, conn) -> None:
    """The engine process's entry point (spawned by :meth:`render.engine.Engine.start`).

    It loads the parts (:func:`load_parts`), says ``("up", ...)`` on the pipe, starts the device on an
    :class:`EngineSource`, says ``("ready", ...)``, serves commands (:func:`serve`) until a stop (the command,
    SIGTERM or SIGHUP, or the pipe closed), then ``("stopped", status)``. Failures go up the pipe as one
    line: ``("error", ...)`` while loading, ``("failed", ...)`` while starting. SIGINT is ignored: Ctrl-C is
    the app's.

    Parameters
    ----------
    config : EngineConfig
        What to render and where.
    shared_name : str
        The name of the shared memory segment the app made.
    conn : multiprocessing.connection.Connection
        The engine's end of the pipe.

    Returns
    -------
    None

    Examples
    --------
    In a process of its own (it sets the process's signal handlers), on the null device:

    >>> import multiprocessing
    >>> from ultraglide.render.engine import EngineConfig
    >>> context = multiprocessing.get_context("fork")
    >>> shared = SharedBlock.create()
    >>> app, engine = context.Pipe()
    >>> config = EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)
    >>> child = context.Process(target=engine_main, args=(config, shared.name, engine))
    >>> child.start()
    >>> app.recv()[0], app.recv()[0]
    ('up', 'ready')
    >>> app.send(("stop",)); app.recv()[0]
    'stopped'
    >>> child.join(); child.exitcode
    0
    >>> shared.close()
    """
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    pages = keep_huge_pages_out() if config.realtime_priority else "huge pages: as the system has them"
    stop_requested = threading.Event()
    for stop_signal in (signal.SIGTERM, signal.SIGHUP):  # a hangup as SIGTERM: ramp to rest, rest the hardware, end
        signal.signal(stop_signal, lambda *_: stop_requested.set())
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the app, which stops the engine in order
    try:
        shared = SharedBlock.attach(shared_name)
    except FileNotFoundError:  # the app was stopped (a signal) before this process started: nobody to serve
        return
    errors = USER_ERRORS
    device = None
    try:
        texture, model, profile, device = load_parts(config)
    except errors as error:
        with contextlib.suppress(OSError):  # the app may have gone already (stopped while this loaded)
            conn.send(("error", describe(error)))
        shared.close()
        return
    try:
        conn.send(("up", {"pid": os.getpid(), "device": config.device}))
    except OSError:  # the app was stopped (a signal) while the device opened: nobody to serve, rest it and end
        close_device(device)
        shared.close()
        return
    from ultraglide.render.renderer import Renderer, RenderSettings

    source = None
    try:
        rate = device.rate_hz if device.signal == "audio" else config.rate_hz
        settings = RenderSettings(audio_rate_hz=int(rate), control_rate_hz=config.control_rate_hz,
                                  carrier_hz=config.carrier_hz, default_force_n=config.default_force_n,
                                  precompensate=config.precompensate, predictor=config.predictor, plan=config.plan,
                                  lookahead_s=config.lookahead_s)
        loop = None
        listeners = []
        if config.closed_loop:
            from ultraglide.render.engine.friction_loop import FrictionLoop

            stream_hz = device.rate_hz if device.signal == "control" else config.control_rate_hz
            loop = FrictionLoop(model, stream_hz)  # indexed by the device's values, at its rate
            listeners.append(loop.take_sensors_frame)
        seen = profile
        if config.closed_loop:  # the device follows amplitude targets: pre-compensate its loop, not the plate
            from ultraglide.render.engine.loop_plate import AmplitudeLoopPlate

            seen = AmplitudeLoopPlate.of(profile)
        renderer = Renderer(texture, model if loop is None else loop.inverse, seen, settings)
        renderer.pause(config.start_paused)
        source = EngineSource(renderer, shared, device, config.realtime_priority, profile)
        source.loop = loop
        if config.envelope_csv:
            from ultraglide.render.engine.envelope_record import EnvelopeRecord

            source.record = EnvelopeRecord(config.envelope_csv)
            if hasattr(device, "add_sensor_listener"):  # a plate driver's SENSORS say when each value plays
                from ultraglide.render.engine.play_clock import PlayClock

                source.record.clock = PlayClock(source.rate_hz)
                listeners.append(source.record.clock.take_frame)
                if hasattr(device, "add_clock_listener"):  # ... and its CLOCK replies, where it states its clock
                    device.add_clock_listener(source.record.clock.take_clock)
        if config.sensors_csv:
            from ultraglide.render.engine.sensor_record import SensorRecord

            source.sensor_record = SensorRecord(config.sensors_csv, source.rate_hz / 1000.0)
            listeners.append(source.sensor_record.take)
        if listeners:
            if not hasattr(device, "add_sensor_listener"):
                from ultraglide.devices.errors import DeviceError

                raise DeviceError(f"{config.device} has no sensors to record or to close the loop on")
            for listener in listeners:  # each SENSORS frame, on the device's reader thread
                device.add_sensor_listener(listener)
        gc.collect()
        gc.freeze()  # everything built so far is permanent: later collections never walk it
        gc.disable()  # no collection can start inside a block; the command thread collects when idle
        if config.realtime_priority:  # before the device starts: the threads it starts (a plate driver's writer,
            raise_other_threads()  # which must send within the plate's 100 ms watchdog from the enable on) inherit it
        device.start(source)
        if loop is not None:
            check_sensors(device, loop)
        if source.sensor_record is not None and getattr(device.hello(), "sensor_rate_hz", 0):
            source.sensor_record.stream_per_sample = source.rate_hz / device.hello().sensor_rate_hz
        clock = getattr(source.record, "clock", None)
        if clock is not None and getattr(device.hello(), "sensor_rate_hz", 0):  # the rates the device states
            clock.sensor_rate_hz = float(device.hello().sensor_rate_hz)
            clock.link_bytes_per_s = float(device.hello().link_bytes_per_s if device.hello().states_link else 0)
    except errors as error:
        _rest_unserved(device, source)
        with contextlib.suppress(OSError):  # the app may have gone already (stopped while the device started)
            conn.send(("failed", describe(error)))
        shared.fast[shm.STATE] = shm.STATES.index("failed")
        shared.close()
        return
    beat = EngineBeat(shared.fast)  # the supervisor's sign that this process runs (raised to SCHED_FIFO 1 below)
    beat.start()
    probe = None
    if config.probe_plate and hasattr(device, "plate"):
        probe = PlateProbe(device.plate.simulator, shared.fast)
        probe.start()
    threads = raise_other_threads() if config.realtime_priority else "other threads: normal"
    threads = f"{threads}; {pages}"
    source.threads = threads
    try:
        conn.send(("ready", {"rate_hz": rate, "carrier_hz": renderer.carrier_hz, "signal": device.signal,
                             "tail_s": renderer.tail_s, "device_status": device_status(device)}))
    except OSError:  # the app was stopped (a signal) while the device started: nobody to serve, rest it and end
        _rest_unserved(device, source)
    else:
        serve(config, conn, shared, renderer, source, device, stop_requested, threads)
    if probe is not None:
        probe.stop_event.set()
        probe.join(timeout=1)
    beat.stop()
    shared.close()
