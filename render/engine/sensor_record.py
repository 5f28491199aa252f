"""The plate's sensor samples, recorded to CSV as they arrive (``play --sensors-csv``).

One row per sensor sample: ``sample`` (the device's sensor sample number: on the simulated plate, sample j
covers the plate's time from j to j + 1 sensor periods after it started, the clock its finger log keeps),
``setpoint_index`` (the stream index playing at that sample's start; -1 when none played), ``received_s``
(perf_counter s the frame was read), ``amplitude_um_pp``, ``normal_force_n``, ``lateral_force_n``. The rows
line a plate's truth up with what the host sent, underruns and all: the envelope CSV names each value's
stream index. Frames are queued by the device's reader thread and written by a thread of this record's own.
"""

from __future__ import annotations

import os
import queue
import threading
import time

import numpy as np
from ultraglide.render.engine.csv_record import CsvRecord

COLUMNS = ("sample", "setpoint_index", "received_s", "amplitude_um_pp", "normal_force_n", "lateral_force_n")
NOT_PLAYING = 0xFFFFFFFF
MAX_QUEUED = 10_000  # frames (100 s at 100 a second): beyond, they are counted as lost
FORMAT = ("%d", "%d", "%.6f", "%.5f", "%.5f", "%.5f")


class SensorRecord(CsvRecord):
    """See the module docstring. ``stream_per_sample``: stream values played per sensor sample (12 at 12 kHz
    setpoints and 1 kHz sensors).

    Parameters
    ----------
    path : str or path-like
        The CSV file written (``FILE.part`` until closed).
    stream_per_sample : float
        Stream values played per sensor sample.

    Examples
    --------
    A SENSORS frame of two samples, packed and parsed as the wire carries it, recorded and read back:

    >>> import csv, pathlib, tempfile
    >>> from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
    >>> frame = parse_sensors(sensors_payload(40, 480, sensor_samples([3.0, 3.2], [0.5, 0.6], [0.2, 0.25])))
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "sensors.csv"
    >>> record = SensorRecord(path, stream_per_sample=12.0)
    >>> record.take(frame, received_s=1.0)
    >>> record.close() is None
    True
    >>> [(row["sample"], row["setpoint_index"], row["normal_force_n"]) for row in csv.DictReader(path.open())]
    [('40', '480', '0.50000'), ('41', '492', '0.60000')]
    """

    def __init__(self, path: str | os.PathLike, stream_per_sample: float):
        super().__init__(path, COLUMNS)
        self.stream_per_sample = stream_per_sample
        self._queue: queue.Queue = queue.Queue(MAX_QUEUED)
        self._thread = threading.Thread(target=self._write_loop, name="sensor-record", daemon=True)
        self._thread.start()

    def take(self, frame, received_s: float | None = None) -> None:
        """A decoded SENSORS frame (the reader thread: queued, never waits); ``received_s`` perf_counter s (default:
        now).

        Parameters
        ----------
        frame : SensorsFrame
            A decoded SENSORS frame.
        received_s : float, optional
            When it arrived, perf_counter s.

        Examples
        --------
        Two frames of one sample each, logged in order:

        >>> import csv, pathlib, tempfile
        >>> from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "sensors.csv"
        >>> record = SensorRecord(path, stream_per_sample=12.0)
        >>> for sample, force in ((10, 0.4), (11, 0.45)):
        ...     record.take(parse_sensors(sensors_payload(sample, 12 * sample, sensor_samples([3.0], [force], [0.2]))))
        >>> record.close() is None
        True
        >>> [(row["sample"], row["normal_force_n"]) for row in csv.DictReader(path.open())]
        [('10', '0.40000'), ('11', '0.45000')]
        """
        if received_s is None:
            received_s = time.perf_counter()
        try:
            self._queue.put_nowait((frame, received_s))
        except queue.Full:
            self.dropped += 1

    def _write_loop(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            self._write(*item)

    def _write(self, frame, received_s: float) -> None:
        if self.error is not None:
            return
        samples = frame.samples
        n = len(samples)
        steps = np.arange(n)
        index = np.full(n, -1.0) if frame.setpoint_index == NOT_PLAYING else \
            frame.setpoint_index + np.round(steps * self.stream_per_sample)
        rows = np.column_stack((frame.first_sample + steps, index, np.full(n, received_s),
                                samples["amplitude_um_pp"], samples["normal_force_n"], samples["lateral_force_n"]))
        self._write_rows(rows, FORMAT)

    def _stop_writer(self, finish: bool) -> None:  # the writer writes what is queued before the None either way
        self._queue.put(None)
        self._thread.join(timeout=10)
