"""The serial link under the plate driver: opening the port, writing frames on it (:class:`FrameWriter`), what a
stream costs in bytes and how it is paced, which stream fits what the device's link carries (:func:`choose_stream`,
after a :func:`probe_hello`), its counters; the driver's constants."""

from __future__ import annotations

import contextlib
import errno
import math
import os
import select
import time
from dataclasses import dataclass, field

import serial
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError

SILENCE_S = p.HOST_SILENCE_MS / 1000.0  # no telemetry for this long while connected: the device has hung
BACKOFF_S = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6)
# faults after which the plate played far from what was commanded (ramped or cut to zero): the tracker
# discards what it was measuring. An underrun holds the last value and an overrun drops a few: both leave
# the mean drive nearly as commanded, and on a loaded host they come often, so they do not count.
TRACKING_DISTURBANCES = (p.FAULT_WATCHDOG, p.FAULT_TRIP, p.FAULT_OVERHEAT)
# setpoints that all round to code 0 for this long: the host stops the stream and disables the output (the
# plate rests either way); the first non-zero setpoint enables it again. Well inside nothing: no watchdog
# runs while disabled, and telemetry (which the host's silence check needs) goes on.
IDLE_AFTER_S = 0.05
ZERO_FRACTION = 0.5 / p.SETPOINT_SCALE  # at most this fraction of full scale is sent as code 0
CUT_FAULTS = (p.FAULT_TRIP, p.FAULT_OVERHEAT)  # the device disabled itself: the host never re-enables it
CUT_WORDS = {"trip": "over-amplitude trip: its measured amplitude went more than 1 % over its limit",
             "overheat": "overheat: its driver stage was too hot"}
REENABLE_AFTER_S = 0.1  # telemetry says the plate is off this long after an ENABLE 1 (unacknowledged, lost on
# the link?) while the host streams: ENABLE goes again (the plate discards every setpoint while disabled)
CLOCK_EVERY_S = 0.05  # a CLOCK request this often while streaming to a device that states its clock, and someone
# listens (the play clock: 20 round trips a second, 9 bytes each; the fastest of them places the plate's clock)
CLOCK_GIVE_UP_S = 0.5  # a CLOCK request unanswered this long is given up (its reply, if it comes, is not taken)
STALL_S = 0.05  # the writer woke this much later than it meant to: the host did not run (not the plate's silence)
CLEAR_RETRY_S = 0.5  # a CLEAR_FAULTS unanswered this long was lost on the link: sent again
DEPTH_WINDOW = 10  # v3 telemetry frames (0.2 s) over which the median of the plate's buffer depth is taken
DEPTH_DEADBAND_S = 0.005  # the plate's buffer's median this far from its target: the host moves its lead (the
# median strays 0-1.3 ms on an idle machine; beside two CPU hogs, a simulated plate's lags made 3 ms strays common)
REST_ACK_S = 0.25  # after a failed handshake, how long the rest's ENABLE 0 waits for its ACK (best effort)
MAX_OUTAGES = 20  # disconnections kept with their times; more are counted
# the baud rates a UART is usually opened at, to name the one a stream needs
STANDARD_BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
                  1500000, 2000000, 2500000, 3000000, 3500000, 4000000)
# device counters whose run totals the report words (summed across reconnections like the fault counters)
LINK_COUNTERS = ("crc_errors", "framing_errors", "lost_setpoints", "late_setpoints", "overrun_setpoints")
COMMAND_NAMES = {p.HELLO: "HELLO", p.SET_CARRIER: "SET_CARRIER", p.ENABLE: "ENABLE", p.SETPOINTS: "SETPOINTS",
                 p.HEARTBEAT: "HEARTBEAT", p.CLEAR_FAULTS: "CLEAR_FAULTS", p.SIM_FAULT: "SIM_FAULT"}
if hasattr(p, "SET_LOOP"):
    COMMAND_NAMES[p.SET_LOOP] = "SET_LOOP"
COMMAND_NAMES[p.SETPOINTS_FORCE] = "SETPOINTS_FORCE"


def port_failure(error: BaseException | None) -> str:
    """Why the port failed, in a few words (pyserial's messages are long and about its internals)."""
    if error is None:
        return "the port closed"
    text = str(error)
    if "returned no data" in text or "Input/output error" in text or getattr(error, "errno", None) == errno.EIO:
        return "the port went away (the device closed it or was unplugged)"
    if "timeout" in text.lower():
        return "the port stopped taking data (a write timed out)"
    return f"the port failed ({text.splitlines()[0] if text else type(error).__name__})"


def open_port(port: str, baudrate: int, write_timeout_s: float = 0.5) -> serial.Serial:
    """A serial port (any pyserial URL) opened exclusively: a ``flock`` (pyserial's ``exclusive``; it holds on
    pseudo-terminals too) and ``TIOCEXCL``, which keeps out programs that take no lock (unless root).
    DeviceError in one line if it is missing or in use."""
    try:
        opened = serial.serial_for_url(port, baudrate=baudrate, timeout=0.05, write_timeout=write_timeout_s,
                                       exclusive=True)
    except (serial.SerialException, OSError, ValueError) as error:
        code = getattr(error, "errno", None)
        if code in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY):  # another holds the lock, or TIOCEXCL
            raise DeviceError(f"serial port {port} is in use by another program; stop it (or the other "
                              "ultraglide) first") from None
        reason = os.strerror(code).lower() if isinstance(code, int) else str(error)
        if "exclusively lock" in str(error):  # the lock failed for another reason: say which
            raise DeviceError(f"cannot lock serial port {port}: {reason}") from None
        raise DeviceError(f"cannot open serial port {port}: {reason}; check the path and permissions (the "
                          "dialout group), or list ports with `ultraglide devices`") from None
    fd = getattr(opened, "fd", None)
    if fd is not None:
        import fcntl
        import termios

        with contextlib.suppress(OSError):
            fcntl.ioctl(fd, termios.TIOCEXCL)
    return opened


class FrameWriter:
    """Whole frames written to one opened port, within its write timeout, without polling the port after a write
    the kernel took whole.

    pyserial's ``Serial.write`` calls ``select()`` on the port after every ``os.write``, even a complete one. On a
    terminal (a UART's or a pseudo-terminal's) that poll is ``n_tty_poll``, which first waits for the tty's
    flip-buffer work on a kworker at ordinary priority: beside busy real-time threads (an emulated board's
    processor) and CPU hogs, the real-time writer waited 20-290 ms in it for nothing (docs/performance.md). So on a
    device node (pyserial's POSIX class, its descriptor kept ``O_NONBLOCK``) a frame is ``os.write``-n at once;
    only when the kernel takes part of it, or none (``EAGAIN``: its buffer is full), is the port polled for room,
    until ``timeout_s`` has passed since the first wait: then ``serial.SerialTimeoutException("Write timeout")``,
    as pyserial says it. A port of a pyserial URL handler (``loop://``, ``socket://``, ...) keeps ``port.write``.
    The complete write allocates nothing; a partial one a ``memoryview`` and the poll's answer.

    Parameters
    ----------
    port : serial.Serial
        The opened port (:func:`open_port`).
    timeout_s : float or None
        How long a frame may wait for room on the port (s); None: for ever.

    Raises
    ------
    serial.SerialException
        From :meth:`write`: the port is closed (``PortNotOpenError``), the write failed (``write failed: ...``,
        with the OS's words, e.g. ``Input/output error`` when the far end went away), or timed out
        (``SerialTimeoutException``).

    Examples
    --------
    >>> import pty
    >>> host_end, plate_end = pty.openpty()
    >>> port = open_port(os.ttyname(plate_end), 115200, write_timeout_s=0.2)
    >>> writer = FrameWriter(port, 0.2)
    >>> writer.direct, writer.write(b"ab\\x00"), os.read(host_end, 16)
    (True, None, b'ab\\x00')
    >>> port.close(); os.close(host_end); os.close(plate_end)
    """

    def __init__(self, port: serial.Serial, timeout_s: float | None):
        self.port, self.timeout_s = port, timeout_s
        posix = getattr(serial, "serialposix", None)  # pyserial's class for device nodes (POSIX systems only)
        fd = getattr(port, "fd", None)
        self.direct = posix is not None and isinstance(port, posix.Serial) and isinstance(fd, int)
        self._poll = None
        self.waited_s = 0.0  # the time its writes waited for room on the port (the link's, not the host's), s
        if self.direct:
            os.set_blocking(fd, False)  # pyserial opens it so; a write must never block the writer
            self._poll = select.poll()  # made once: a wait for room makes no poll object
            self._poll.register(fd, select.POLLOUT)

    def write(self, frame: bytes) -> None:
        """Write ``frame`` whole (see the class); SerialException if the port is closed or fails, or the frame
        waited ``timeout_s`` for room."""
        port = self.port
        if not self.direct:  # (a URL handler's write may block: the link's time)
            began = time.perf_counter()
            try:
                port.write(frame)
            finally:
                self.waited_s += time.perf_counter() - began
            return
        fd = port.fd
        if fd is None:  # closed under us
            raise serial.PortNotOpenError()
        try:
            written = os.write(fd, frame)
        except BlockingIOError:  # the kernel's buffer is full: wait for room
            written = 0
        except OSError as error:
            raise serial.SerialException(f"write failed: {error}") from None
        if written < len(frame):
            began = time.perf_counter()
            try:
                _write_rest(fd, self._poll, frame, written, self.timeout_s)
            finally:
                self.waited_s += time.perf_counter() - began


def _write_rest(fd: int, poller, frame: bytes, written: int, timeout_s: float | None) -> None:
    """The rest of ``frame`` from byte ``written`` on the non-blocking ``fd``, each time ``poller`` (a
    ``select.poll`` with ``fd`` registered for POLLOUT) says it has room, until ``timeout_s`` after the first
    wait: SerialException as :meth:`FrameWriter.write` raises them."""
    view = memoryview(frame)
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    while written < len(frame):
        wait_ms = None
        if deadline is not None:
            wait_ms = (deadline - time.monotonic()) * 1000.0
            if wait_ms <= 0.0:
                raise serial.SerialTimeoutException("Write timeout")
        events = poller.poll(wait_ms)
        if not events:
            raise serial.SerialTimeoutException("Write timeout")
        try:
            written += os.write(fd, view[written:])
        except BlockingIOError:
            if events[0][1] & (select.POLLHUP | select.POLLERR | select.POLLNVAL):  # no room will come
                raise serial.SerialException("write failed: the port hung up") from None
        except OSError as error:
            raise serial.SerialException(f"write failed: {error}") from None


def write_frame_fd(fd: int, frame: bytes, timeout_s: float | None) -> None:
    """Write ``frame`` whole on a terminal's descriptor ``fd`` as :class:`FrameWriter` does on a port: at once,
    polling the descriptor for room only when the kernel took part of it or none (a poll of a terminal waits for its
    flip-buffer work, on an ordinary-priority kworker). ``fd`` is made non-blocking (its open file's flag: every
    descriptor of that file, in any process, shares it).

    Parameters
    ----------
    fd : int
        The terminal's descriptor (a serial port's, a pseudo-terminal's).
    frame : bytes
        What to write.
    timeout_s : float or None
        How long the frame may wait for room (s) from the first wait; None: for ever.

    Raises
    ------
    serial.SerialException
        The write failed (``write failed: ...``) or waited ``timeout_s`` for room (``SerialTimeoutException``).

    Examples
    --------
    >>> import pty
    >>> host_end, plate_end = pty.openpty()
    >>> write_frame_fd(plate_end, b"ab\\x00", 0.2); os.read(host_end, 16)
    b'ab\\x00'
    >>> os.close(host_end); os.close(plate_end)
    """
    os.set_blocking(fd, False)
    try:
        written = os.write(fd, frame)
    except BlockingIOError:
        written = 0
    except OSError as error:
        raise serial.SerialException(f"write failed: {error}") from None
    if written < len(frame):
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        _write_rest(fd, poller, frame, written, timeout_s)


def stream_bytes_per_s(rate_hz: int, batch_s: float = p.BATCH_S) -> float:
    """Bytes a second a stream of ``rate_hz`` setpoints costs in frames of ``batch_s`` seconds (docs/protocol.md,
    byte budget): each frame 19 bytes of framing and 2 a value."""
    return p.FRAME_OVERHEAD_BYTES / batch_s + 2.0 * rate_hz


def check_link_budget(port: str, baud: int, rate_hz: int) -> None:
    """DeviceError (one line, naming the baud rate needed) unless a ``baud`` UART (8N1: ten bits a byte) carries
    ``rate_hz`` setpoints a second in 2 ms frames."""
    needed = stream_bytes_per_s(rate_hz)
    if needed <= baud / 10.0:
        return
    fastest = max(0, int((baud / 10.0 - p.FRAME_OVERHEAD_BYTES / p.BATCH_S) / 2.0))
    minimum = int(math.ceil(needed * 10.0))
    standard = next((b for b in STANDARD_BAUDS if b >= minimum), None)
    advice = f"open it at {standard} baud (serial:{port}?baud={standard})" if standard else \
        "use USB CDC or a faster link, or a lower rate"
    raise DeviceError(f"serial port {port} at {baud} baud carries at most {fastest} setpoints/s (docs/protocol.md, "
                      f"byte budget), not {rate_hz}: the stream needs {minimum} baud; {advice}")


@dataclass
class SerialCounters:
    frames_sent: int = 0
    setpoints_sent: int = 0
    setpoints_discarded: int = 0  # pulled while disconnected
    setpoints_skipped: int = 0  # skipped after a host stall (re-anchoring): the device counts them lost
    disconnects: int = 0
    reconnects: int = 0
    silences: int = 0  # device stopped answering
    bad_frames: int = 0  # received frames that did not decode
    late_batches: int = 0
    naks: int = 0  # frames the device refused
    carrier_changes: int = 0  # SET_CARRIER sent while streaming (sweep or tracking)
    send_stalls: int = 0  # the writer sent nothing for longer than the device's watchdog timeout
    write_timeouts: int = 0  # a frame waited the write timeout for room: the device took nothing (hung or gone)
    host_stalls: int = 0  # the writer woke more than STALL_S late (the host process did not run)
    late_frames: int = 0  # frames sent longer after the one before than the plate's buffer lasts (it may run dry)
    depth_corrections: int = 0  # the plate's buffer (v3 telemetry) drifted from its depth: the lead moved
    idle_rests: int = 0  # the stream stopped and the output disabled while the drive was zero
    idle_wakes: int = 0  # ... and enabled again by a non-zero drive
    reenables: int = 0  # ENABLE sent again: the plate's telemetry said it was off while the host streamed to it
    errors: list[str] = field(default_factory=list)


@dataclass
class Outage:
    """One loss of the plate: when (s into the run), why, when it came back, setpoints not sent meanwhile."""

    lost_s: float
    cause: str
    discarded_before: int
    back_s: float | None = None
    not_sent: int = 0
    last_error: str = ""


@dataclass(frozen=True)
class Pacing:
    """How a stream of ``rate_hz`` setpoints is paced: frames of ``batch`` values, kept ``lead`` values ahead of
    the host's clock (the device's prefill plus a frame)."""

    rate_hz: int
    batch: int
    lead: int

    @classmethod
    def of(cls, rate_hz: int, batch_s: float) -> Pacing:
        batch = max(1, int(round(batch_s * rate_hz)))
        return cls(rate_hz, batch, int(math.ceil(p.PREFILL_MS * rate_hz / 1000.0)) + batch)

    @property
    def buffer_lasts_s(self) -> float:
        """How long the plate's buffer lasts after a frame (s): the lead, less a frame's time between frames and
        one more for the link's latency. A frame sent later than that after the one before is late: the plate
        may have run dry. (A simulated plate on a pty beside two CPU hogs held 1.3 ms less than the lead when a
        frame arrived, and ran dry after a gap of 9.7 ms that a margin of one frame called on time.)"""
        return (self.lead - 2 * self.batch) / self.rate_hz


# ---- which stream fits the link -------------------------------------------------------------------------------
FRAME_CHOICES_S = (0.001, 0.002, 0.004)  # the frames the host chooses among, shortest first: a longer one leaves
# less of the plate's 10 ms prefill between two frames (Pacing.buffer_lasts_s: 6 ms at 4 ms frames, 2 ms at 8)
LOWEST_RATE_HZ = 1000  # the slowest stream a serial URL may ask for (devices/urls.py), and the host chooses


@dataclass(frozen=True)
class StreamPlan:
    """The stream the host sends a plate driver: ``rate_hz`` setpoints a second in frames of ``batch_s`` seconds;
    what the device's link carries (bytes/s, 0: not stated) and who chose the stream: ``device`` (fitted to what
    the device stated in its handshake), ``url`` (the URL's ``rate`` and ``frame_ms``, or one of them and the rest
    fitted) or ``default`` (the device states nothing: the host's default)."""

    rate_hz: int
    batch_s: float
    link_bytes_per_s: int
    chosen_by: str
    protocol_version: int = p.PROTOCOL_VERSION

    @property
    def bytes_per_s(self) -> float:
        """What the stream costs on the wire (bytes/s)."""
        return stream_bytes_per_s(self.rate_hz, self.batch_s)

    def line(self, port: str) -> str:
        """The stream in one line, and why it is this one."""
        head = f"stream: {self.rate_hz} setpoints/s in {self.batch_s * 1000:g} ms frames"
        cost = f"{self.bytes_per_s / 1000:.1f} kB/s"
        if self.chosen_by == "default":
            missing = "speaks protocol v2, which has no place to" if self.protocol_version < 3 else "does not"
            return (f"{head} ({cost}), the default: the plate driver {missing} say what its link carries; if the "
                    f"plate is lost, ask for a slower stream, e.g. serial:{port}?rate=1000&frame_ms=4")
        carries = f"the {self.link_bytes_per_s / 1000:.1f} kB/s the plate driver's link carries, as its handshake says"
        if self.chosen_by == "url":
            of = f"of {carries}" if self.link_bytes_per_s else "(the plate driver does not say what its link carries)"
            return f"{head} as the device URL asks, {cost} {of}"
        return f"{head}, {cost}: fitted to at most {p.LINK_MARGIN:.0%} of {carries}"

    def as_dict(self) -> dict:
        return {"rate_hz": self.rate_hz, "frame_ms": round(self.batch_s * 1000, 3),
                "bytes_per_s": round(self.bytes_per_s, 1), "link_bytes_per_s": self.link_bytes_per_s or None,
                "chosen_by": self.chosen_by}


def choose_stream(port: str, hello: p.HelloReply, control_rate_hz: int, baud: int, rate_hz: int | None = None,
                  batch_s: float | None = None) -> StreamPlan:
    """The stream for a plate driver that answered ``hello``: what the URL asks (``rate_hz``, ``batch_s``; None:
    not asked) where it fits, else the fastest rate (a whole fraction of ``control_rate_hz``, within what the device
    plays) in the shortest frame (1, 2 or 4 ms) that takes at most half (:data:`LINK_MARGIN`) of what the device
    says its link carries (and, on a UART, of ``baud``). A device that says nothing gets the host's default.

    Parameters
    ----------
    port : str
        The port, for the messages.
    hello : HelloReply
        The device's answer to HELLO.
    control_rate_hz : int
        The renderer's rate (setpoints/s): a stream's rate divides it.
    baud : int
        The UART's baud rate (8N1: ten bits a byte); ignored for a URL transport (``loop://``).
    rate_hz, batch_s : int, float, optional
        What the device URL asks: setpoints/s, and seconds between frames.

    Returns
    -------
    StreamPlan

    Raises
    ------
    DeviceError
        No stream fits what the link carries (one line, saying what would), or the URL's does not.

    Examples
    --------
    >>> hello = p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "board",
    ...                      features=p.FEATURE_LINK_STATED, link_bytes_per_s=14000, q=200.0)
    >>> plan = choose_stream("/dev/pts/3", hello, 12000, 921600)
    >>> plan.rate_hz, plan.batch_s, plan.bytes_per_s      # 6 750 bytes/s: within half of 14 000
    (1000, 0.004, 6750.0)
    """
    asked = rate_hz is not None or batch_s is not None
    if not hello.states_link:
        rate = rate_hz or control_rate_hz
        return StreamPlan(rate, batch_s or p.batch_s_for(baud, rate), 0, "url" if rate_hz and batch_s else "default",
                          hello.version)
    capacity = hello.link_bytes_per_s
    if "://" not in port:
        capacity = min(capacity, baud // 10)
    rates = [rate_hz] if rate_hz else [control_rate_hz // k for k in range(1, control_rate_hz // LOWEST_RATE_HZ + 1)
                                       if control_rate_hz % k == 0 and control_rate_hz // k >= LOWEST_RATE_HZ]
    rates = [rate for rate in rates if hello.min_setpoint_rate_hz <= rate <= hello.max_setpoint_rate_hz] or rates
    frames = [batch_s] if batch_s else list(FRAME_CHOICES_S)
    # the host's own choice keeps half the link free; what the URL asks may take all of it
    for budget in (p.LINK_MARGIN * capacity, capacity) if asked else (p.LINK_MARGIN * capacity,):
        for rate in rates:
            for frame in frames:
                if stream_bytes_per_s(rate, frame) <= budget:
                    return StreamPlan(rate, frame, hello.link_bytes_per_s, "url" if asked else "device")
    slowest = min(stream_bytes_per_s(rate, frame) for rate in rates for frame in frames)
    if asked:
        raise DeviceError(f"serial:{port}: the plate driver's link carries {capacity} bytes/s (its handshake says); "
                          f"the stream the URL asks needs at least {slowest:.0f}: ask for less (rate=, frame_ms=), or "
                          "leave both out and the host fits the stream to the link")
    raise DeviceError(f"serial:{port}: the plate driver's link carries {capacity} bytes/s (its handshake says); the "
                      f"slowest stream the host sends needs {slowest:.0f} with half the link kept free: use a faster "
                      "link")


def probe_hello(port: str, baudrate: int, timeout_s: float = p.HOST_ACK_TIMEOUT_S) -> bytes:
    """Open ``port`` (exclusively), send HELLO, and return the device's HELLO_REPLY payload, unchecked; the port is
    closed again. HELLO changes nothing on the device but the session's version (R-HELLO-NO-STATE).

    Raises
    ------
    DeviceError
        The port cannot be opened, the device refuses HELLO or says nothing within ``timeout_s`` (one line).
    """
    import serial

    opened = open_port(port, baudrate)
    try:
        opened.reset_input_buffer()
        FrameWriter(opened, opened.write_timeout).write(p.encode_frame(p.HELLO, 0, p.hello_payload()))  # no poll
        decoder = p.FrameDecoder()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for frame in decoder.feed(opened.read(max(1, opened.in_waiting))):
                if frame.kind == p.HELLO_REPLY:
                    return frame.payload
                if frame.kind == p.NAK and len(frame.payload) >= 3 and int.from_bytes(frame.payload[:2], "little") == 0:
                    reason = p.NAK_REASONS.get(frame.payload[2], f"reason {frame.payload[2]}")
                    raise DeviceError(f"{port}: the plate driver refused the handshake (HELLO: {reason}); it does "
                                      f"not speak ultraglide protocol v{p.PROTOCOL_VERSION} as docs/protocol.md "
                                      "describes")
    except (serial.SerialException, OSError) as error:
        raise DeviceError(f"{port}: {port_failure(error)} during the handshake") from None
    finally:
        opened.close()
    raise DeviceError(f"{port}: no answer to the handshake; is a plate driver there, speaking ultraglide protocol "
                      f"v{p.PROTOCOL_VERSION}?")
