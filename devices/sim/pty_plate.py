"""The simulated plate on a pseudo-terminal: the firmware core and its plate served to a host as a serial
port would be, with faults injected on the link when asked."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import select
import struct
import termios
import threading
import time
import tty

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.sim.lies import Lies
from ultraglide.devices.sim.links import LinkClaim, link_path_for, place_link, remove_link
from ultraglide.devices.sim.plate import (
    LINK_BYTES_PER_S,
    LISTEN_S,
    STALL_S,
    TICK_S,
    ForceSource,
    PlateSimulator,
    PlateTruth,
)


class PtyPlate:
    """A :class:`PlateSimulator` served on a pseudo-terminal behind a stable symlink.

    Two threads: the frame handler (reads the port, answers frames) and the output stage (plays
    setpoints, runs the watchdog, sends telemetry), so a hung handler still rests the plate. The
    pty's slave side is not held open here, so the master sees who is connected (EIO when nobody is).
    """

    def __init__(self, profile: PlateProfile, link_path: str | None = None, truth: PlateTruth | None = None,
                 breaks: tuple[str, ...] = (), max_version: int = 3, finger: ForceSource | None = None,
                 link_bytes_per_s: int = LINK_BYTES_PER_S, lies: Lies | None = None):
        self.lies = lies  # fields replaced in what it sends (devices/sim/lies.py): a plate that lies
        self.simulator = PlateSimulator(profile, truth=truth, breaks=breaks, max_version=max_version, finger=finger,
                                        link_bytes_per_s=link_bytes_per_s)
        self.path, self._own_dir = link_path_for(link_path, "ultraglide-plate-")
        self._claim = LinkClaim(self.path) if self._own_dir is None else None  # a path given: no other simulator's
        self.pty_name = ""
        self._master = -1
        self._port_lock = threading.Lock()
        self._input_lock = threading.Lock()  # bytes read and decoded in order, by whichever thread takes them
        self._client = False
        self._stop = threading.Event()
        self._wake = threading.Event()  # the output stage's sleep ends early: stop, or the output enabled
        self._sleeping_long = False  # the output stage waits for telemetry, not the next tick
        self._threads: list[threading.Thread] = []
        self._drop_until = 0.0
        self._corrupt_until = 0.0
        self._hang_until = 0.0
        self._disconnect_until = 0.0
        self._rng = np.random.default_rng(0)
        self.dropped_replies = 0  # written while the port's buffer was full (nobody reading)
        # the host's frames stopped for longer than the watchdog's timeout while the output was enabled, outside
        # injected faults, as this side's clock saw it: each such gap may trip the watchdog, nothing else may
        self.quiet_gaps = 0
        self._last_delivered: float | None = None
        self._enabled_after_last = False

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: a byte pipe like a USB serial port
        name = os.ttyname(slave)
        os.close(slave)
        fcntl.fcntl(master, fcntl.F_SETFL, fcntl.fcntl(master, fcntl.F_GETFL) | os.O_NONBLOCK)
        place_link(name, self.path)
        with self._port_lock:
            self._master, self.pty_name = master, name

    def _close_pty(self) -> None:
        remove_link(self.path, self.pty_name or None)  # only the link it made
        with self._port_lock:
            master, self._master = self._master, -1
            if master >= 0:
                with contextlib.suppress(OSError):
                    os.close(master)
        self._set_client(False)

    def _set_client(self, present: bool) -> None:
        if present != self._client:
            self._client = present
            self.simulator._event("connected" if present else "disconnected", pty=self.pty_name)

    def start(self) -> PtyPlate:
        self.simulator.real_time = True
        self._open_pty()
        for target, name in ((self._serve_frames, "plate-sim-frames"), (self._serve_output, "plate-sim-output")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    @property
    def alive(self) -> bool:
        """Both threads serving."""
        return bool(self._threads) and all(thread.is_alive() for thread in self._threads)

    def inject(self, kind: int, duration_s: float) -> None:
        """Inject a fault now: SIM_DROP, SIM_CORRUPT, SIM_HANG, SIM_DISCONNECT (for ``duration_s``) or SIM_OVERHEAT."""
        if kind == p.SIM_OVERHEAT:
            self.simulator.overheat()
            return
        until = time.monotonic() + duration_s
        self.simulator._count_injected(p.SIM_FAULT_KINDS[kind])
        self._last_delivered = None  # the silence this makes is the injected fault's, not the host's
        if kind == p.SIM_DROP:
            self._drop_until = until
        elif kind == p.SIM_CORRUPT:
            self._corrupt_until = until
        elif kind == p.SIM_HANG:
            self._hang_until = until
        elif kind == p.SIM_DISCONNECT:
            self._disconnect_until = until

    def unread_bytes(self) -> int:
        """Bytes the host has written that this plate has not read yet (what waits in the pty): a frame counted
        by the plate after a moment may have been sent before it, by this many bytes.

        Returns
        -------
        int
            Bytes waiting, 0 when the pty is closed.

        Examples
        --------
        A plate serving an idle port: nothing waits.

        >>> from ultraglide.devices.profiles import load_profile
        >>> plate = PtyPlate(load_profile("sim-plate")).start()
        >>> plate.unread_bytes()
        0
        >>> plate.stop()
        """
        with self._port_lock:
            if self._master < 0:
                return 0
            try:
                return struct.unpack("i", fcntl.ioctl(self._master, termios.FIONREAD, b"\0\0\0\0"))[0]
            except OSError:
                return 0

    def end_injected(self) -> None:
        """End every injected transport fault now."""
        self._drop_until = self._corrupt_until = self._hang_until = self._disconnect_until = 0.0

    def _write(self, frames: list[bytes]) -> None:
        if self.lies:
            frames = self.lies.rewrite(frames)
        with self._port_lock:
            for frame in frames:
                if self._master < 0:
                    return
                try:
                    os.write(self._master, frame)
                except BlockingIOError:  # nobody reads and the pty's buffer is full: like a UART, drop it
                    self.dropped_replies += 1
                except OSError:
                    return

    def _serve_frames(self) -> None:
        """The frame handler's thread: read, decode, answer. Never ends before stop()."""
        while not self._stop.is_set():
            try:
                self._serve_once()
            except Exception as error:  # keep serving whatever happened; say what it was
                self.simulator._event("handler_error", error=f"{type(error).__name__}: {error}")
                time.sleep(TICK_S)

    def _serve_once(self) -> None:
        now = time.monotonic()
        if now < self._disconnect_until:
            if self._master >= 0:
                self._close_pty()
            time.sleep(TICK_S)
            return
        if self._master < 0:
            self._open_pty()
        if now < self._hang_until:
            time.sleep(TICK_S)
            return
        ready, _, _ = select.select([self._master], [], [], LISTEN_S)
        if not ready and self._client:
            return
        with self._input_lock:
            try:
                data = os.read(self._master, 65536)
            except BlockingIOError:  # someone has the port open and is quiet (or the output stage took the bytes)
                self._set_client(True)
                return
            except OSError as error:
                if error.errno != errno.EIO:
                    raise
                self._set_client(False)  # nobody has the port open
                data = None
            if data is not None:
                self._set_client(True)
                self._write(self._incoming(data))
                return
        time.sleep(TICK_S)

    def _take_waiting_frames(self) -> None:
        """Frames already waiting on the link are handled before time advances, as a UART's interrupt
        comes before real firmware's output loop: a frame handler thread that has not been scheduled yet
        (a loaded machine) is not the host's silence, and must not trip the watchdog."""
        now = time.monotonic()
        master = self._master
        if master < 0 or now < self._hang_until or now < self._disconnect_until:
            return
        with self._input_lock:
            try:
                ready, _, _ = select.select([master], [], [], 0)
                data = os.read(master, 65536) if ready else b""
            except OSError:  # nothing after all, nobody on the port, or the port just closed
                return
            if data:
                self._write(self._incoming(data))

    def _serve_output(self) -> None:
        """The output stage's thread: plays setpoints, runs the watchdog, sends telemetry.

        It ticks every ``TICK_S`` while the output is enabled or the plate still moves; a disabled plate
        at rest wakes only for telemetry (50 a second), or at once when a frame enables the output."""
        simulator = self.simulator
        wait = TICK_S
        while True:
            self._wake.wait(wait)
            if self._stop.is_set():
                return
            self._wake.clear()
            try:
                hung = time.monotonic() < self._hang_until
                self._take_waiting_frames()
                # what the advance renders beyond the sleep it meant: this process was not running (a stop
                # anywhere in the last turn of this loop counts), and real firmware's clock stops too
                stalled_s = simulator.lag_s() - wait
                if stalled_s > STALL_S - TICK_S:
                    simulator.excuse(stalled_s)
                frames = simulator.advance(telemetry=not hung)
                if frames and self._client:
                    self._write(frames)
                wait = simulator.next_wake_s(time.perf_counter())
                self._sleeping_long = wait > TICK_S
            except Exception as error:
                simulator._event("output_error", error=f"{type(error).__name__}: {error}")
                wait = TICK_S

    def _incoming(self, data: bytes) -> list[bytes]:
        now = time.monotonic()
        if now < self._drop_until:
            return []
        if now < self._corrupt_until:
            corrupted = bytearray(data)
            flips = self._rng.integers(0, len(corrupted), max(1, len(corrupted) // 16))
            for index in flips:
                corrupted[index] ^= 1 << int(self._rng.integers(0, 8))
            data = bytes(corrupted)
            self._last_delivered = None
        else:
            self._note_delivery(now)
        if self._sleeping_long:  # the output stage sleeps until telemetry: bring the core's clock to now first, so a
            self._write(self.simulator.advance())  # frame enabling it is not handled up to 20 ms in the past (the
        replies = self.simulator.receive(data)  # rendering that then caught up played the prefill at once, and ran dry)
        if self._last_delivered is not None:
            self._enabled_after_last = self.simulator.enabled
        if self._sleeping_long and self.simulator.enabled:  # the output stage waits for telemetry: its clock starts now
            self._sleeping_long = False
            self._wake.set()
        while self.simulator.fault_requests:
            self.inject(*self.simulator.fault_requests.pop(0))
        return replies

    def _note_delivery(self, now: float) -> None:
        """Frames arrive at ``now`` (s, monotonic): a gap since the last that began with the output enabled (as
        the frames then left it) and outlasted the watchdog's timeout is counted."""
        last = self._last_delivered
        if last is not None and now - last > p.WATCHDOG_MS / 1000.0 and self._enabled_after_last:
            self.quiet_gaps += 1
        self._last_delivered = now

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        for thread in self._threads:
            thread.join(timeout=2)
        self._close_pty()
        if self._claim is not None:
            self._claim.release()
        if self._own_dir:
            with contextlib.suppress(OSError):
                os.rmdir(self._own_dir)
