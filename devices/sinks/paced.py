"""Devices that consume in real time without hardware: a WAV recorder and a null sink.

A thread pulls blocks at the pace of the wall clock, as a sound card would, from the output stage
(the limiter, then the carrier) that wraps its source, so what they record is what a plate would
get, with the same timing and the same live input.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.source import BlockSource, ramp_down
from ultraglide.devices.output.stage import output_stage
from ultraglide.devices.profiles import PlateProfile

from ultraglide.atomic import AtomicFile, write_failure

BLOCK_S = 0.005


class PacedSink:
    """Pulls ``rate_hz`` values a second from a source in small blocks; hands them to ``consume``."""

    signal = "audio"

    def __init__(self, profile: PlateProfile, rate_hz: int = 96000, name: str = "null",
                 carrier_hz: float | None = None):
        self.profile = profile
        self.rate_hz = rate_hz
        self.name = name
        self.carrier_hz = carrier_hz or profile.resonance_hz
        profile.check_carrier(self.carrier_hz)
        self.blocks = 0
        self.late_blocks = 0
        self.errors: list[str] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._source: BlockSource | None = None

    def consume(self, block: np.ndarray) -> None:
        """What to do with each block; the null sink drops it."""

    def start(self, source: BlockSource) -> None:
        """Consume ``source``'s drive envelope (µm p-p) through the limiter and the carrier."""
        self._source = output_stage(source, self.profile, self.signal, self.rate_hz, self.carrier_hz)
        self._thread = threading.Thread(target=self._run, name=f"{self.name}-sink", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        started = time.perf_counter()
        done = 0
        block = max(1, int(BLOCK_S * self.rate_hz))
        try:
            while not self._stop.is_set():
                now = time.perf_counter()
                due = int((now - started) * self.rate_hz) - done
                if due < block:
                    time.sleep((done + block) / self.rate_hz - (now - started))
                    continue
                if due > 4 * block:
                    self.late_blocks += 1
                self.consume(np.asarray(self._source.pull(due, now), dtype=np.float32))
                done += due
                self.blocks += 1
                if self._source.finished:
                    break
        except Exception as error:  # noqa: BLE001 - reported by status(), the recording is kept
            self.errors.append(f"{type(error).__name__}: {error}")

    def stop(self) -> None:
        if self._thread is not None and self._thread.is_alive():
            ramp_down(self._source, self._thread.is_alive)
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self.close()

    def close(self) -> None:
        """Release what the sink holds."""

    def status(self) -> dict:
        return {"device": self.name, "rate_hz": self.rate_hz, "blocks": self.blocks,
                "late_blocks": self.late_blocks, "errors": self.errors[:5]}


class WavRecorder(PacedSink):
    """``wav:PATH``: records in real time what a plate would get; the file appears, whole, at stop.

    The recording goes to a hidden temporary file beside PATH (:class:`AtomicFile`), renamed into
    place by :meth:`close`. If a write fails (a full disk, a file too large) the recording stops,
    the temporary file is removed and :meth:`close` raises the system's OSError naming PATH."""

    def __init__(self, path: str | Path, profile: PlateProfile, rate_hz: int = 96000, carrier_hz: float | None = None):
        super().__init__(profile, rate_hz, f"wav:{path}", carrier_hz)
        import soundfile

        self.path = Path(path)
        if self.path.suffix.lower() != ".wav":
            raise DeviceError(f"wav device path must end in .wav, got {self.path}")
        directory = self.path.parent if str(self.path.parent) else Path(".")
        if not directory.is_dir():
            raise DeviceError(f"wav device: no directory {directory}")
        self._target = AtomicFile(self.path)
        self._write_error: Exception | None = None
        self._failed = soundfile.LibsndfileError
        try:
            self._file = soundfile.SoundFile(self._target.temporary, "w", samplerate=rate_hz, channels=1,
                                             subtype="FLOAT")
        except self._failed as error:  # its header written at once: a full disk (a copy of /dev/full) fails here
            self._target.discard()
            raise write_failure(self.path, self._target.temporary, error) from None
        except BaseException:
            self._target.discard()
            raise

    def consume(self, block: np.ndarray) -> None:
        try:
            self._file.write(block)
        except self._failed as error:  # the pacing thread stops here; close() reports it
            self._write_error = error
            raise

    def close(self) -> None:
        if self._file is None:
            return
        if self._source is None:  # never started: a recording of nothing is no recording
            self.discard()
            return
        file, self._file = self._file, None
        try:
            file.close()
        except self._failed as error:
            self._write_error = self._write_error or error
        if self._write_error is not None:
            failure = write_failure(self.path, self._target.temporary, self._write_error)
            self._target.discard()
            raise failure
        self._target.commit()

    def discard(self) -> None:
        """Drop the recording (an error before anything worth keeping)."""
        if self._file is not None:
            self._file.close()
            self._file = None
        self._target.discard()
