"""Putting an export's limited envelope on the carrier and writing it to a WAV file, in a process of its own.

Export's work splits by what it depends on. The control-rate envelope is a recursion over Python
and numpy code that holds the interpreter lock; it runs in order on the caller's thread. Putting
each block on the carrier and writing it depends on nothing but the block (each frame's carrier
phase comes from its index), so a *writer process*, forked once the envelope's set-up is done,
does it on the other core: the envelope thread then never waits for the lock, and the two run
side by side. The caller sends each block's :class:`~ultraglide.devices.output.stage.Modulation`
(its limited knots, about 100 kB a second of audio) down a pipe; the writer renders it in
``threads`` chunks on a thread pool, writes the blocks in order and acknowledges the frames
written, which drives the progress bar. A pipe holds about one block, and the writer holds at
most ``IN_FLIGHT``: memory does not grow with the length.

Errors come back as they were raised (a full disk is libsndfile's error, as without the process).
The writer ignores Ctrl-C (a terminal sends it to the whole process group: the caller stops it),
dies by SIGTERM when the caller stops it, and ends when the caller's pipe closes, so it never
outlives a caller that was killed. Where ``fork`` is missing (not Linux) the same blocks are
written on threads of the calling process instead.

libsndfile syncs the file to disk when it is closed; the writer asks the kernel to start writing
each few blocks back as it goes (``posix_fadvise``), so that sync finds little left to do.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import traceback
import warnings
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import soundfile

from ultraglide.devices.output.stage import Modulation

IN_FLIGHT = 3  # blocks being put on the carrier or written, at most
WRITEBACK_EVERY = 4  # blocks written between requests to start writing the file back to disk
PIPE_BYTES = 1 << 20  # the most Linux lets a process ask for without privileges (/proc/sys/fs/pipe-max-size)
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


def chunk_bounds(frames: int, chunks: int) -> list[tuple[int, int]]:
    """``frames`` split into ``chunks`` nearly equal, consecutive (start, stop) ranges."""
    cuts = [round(i * frames / chunks) for i in range(chunks + 1)]
    return [(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def fork_available() -> bool:
    """Whether the writer can be a forked process (Linux; elsewhere fork is missing or unsafe)."""
    return sys.platform.startswith("linux") and hasattr(os, "fork")


class _Writeback:
    """Asks the kernel to start writing a file's dirty pages back to disk (no wait)."""

    def __init__(self, path: str):
        self.fd = None
        if hasattr(os, "posix_fadvise") and os.path.isfile(path):  # not a device or a pipe written directly
            self.fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)

    def start(self) -> None:
        if self.fd is not None:
            os.posix_fadvise(self.fd, 0, 0, os.POSIX_FADV_DONTNEED)  # starts writeback, drops clean pages

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def write_file(jobs: Iterable[Modulation], path: str, rate: int, subtype: str, container: str, threads: int,
               advance: Callable[[int], None], pool: bool = True) -> None:
    """Render ``jobs`` in order onto the carrier, ``threads`` chunks each, and write them to a WAV at ``path``;
    ``pool``: the chunks on a pool of threads and the writes on another while the caller makes the next
    job, else all in order on this thread (the writer process's way: it has a core to itself)."""
    with soundfile.SoundFile(path, "w", samplerate=rate, channels=1, subtype=subtype, format=container) as wav:
        writeback = _Writeback(path)
        try:
            if pool:
                _write_blocks(jobs, wav, threads, advance, writeback)
            else:
                for blocks, job in enumerate(jobs, 1):
                    out = np.empty(job.frames, dtype=np.float32)
                    for start, stop in chunk_bounds(job.frames, threads):
                        job.render(out, start, stop)
                    wav.write(out)
                    if blocks % WRITEBACK_EVERY == 0:
                        writeback.start()
                    advance(job.frames)
        finally:
            writeback.close()


def _write_blocks(jobs: Iterable[Modulation], wav, threads: int, advance, writeback: _Writeback) -> None:
    renderers = ThreadPoolExecutor(threads, thread_name_prefix="export-render")
    writer = ThreadPoolExecutor(1, thread_name_prefix="export-write")
    blocks = 0

    def write(out: np.ndarray, parts) -> int:
        nonlocal blocks
        for part in parts:
            part.result()
        wav.write(out)
        blocks += 1
        if blocks % WRITEBACK_EVERY == 0:
            writeback.start()
        return len(out)

    written: deque = deque()
    try:
        for job in jobs:
            out = np.empty(job.frames, dtype=np.float32)
            parts = [renderers.submit(job.render, out, start, stop)
                     for start, stop in chunk_bounds(job.frames, threads)]
            written.append(writer.submit(write, out, parts))
            while len(written) >= IN_FLIGHT or (written and written[0].done()):
                advance(written.popleft().result())
        while written:
            advance(written.popleft().result())
    finally:  # on an error or a stop signal: nothing more starts, and nothing runs on once this returns
        renderers.shutdown(wait=True, cancel_futures=True)
        writer.shutdown(wait=True, cancel_futures=True)


def write_in_process(jobs: Iterable[Modulation], path: str, rate: int, subtype: str, container: str, threads: int,
                     advance: Callable[[int], None]) -> None:
    """:func:`write_file` in a forked writer process, fed ``jobs`` as this thread makes them (see the module)."""
    import fcntl
    import multiprocessing

    context = multiprocessing.get_context("fork")
    jobs_in, jobs_out = context.Pipe(duplex=False)
    acks_in, acks_out = context.Pipe(duplex=False)
    writer = context.Process(target=_writer_main, name="ultraglide-export-writer", daemon=True,
                             args=(jobs_in, acks_out, (jobs_out, acks_in), path, rate, subtype, container, threads))
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)  # none lands between fork and the writer's own
    try:
        with warnings.catch_warnings():  # 3.12+ warns of forking with threads; the writer uses none it inherits
            warnings.simplefilter("ignore", DeprecationWarning)
            writer.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
    jobs_in.close()
    acks_out.close()
    with contextlib.suppress(OSError):  # a pipe that holds a few blocks: this thread seldom waits for the writer
        fcntl.fcntl(jobs_out.fileno(), getattr(fcntl, "F_SETPIPE_SZ", 1031), PIPE_BYTES)
    outcome: list = []

    def take_acks(wait: bool) -> None:
        while not outcome and (wait or acks_in.poll()):
            try:
                message = acks_in.recv()
            except EOFError:
                outcome.append(("died", writer))
                return
            if isinstance(message, int):
                advance(message)
            else:
                outcome.append(message)

    try:
        try:
            for job in jobs:
                jobs_out.send(job)
                take_acks(wait=False)
                if outcome:
                    break
            else:
                jobs_out.send(None)
        except BrokenPipeError:  # the writer stopped reading: its reason is in the acknowledgements
            pass
        take_acks(wait=True)
    finally:
        jobs_out.close()
        if writer.is_alive() and outcome[:1] != [("done",)]:
            writer.terminate()
        writer.join()
        acks_in.close()
    _raise_failure(outcome[0], writer)


def _raise_failure(message: tuple, writer) -> None:
    kind = message[0]
    if kind == "done":
        return
    if kind == "error":
        raise message[1]
    if kind == "bug":
        raise RuntimeError(f"the export's writer process failed:\n{message[1]}")
    raise RuntimeError(f"the export's writer process ended unexpectedly (exit code {writer.exitcode})")


def _writer_main(jobs_in, acks_out, parent_ends, path, rate, subtype, container, threads) -> None:
    for end in parent_ends:
        end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group; the caller stops us
    for signum in STOP_SIGNALS[1:]:
        signal.signal(signum, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)

    def received():
        while (job := jobs_in.recv()) is not None:
            yield job

    try:
        write_file(received(), path, rate, subtype, container, threads, acks_out.send, pool=False)
        outcome = ("done",)
    except (EOFError, BrokenPipeError):  # the caller has gone: nobody to tell
        return
    except (OSError, soundfile.LibsndfileError) as error:
        outcome = ("error", error)
    except BaseException:  # a bug: its traceback goes to the caller
        outcome = ("bug", traceback.format_exc())
    try:
        acks_out.send(outcome)
    except BrokenPipeError:
        pass
