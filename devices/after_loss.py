"""What the host does for a device whose driver's process was lost (killed, or frozen and then killed).

The engine (:mod:`ultraglide.render.engine`) drives the device from a process of its own. When that process dies
or freezes, nothing in it can rest the hardware any more; the app that started it (its supervisor,
:mod:`ultraglide.render.engine.supervisor`) makes the device safe from outside, once the process is gone:

* a plate on a serial link gets ENABLE 0 (:func:`disable_serial_plate`): the port, which the dead process held
  exclusively, is opened again and the disable frame of docs/protocol.md sent, its ACK awaited briefly;
* a WAV recording left as its hidden temporary file is finished (:func:`finish_recording`): its header made to
  say how many samples it holds, and renamed into place, as a recording stopped by a signal is kept;
* a CSV log left as ``FILE.part`` is finished the same way (:func:`finish_log`): cut after its last whole row.

Each returns a sentence for the run's report. None raises: the hardware's rest is best effort on the way out,
and what failed is said.

Example::

    words = disable_serial_plate("/dev/ttyACM0", 2_000_000)   # "the plate was disabled (ENABLE 0 acknowledged)"
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import struct
import time
from pathlib import Path

from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError

ACK_WAIT_S = 0.25  # how long the disable's ACK is waited for (the device answers within ACK_DEADLINE_MS = 50 ms)
_RIFF = struct.Struct("<4sI4s")
_CHUNK = struct.Struct("<4sI")


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
    """
    from ultraglide.devices.serial.link import open_port

    sent_s = None
    try:
        link = open_port(port, baud, write_timeout_s=0.2)
    except DeviceError as error:
        return f"the plate could not be disabled ({error}); its own watchdog rests it"
    try:
        seq = 0xFFF0  # any sequence number: the ACK names it back
        link.reset_input_buffer()
        link.write(p.encode_frame(p.ENABLE, seq, p.enable_payload(False)))
        link.flush()
        sent_s = time.perf_counter()
        decoder = p.FrameDecoder()
        deadline = sent_s + wait_ack_s
        link.timeout = 0.01
        while time.perf_counter() < deadline:
            for frame in decoder.feed(link.read(256)):
                if frame.kind == p.ACK and _acked(frame.payload) == seq:
                    after_ms = 1000 * (time.perf_counter() - sent_s)
                    return f"ENABLE 0 sent and acknowledged by the plate {after_ms:.0f} ms after"
                if frame.kind == p.NAK:
                    return "ENABLE 0 sent; the plate refused it (NAK): its own watchdog rests it"
        return f"ENABLE 0 sent; no acknowledgement within {1000 * wait_ack_s:.0f} ms"
    except Exception as error:  # noqa: BLE001 - pyserial's errors are many; the words matter, not the type
        if sent_s is not None:
            return f"ENABLE 0 sent; then the port failed ({error})"
        return f"the plate could not be disabled (the port failed: {error}); its own watchdog rests it"
    finally:
        with contextlib.suppress(Exception):
            link.close()


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


def rest_after_loss(url: str, pid: int) -> list[str]:
    """Make the device at ``url`` (a device URL) safe after process ``pid``, which drove it, was lost; what was done,
    in sentences. Never raises.

    Parameters
    ----------
    url : str
        The device URL the lost process opened (sim, serial:PORT, audio, wav:PATH, null).
    pid : int
        The lost process (gone by now: its files are closed and its locks released).

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
        return [disable_serial_plate(spec.target, spec.options.get("baud", 921600))]  # urls.open_device's default
    if spec.kind == "wav":
        return [finish_recording(spec.target, pid)]
    if spec.kind == "audio":
        return ["the audio stream ended with the engine's process (the sound card plays nothing more)"]
    if spec.kind == "sim":
        return ["the simulated plate ended with the engine's process"]
    return []
