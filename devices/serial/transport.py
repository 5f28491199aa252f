"""The serial plate driver's transport: the port, its reader thread, and frames written one at a time.

It knows framing, seqs and the stream's index, not what a frame means: received frames, damaged bytes and a
failed port are handed to the callbacks it was made with (the driver's :mod:`.telemetry` and :mod:`.session`).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable

import numpy as np
import serial
import serial.threaded
from ultraglide.devices import protocol as p
from ultraglide.devices.serial.link import FrameWriter, SerialCounters, open_port, port_failure
from ultraglide.devices.serial.locks import DriverLocks


class FrameReader(serial.threaded.Protocol):
    """Feeds received bytes to a FrameDecoder (which bounds its buffer) and hands frames on."""

    def __init__(self, transport: Transport):
        self.transport = transport
        self.decoder = p.FrameDecoder()
        self._bad = 0

    def data_received(self, data: bytes) -> None:
        for frame in self.decoder.feed(data):
            self.transport.on_frame(frame)
        bad = self.decoder.crc_errors + self.decoder.framing_errors
        if bad != self._bad:
            self.transport.on_bad_frames(bad - self._bad, self.decoder.crc_errors, self.decoder.framing_errors)
            self._bad = bad

    def connection_lost(self, exc) -> None:
        self.transport.on_lost(port_failure(exc))


class Transport:
    """The port (any pyserial URL), opened exclusively, with a reader thread and a framer for SETPOINTS.

    ``on_frame(frame)`` and ``on_bad_frames(count, crc_errors, framing_errors)`` run on the reader thread;
    ``on_lost(cause)`` when the port fails under it.
    """

    def __init__(self, port: str, baudrate: int, write_timeout_s: float, rate_hz: int, locks: DriverLocks,
                 counters: SerialCounters, on_frame: Callable, on_bad_frames: Callable, on_lost: Callable):
        self.port, self.baudrate, self.write_timeout_s = port, baudrate, write_timeout_s
        self.locks, self.counters = locks, counters
        self.on_frame, self.on_bad_frames, self.on_lost = on_frame, on_bad_frames, on_lost
        self.serial: serial.Serial | None = None
        self.writer: FrameWriter | None = None  # the open port's frame writer (no poll after a whole write)
        self._reader: serial.threaded.ReaderThread | None = None
        self.seq = 0
        self.index = 0  # the stream's index: the next setpoint sent plays as this one
        self.sent_at = 0.0  # perf_counter s of the last frame sent
        self._waited_before = 0.0  # what the writes of the connections before this one waited for room, s
        self._sent_kinds = bytearray(65536)  # the command each seq carried, to name what a NAK refused
        self._framer = p.SetpointFramer(rate_hz)  # SETPOINTS frames built in buffers made once
        self._clock = p.EmptyFramer(p.CLOCK)  # and CLOCK's, asked every 50 ms while streaming

    @property
    def is_open(self) -> bool:
        return self.serial is not None

    def open(self) -> None:
        """Open the port (DeviceError in one line if missing or in use) and start reading it."""
        port = open_port(self.port, self.baudrate, write_timeout_s=self.write_timeout_s)
        with contextlib.suppress(serial.SerialException, OSError):
            port.reset_input_buffer()  # what a previous session left unread is not ours
        self.writer = FrameWriter(port, self.write_timeout_s)
        self.serial = port
        self._reader = serial.threaded.ReaderThread(port, lambda: FrameReader(self))
        self._reader.daemon = True
        self._reader.start()

    @property
    def waited_s(self) -> float:
        """How long the writes of the run have waited for room on the port, s: the link's time, not the host's
        (:meth:`.link.FrameWriter.write`, summed over connections)."""
        writer = self.writer
        return self._waited_before + (writer.waited_s if writer is not None else 0.0)

    def close(self) -> None:
        reader, self._reader = self._reader, None
        port, self.serial = self.serial, None
        writer, self.writer = self.writer, None
        if writer is not None:
            self._waited_before += writer.waited_s
        if reader is not None:
            with contextlib.suppress(Exception):
                reader.stop()
        if port is not None:
            with contextlib.suppress(Exception):
                port.close()

    def kind_of(self, seq: int) -> int:
        """The command the frame with this seq carried."""
        return self._sent_kinds[seq]

    def send(self, kind: int, payload: bytes = b"", expect: Callable[[int], None] | None = None,
             setpoints: np.ndarray | None = None, force: p.ForceReference | None = None) -> int:
        """Write one frame; returns its seq. ``expect(seq)`` is called before the write (its answer will be
        awaited). ``setpoints`` (fractions of full scale): a SETPOINTS frame at the stream's index instead (the
        index moves on by their number), or with ``force`` a SETPOINTS_FORCE frame. SerialException if closed,
        if the port fails, or if the frame waited ``write_timeout_s`` for room (``SerialTimeoutException``):
        :class:`.link.FrameWriter`, which never polls the port after a write the kernel took whole."""
        with self.locks.write:
            writer = self.writer
            if writer is None:
                raise serial.SerialException("not connected")
            self.seq = seq = (self.seq + 1) & 0xFFFF
            self._sent_kinds[seq] = kind if force is None else p.SETPOINTS_FORCE
            self.sent_at = time.perf_counter()
            if expect is not None:
                expect(seq)
            if kind == p.CLOCK and not payload:
                writer.write(self._clock.frame(seq))
            elif setpoints is None:
                writer.write(p.encode_frame(kind, seq, payload))
            else:
                writer.write(self._framer.frame(seq, self.index, setpoints, force))
                self.index += len(setpoints)
        self.counters.frames_sent += 1
        return seq

    def skip(self, n: int) -> None:
        """``n`` indices of the stream go by unsent (the device counts them lost, or it was not listening). Only
        the writer moves the index while it runs (no lock on its path); the rest at the end, after it."""
        self.index += n
