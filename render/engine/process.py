"""The engine's own process: the renderer and the device, fed through shared memory.

:func:`engine_main` is what :class:`render.engine.Engine` spawns. Its main thread loads the inputs,
opens the device, answers rare commands from the pipe and publishes the device's status; the
device's own thread (PortAudio's callback, the serial writer, the paced sink) pulls blocks from
:class:`EngineSource`, whose ``pull`` is the block path: drain the touch ring into the renderer,
render, publish the block's figures. The block path never waits on the UI or on the command thread.

If the pipe to the parent closes (the parent died) or SIGTERM arrives, the engine ramps to rest,
rests the hardware and exits.
"""

from __future__ import annotations

import gc
import math
import os
import signal
import sys
import threading
import time

import numpy as np
from ultraglide.devices.output_stage import OutputStage
from ultraglide.render.engine import shm
from ultraglide.render.engine.realtime import CpuWakeLatency, keep_huge_pages_out, raise_other_threads, raise_priority
from ultraglide.render.engine.shm import SharedBlock
from ultraglide.render.engine.sources import EnvelopeSource

from ultraglide.errors import UltraglideError, describe

SWITCH_INTERVAL_S = 0.0002  # the GIL changes hands this often, so the block thread waits at most this on the others
STATUS_PERIOD_S = 0.1
PROBE_THRESHOLD_UM_PP = 0.05
PROBE_PERIOD_S = 0.0002
# what the engine reports to the app as one line (a plain ValueError too: a bad texture spec from a script)
USER_ERRORS = (UltraglideError, OSError, ValueError)
RESTING_CAPACITY = 65536  # the longest block served as zeros while at rest (frames)


class EngineSource(OutputStage):
    """The block path: the device's output stage (limiter, carrier for audio) with the touch ring drained
    before each block and the block's figures published after it. Devices take it as their stage."""

    def __init__(self, renderer, shared: SharedBlock, device, raise_priority_: bool = True):
        carrier_hz = getattr(device, "carrier_hz", None) or renderer.carrier_hz
        super().__init__(EnvelopeSource(renderer, realtime_capacity=4096), renderer.profile, device.signal,
                         device.rate_hz, carrier_hz)
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

    def _view(self, n: int) -> np.ndarray:
        view = self._views.get(n)
        if view is None:
            view = self._out[:n]
            if len(self._views) < 64:
                self._views[n] = view
        return view

    def pull(self, n: int, now_s: float | None) -> np.ndarray:
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
        done = time.perf_counter()
        self._publish(started, done, now_s, touched, renderer.counters.clipped_samples - clipped_before)
        return out

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
        self._stopping = True
        super().request_stop()


class _PlateProbe(threading.Thread):
    """Watches the simulated plate's amplitude and publishes when it last rose above a threshold
    (for ``ultraglide latency`` on ``sim``: the end-to-end measurement)."""

    def __init__(self, simulator, fast: np.ndarray):
        super().__init__(name="plate-probe", daemon=True)
        self.simulator = simulator
        self.fast = fast
        self.stop_event = threading.Event()

    def run(self) -> None:
        above = False
        while not self.stop_event.wait(PROBE_PERIOD_S):
            amplitude = self.simulator.amplitude_um_pp
            self.fast[shm.PLATE_PROBE_UM_PP] = amplitude
            if amplitude > PROBE_THRESHOLD_UM_PP and not above:
                self.fast[shm.PROBE_RISE_S] = time.perf_counter()
            above = amplitude > PROBE_THRESHOLD_UM_PP


def _load(config):
    """Texture, model, profile and an opened device; one-line errors for bad ones."""
    import warnings

    from ultraglide.devices.profiles import load_profile
    from ultraglide.devices.urls import open_device
    from ultraglide.render.physics.calibration import load_model

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        texture = _texture(config.texture)
    model = load_model(config.model)
    profile = load_profile(config.profile)
    device = open_device(config.device, profile, control_rate_hz=int(config.control_rate_hz),
                         carrier_hz=config.carrier_hz, track_resonance=config.track_resonance)
    return texture, model, profile, device


def _texture(spec):
    """A library name or file, loaded here; or a Texture the app composed in memory (it came pickled)."""
    if isinstance(spec, str):
        from ultraglide.textures.library import resolve_texture

        return resolve_texture(spec)
    from ultraglide.textures.texture import Texture

    if not isinstance(spec, Texture):
        raise ValueError(f"a texture must be a name, a file or a Texture, not {type(spec).__name__}")
    return spec


def engine_main(config, shared_name: str, conn) -> None:
    """The engine process's entry point (spawned by :meth:`render.engine.Engine.start`)."""
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    pages = keep_huge_pages_out() if config.realtime_priority else "huge pages: as the system has them"
    stop_requested = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop_requested.set())
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the app, which stops the engine in order
    shared = SharedBlock.attach(shared_name)
    errors = USER_ERRORS
    device = None
    try:
        texture, model, profile, device = _load(config)
    except errors as error:
        conn.send(("error", describe(error)))
        shared.close()
        return
    conn.send(("up", {"pid": os.getpid(), "device": config.device}))
    from ultraglide.render.renderer import Renderer, RenderSettings

    try:
        rate = device.rate_hz if device.signal == "audio" else config.rate_hz
        settings = RenderSettings(audio_rate_hz=int(rate), control_rate_hz=config.control_rate_hz,
                                  carrier_hz=config.carrier_hz, default_force_n=config.default_force_n,
                                  precompensate=config.precompensate, predictor=config.predictor,
                                  lookahead_s=config.lookahead_s)
        renderer = Renderer(texture, model, profile, settings)
        renderer.pause(config.start_paused)
        source = EngineSource(renderer, shared, device, config.realtime_priority)
        gc.collect()
        gc.freeze()  # everything built so far is permanent: later collections never walk it
        gc.disable()  # no collection can start inside a block; the command thread collects when idle
        device.start(source)
    except errors as error:
        _close_device(device)
        conn.send(("failed", describe(error)))
        shared.fast[shm.STATE] = shm.STATES.index("failed")
        shared.close()
        return
    probe = None
    if config.probe_plate and hasattr(device, "plate"):
        probe = _PlateProbe(device.plate.simulator, shared.fast)
        probe.start()
    threads = raise_other_threads() if config.realtime_priority else "other threads: normal"
    threads = f"{threads}; {pages}"
    source.threads = threads
    conn.send(("ready", {"rate_hz": rate, "carrier_hz": renderer.carrier_hz, "signal": device.signal,
                         "tail_s": renderer.tail_s, "device_status": _device_status(device)}))
    _serve(config, conn, shared, renderer, source, device, stop_requested, threads)
    if probe is not None:
        probe.stop_event.set()
        probe.join(timeout=1)
    shared.close()


def _device_status(device, stage=None) -> dict:
    """The device's own status, with its fault counts over the run when it keeps them, and the limiter's."""
    try:
        status = device.status()
        if stage is not None:
            status.update(stage.limiter.status())
            status["limiter"] = stage.limiter.summary()
        counts = getattr(device, "fault_counts", None)
        if counts is not None:
            status["fault_counts"] = counts()
        return status
    except Exception as error:  # noqa: BLE001 - a status that fails to build must not stop the engine
        return {"errors": [f"status: {type(error).__name__}: {error}"]}


def _renderer_status(renderer) -> dict:
    """What the renderer renders with: texture, model, the default force (N); the temporal effects started."""
    player = renderer.effects
    return {"texture": renderer.texture.name, "model": getattr(renderer.model, "name", str(renderer.model)),
            "force_n": renderer.default_force_n, "effects_started": 0 if player is None else player.started}


def _close_device(device) -> str | None:
    """Stop the device; what went wrong that a person can act on (e.g. a recording that did not fit on
    the disk), or None. Resting the hardware is best effort on the way out: nothing here raises."""
    if device is None:
        return None
    try:
        device.stop()
    except USER_ERRORS as error:
        return describe(error)
    except Exception as error:  # noqa: BLE001 - reported, never raised past the hardware's rest
        return f"the device failed while stopping: {type(error).__name__}: {error}"
    return None


def _serve(config, conn, shared, renderer, source, device, stop_requested, threads: str) -> None:
    """The command loop: rare commands, the device's status ten times a second, idle collection, and the
    CPUs kept quick to wake while the block path renders (released while it serves zeros at rest)."""
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
            shared.write_slow({**_device_status(device, source), **_renderer_status(renderer),
                               "priority": f"{source.priority}; {threads}; {wake.words()}", "pid": os.getpid()})
            next_status = now + STATUS_PERIOD_S
        if now >= next_collect:
            gc.collect(0)  # young objects only: short; the block thread waits at most the switch interval
            next_collect = now + 1.0
        if stop_requested.is_set():
            _finish(shared, source, device, None, wake)
            return
        try:
            if not conn.poll(STATUS_PERIOD_S / 2):
                continue
            command, *args = conn.recv()
        except (EOFError, OSError):  # the parent is gone: rest the plate and leave
            _finish(shared, source, device, None, wake)
            return
        if command == "stop":
            _finish(shared, source, device, conn, wake)
            return
        try:
            if command == "texture":
                renderer.set_texture(_texture(args[0]))
            elif command == "model":
                from ultraglide.render.physics.calibration import load_model

                renderer.set_model(load_model(args[0]))
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


def _finish(shared, source, device, conn, wake) -> None:
    """Ramp to rest, rest the hardware, publish the last status; tell the parent if it is there."""
    source._stopping = True
    failure = _close_device(device)
    wake.close()
    status = {**_device_status(device, source), **_renderer_status(source.renderer),
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
