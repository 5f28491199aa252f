"""What the host does for a device whose driver's process was lost (killed, or frozen and then killed).

The engine (:mod:`ultraglide.render.engine`) drives the device from a process of its own. When that process dies
or freezes, nothing in it can rest the hardware any more; the app that started it (its supervisor,
:mod:`ultraglide.render.engine.supervisor`) makes the device safe from outside, once the process is gone:

* a plate on a serial link gets ENABLE 0 (:func:`disable_serial_plate`): the port, which the dead process held
  exclusively, is opened again and the disable frame of docs/protocol.md sent, its ACK awaited briefly. A
  frozen process still holds its port: its open file is borrowed before it is killed (:func:`borrow_port`,
  Linux's ``pidfd_getfd``), and ENABLE 0 goes out on it at once (:class:`BorrowedPort`) instead of after the
  killed process's memory is torn down and its files closed (15-60 ms);
* a WAV recording left as its hidden temporary file is finished (:func:`finish_recording`): its header made to
  say how many samples it holds, and renamed into place, as a recording stopped by a signal is kept;
* a CSV log left as ``FILE.part`` is finished the same way (:func:`finish_log`): cut after its last whole row.

Each returns a sentence for the run's report. None raises: the hardware's rest is best effort on the way out,
and what failed is said.

The disable is sent after a 0x00: the lost process may have been cut off in the middle of a frame, and the
plate's decoder would otherwise take that frame's first half and the disable as one frame, fail its CRC and
drop both (docs/protocol.md: a run of 0x00 is idle line).

Example::

    words = disable_serial_plate("/dev/ttyACM0", 2_000_000)   # "the plate was disabled (ENABLE 0 acknowledged)"
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import select
import stat
import struct
import termios
import time
from collections.abc import Callable
from pathlib import Path

from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError

ACK_WAIT_S = 0.25  # how long the disable's ACK is waited for (the device answers within ACK_DEADLINE_MS = 50 ms)
DISABLE_SEQ = 0xFFF0  # the disable's sequence number (any: the ACK names it back)
WRITE_WAIT_S = 0.2  # the longest wait for the port to take the disable frame
SYS_PIDFD_GETFD = 438  # pidfd_getfd(2)'s number, the same on every Linux architecture (since 5.6)
_RIFF = struct.Struct("<4sI4s")
_CHUNK = struct.Struct("<4sI")


def disable_frame() -> bytes:
    """The bytes that disable a plate whatever its decoder holds: a 0x00 (ending any frame the lost process left
    half-written, which the plate then drops as one framing error) and ENABLE 0 (docs/protocol.md, Enable).

    Returns
    -------
    bytes
        0x00, then the encoded ENABLE 0 frame with its own 0x00 terminator.

    Examples
    --------
    >>> from ultraglide.devices import protocol as p
    >>> frame = disable_frame()
    >>> frame[:1], frame[-1:]
    (b'\\x00', b'\\x00')
    >>> decoded = p.FrameDecoder().feed(b"\\x05half" + frame)   # half a frame before it: the disable still decodes
    >>> [(f.kind == p.ENABLE, f.payload == p.enable_payload(False)) for f in decoded]
    [(True, True)]
    """
    return b"\x00" + p.encode_frame(p.ENABLE, DISABLE_SEQ, p.enable_payload(False))


def disable_serial_plate(port: str, baud: int, wait_ack_s: float = ACK_WAIT_S) -> str:
    """Send ENABLE 0 to the plate on ``port`` (a path or any pyserial URL, at ``baud``) and wait up to
    ``wait_ack_s`` for its ACK. The plate drops its drive to zero within 1 ms of the frame (docs/protocol.md,
    Enable), whatever its session. Returns what happened in words; never raises.

    Parameters
    ----------
    port : str
        The serial port the lost process drove.
    baud : int
        Its baud rate.
    wait_ack_s : float
        The longest wait for the plate's ACK, s.

    Returns
    -------
    str
        ``"ENABLE 0 acknowledged by the plate 4 ms after"``, or what went wrong.

    Examples
    --------
    Nothing at the path: said, not raised.

    >>> disable_serial_plate("/nonexistent/ttyACM9", 921600).startswith("the plate could not be disabled")
    True
    """
    from ultraglide.devices.serial.link import FrameWriter, open_port

    sent_s = None
    try:
        link = open_port(port, baud, write_timeout_s=WRITE_WAIT_S)
    except DeviceError as error:
        return f"the plate could not be disabled ({error}); its own watchdog rests it"
    try:
        link.reset_input_buffer()
        FrameWriter(link, WRITE_WAIT_S).write(disable_frame())  # as the engine writes: no poll after it
        sent_s = time.perf_counter()
        link.timeout = 0.01
        return "ENABLE 0 sent" + _awaited_ack(lambda: link.read(256), sent_s, wait_ack_s)
    except Exception as error:  # noqa: BLE001 - pyserial's errors are many; the words matter, not the type
        if sent_s is not None:
            return f"ENABLE 0 sent; then the port failed ({error})"
        return f"the plate could not be disabled (the port failed: {error}); its own watchdog rests it"
    finally:
        with contextlib.suppress(Exception):
            link.close()


def _awaited_ack(read: Callable[[], bytes], sent_s: float, wait_ack_s: float) -> str:
    """The end of the disable's sentence: the plate's ACK of it (or NAK) read with ``read`` (a few ms a call) until
    ``wait_ack_s`` after ``sent_s``."""
    decoder = p.FrameDecoder()
    deadline = sent_s + wait_ack_s
    while time.perf_counter() < deadline:
        for frame in decoder.feed(read()):
            if frame.kind == p.ACK and _acked(frame.payload) == DISABLE_SEQ:
                return f" and acknowledged by the plate {1000 * (time.perf_counter() - sent_s):.0f} ms after"
            if frame.kind == p.NAK:
                return "; the plate refused it (NAK): its own watchdog rests it"
    return f"; no acknowledgement within {1000 * wait_ack_s:.0f} ms"


def borrow_port(url: str, pid: int) -> BorrowedPort | None:
    """The serial port of the device at ``url`` as process ``pid`` holds it open, taken into this process
    (``pidfd_getfd``: the same open file, its settings and its lock), or None: not a serial device, not a port
    this process can find among ``pid``'s files, or a kernel or sandbox that refuses (then the port is opened again
    once ``pid`` has ended, :func:`disable_serial_plate`).

    Parameters
    ----------
    url : str
        The device URL ``pid`` opened (``serial:PATH``).
    pid : int
        The process holding the port: a child of this one, still there (stopped or running).

    Returns
    -------
    BorrowedPort or None

    Examples
    --------
    Only a serial plate's port is borrowed:

    >>> import os
    >>> print(borrow_port("sim", os.getpid()))
    None
    """
    from ultraglide.devices.urls import parse_device_url

    try:
        spec = parse_device_url(url)
        wanted = os.stat(spec.target) if spec.kind == "serial" else None
    except (DeviceError, OSError, ValueError):
        return None
    if wanted is None or not stat.S_ISCHR(wanted.st_mode):
        return None
    try:
        entries = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return None
    for entry in entries:
        try:
            held = os.stat(f"/proc/{pid}/fd/{entry}")
        except OSError:
            continue
        if stat.S_ISCHR(held.st_mode) and held.st_rdev == wanted.st_rdev:
            fd = _fd_of(pid, int(entry))
            return None if fd is None else BorrowedPort(fd)
    return None


def _fd_of(pid: int, target_fd: int) -> int | None:
    """A duplicate in this process of file descriptor ``target_fd`` of process ``pid`` (close-on-exec), or None."""
    try:
        pidfd = os.pidfd_open(pid)
    except (OSError, AttributeError):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fd = libc.syscall(SYS_PIDFD_GETFD, pidfd, target_fd, 0)
        return fd if fd >= 0 else None
    except (OSError, AttributeError):
        return None
    finally:
        os.close(pidfd)


class BorrowedPort:
    """A lost process's serial port, taken from it (:func:`borrow_port`): the disable goes out on it while that
    process is still being killed, and the ACK is read once it has ended (its reader could take the ACK before).

    Parameters
    ----------
    fd : int
        This process's file descriptor for the port (closed by :meth:`finish`).

    Examples
    --------
    On a pseudo-terminal standing in for a plate's port (the plate is silent: no ACK):

    >>> import os, pty, tty
    >>> plate_end, port_end = pty.openpty()
    >>> tty.setraw(port_end)                  # as a serial port's driver sets it: bytes pass as they are
    >>> borrowed = BorrowedPort(port_end)
    >>> borrowed.send()
    >>> os.read(plate_end, 64) == disable_frame()
    True
    >>> borrowed.finish(wait_ack_s=0.02)
    "ENABLE 0 sent on the frozen engine's own port before its end; no acknowledgement within 20 ms"
    >>> os.close(plate_end)
    """

    def __init__(self, fd: int):
        self.fd = fd
        self.sent_s: float | None = None
        self.failure: str | None = None

    def send(self) -> None:
        """Write the disable (:func:`disable_frame`) on the port, within ``WRITE_WAIT_S``; never raises. Written at
        once as the engine's writer does (:func:`.serial.link.write_frame_fd`): the port is polled for room only if
        the kernel took part of the frame (a poll of a terminal waits for its flip-buffer work, on a kworker at
        ordinary priority)."""
        import serial
        from ultraglide.devices.serial.link import write_frame_fd

        try:
            with contextlib.suppress(termios.error):
                termios.tcflush(self.fd, termios.TCIFLUSH)  # what the lost process had not read: not the ACK
            write_frame_fd(self.fd, disable_frame(), WRITE_WAIT_S)
            self.sent_s = time.perf_counter()
        except serial.SerialTimeoutException:
            self.failure = f"the port took no byte for {1000 * WRITE_WAIT_S:.0f} ms"
        except (serial.SerialException, OSError) as error:
            self.failure = str(getattr(error, "strerror", None) or error)

    def finish(self, wait_ack_s: float = ACK_WAIT_S) -> str:
        """The disable's ACK awaited (until ``wait_ack_s`` after it was sent), the port closed; what happened in
        words. Never raises."""
        try:
            if self.sent_s is None:
                return (f"the plate could not be disabled (its port failed: {self.failure}); its own watchdog "
                        "rests it")

            def read() -> bytes:
                if select.select([self.fd], [], [], 0.01)[0]:
                    return os.read(self.fd, 256)
                return b""

            return ("ENABLE 0 sent on the frozen engine's own port before its end" +
                    _awaited_ack(read, self.sent_s, wait_ack_s))
        except OSError as error:
            return f"ENABLE 0 sent; then the port failed ({error.strerror or error})"
        finally:
            with contextlib.suppress(OSError):
                os.close(self.fd)


def _acked(payload: bytes) -> int | None:
    try:
        return p.parse_ack(payload)
    except (ValueError, struct.error):
        return None


def leftover_of(path: str | Path, pid: int) -> Path | None:
    """The hidden temporary file (``ultraglide.atomic``'s naming) that process ``pid`` was writing for
    ``path``, if it is there (the newest, if several)."""
    target = Path(os.path.realpath(path))
    pattern = re.compile(rf"^\.{re.escape(target.stem)}\.ultraglide-{pid}-[0-9a-f]{{6}}-[a-z0-9_]{{8}}"
                         rf"{re.escape(target.suffix)}$")
    try:
        found = [entry for entry in os.scandir(target.parent) if pattern.match(entry.name)
                 and entry.is_file(follow_symlinks=False)]
    except OSError:
        return None
    return Path(max(found, key=lambda entry: entry.stat().st_mtime).path) if found else None


def finish_recording(path: str | Path, pid: int) -> str:
    """Finish the WAV recording that process ``pid`` (the lost engine) was writing for ``path``: its hidden
    temporary file gets the sizes of what it holds (cut to whole samples) and is renamed into place; a file too
    damaged to finish is removed. Returns what happened in words; never raises.

    Parameters
    ----------
    path : str or Path
        The recording's path (``wav:PATH``).
    pid : int
        The process that wrote it.

    Returns
    -------
    str
        ``"the recording out.wav keeps the 4.02 s written before the engine was lost"``, or why it was removed.
    """
    temporary = leftover_of(path, pid)
    if temporary is None:
        return f"the recording {path} was not begun: nothing kept"
    try:
        seconds = _finish_wav(temporary)
        if seconds == 0.0:
            os.unlink(temporary)
            return f"the recording {path} had nothing in it: removed"
        target = Path(os.path.realpath(path))
        with contextlib.suppress(FileNotFoundError):
            if not stat.S_ISREG(os.lstat(target).st_mode):
                raise OSError(f"{path} became something other than a file")
        os.replace(temporary, target)
    except (OSError, ValueError) as error:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        return f"the recording {path} could not be finished ({error}): removed"
    return (f"the recording {path} keeps the {seconds:.2f} s written before the engine was lost (it ends there, "
            "abruptly)")


def _finish_wav(temporary: Path) -> float:
    """Make a WAV cut short (its writer killed) whole: the data chunk and the RIFF size say what the file holds,
    cut to whole frames; the fact chunk's frame count too. Returns its length, s."""
    with open(temporary, "r+b") as handle:
        size = os.fstat(handle.fileno()).st_size
        riff, _, wave = _RIFF.unpack(handle.read(_RIFF.size))
        if riff != b"RIFF" or wave != b"WAVE":
            raise ValueError("not a RIFF WAVE file")
        offset, block_align, rate, fact_at, data_at = _RIFF.size, None, None, None, None
        while offset + _CHUNK.size <= size:
            handle.seek(offset)
            chunk, length = _CHUNK.unpack(handle.read(_CHUNK.size))
            if chunk == b"fmt ":
                _, channels, rate, _, block_align = struct.unpack("<HHIIH", handle.read(14))
            elif chunk == b"fact":
                fact_at = offset + _CHUNK.size
            elif chunk == b"data":
                data_at = offset + _CHUNK.size
                break
            offset += _CHUNK.size + length + (length & 1)
        if data_at is None or not block_align or not rate:
            raise ValueError("its header was never written whole")
        frames = (size - data_at) // block_align
        data_bytes = frames * block_align
        handle.truncate(data_at + data_bytes)
        handle.seek(data_at - 4)
        handle.write(struct.pack("<I", data_bytes))
        handle.seek(4)
        handle.write(struct.pack("<I", data_at + data_bytes - 8))
        if fact_at is not None:
            handle.seek(fact_at)
            handle.write(struct.pack("<I", frames))
        handle.flush()
        os.fsync(handle.fileno())
    return frames / rate


def finish_log(path: str | Path) -> str:
    """Finish a CSV log (``FILE.part``, :class:`ultraglide.atomic.AtomicFile`'s ``partial``) its lost writer left:
    cut after its last whole line and renamed to ``FILE``. Returns what happened in words; never raises."""
    target = Path(os.path.realpath(path))
    part = target.with_name(target.name + ".part")
    try:
        info = os.lstat(part)
    except FileNotFoundError:
        return f"{path}: nothing left to finish"
    except OSError as error:
        return f"{path}: could not be finished ({error.strerror})"
    if not stat.S_ISREG(info.st_mode):
        return f"{path}: its {part.name} is not a file: left alone"
    try:
        with open(part, "r+b") as handle:
            size = info.st_size
            handle.seek(max(0, size - 65536))
            tail = handle.read()
            cut = tail.rfind(b"\n")
            keep = size - len(tail) + cut + 1 if cut >= 0 else 0
            handle.truncate(keep)
        os.replace(part, target)
    except OSError as error:
        with contextlib.suppress(OSError):
            os.unlink(part)
        return f"{path}: could not be finished ({error.strerror or error}): removed"
    return f"{path} keeps the rows written before the engine was lost"


def rest_after_loss(url: str, pid: int, borrowed: BorrowedPort | None = None) -> list[str]:
    """Make the device at ``url`` (a device URL) safe after process ``pid``, which drove it, was lost; what was done,
    in sentences. Never raises.

    Parameters
    ----------
    url : str
        The device URL the lost process opened (sim, serial:PORT, audio, wav:PATH, null).
    pid : int
        The lost process (gone by now: its files are closed and its locks released).
    borrowed : BorrowedPort, optional
        Its serial port, taken from it before it was killed, the disable sent on it already (:func:`borrow_port`).

    Returns
    -------
    list of str
        One sentence per thing done (or found).
    """
    from ultraglide.devices.urls import parse_device_url

    try:
        spec = parse_device_url(url)
    except DeviceError as error:
        return [f"the device could not be named ({error})"]
    if spec.kind == "serial":
        if borrowed is not None:
            return [borrowed.finish()]
        return [disable_serial_plate(spec.target, spec.options.get("baud", 921600))]  # urls.open_device's default
    if spec.kind == "wav":
        return [finish_recording(spec.target, pid)]
    if spec.kind == "audio":
        return ["the audio stream ended with the engine's process (the sound card plays nothing more)"]
    if spec.kind == "sim":
        return ["the simulated plate ended with the engine's process"]
    return []
