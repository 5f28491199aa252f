"""The envelope record's times are when each value plays on the plate (issue 43), end to end.

A real ``play`` on the simulated plate (the firmware core on a pty) with ``--envelope-csv``, ``--sensors-csv`` and
``--finger-log``. The truth is the plate's own clock: the finger log's times are the simulator's sample clock on the
host's (sample 0 at its first row), and SENSORS' sample ``m`` (1 kHz) starts ``m`` ms after it with the stream index
``setpoint_index`` playing: where the index advances evenly (12 values a sample), index ``k`` plays at
``origin + m / 1000 + (k - setpoint_index) / 12000``. The play clock's contract (render/engine/play_clock.py): never
earlier than the truth (within a value's period: the index named is the one playing), later by no more than the
fastest SENSORS frame it looked at took beyond its bytes' time on the stated link, stalls and all.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import run_cli
from ultraglide.render.engine.envelope_record import PIECE_S, hold_s
from ultraglide.render.engine.play_clock import DRIFT_SPAN_S, WINDOW_S, PlayClock

RATE, SENSOR_RATE = 12000.0, 1000.0
LINK_BYTES_PER_S = 92160.0  # what the simulated plate states in its handshake (devices/sim/plate.py)
REGULAR = 10  # samples of a regular SENSORS frame (10 ms at 1 kHz)


def columns(path) -> dict[str, np.ndarray]:
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}


def frames_of(sensors: dict) -> list[np.ndarray]:
    """The SENSORS frames as the record shows them: consecutive samples read at one time."""
    breaks = np.flatnonzero((np.diff(sensors["received_s"]) != 0) | (np.diff(sensors["sample"]) != 1)) + 1
    return np.split(np.arange(len(sensors["sample"])), breaks)


@pytest.mark.slow
def test_the_envelope_records_times_are_when_the_plate_plays_each_value(tmp_path):
    envelope_csv, sensors_csv, finger_csv = tmp_path / "envelope.csv", tmp_path / "sensors.csv", tmp_path / "finger.csv"
    result = run_cli("play", "grating-1mm", "--device", "sim", "--duration-s", "5", "--envelope-csv", envelope_csv,
                     "--sensors-csv", sensors_csv, "--finger-log", finger_csv)
    assert result.returncode == 0, result.stderr
    envelope, sensors, finger = columns(envelope_csv), columns(sensors_csv), columns(finger_csv)
    origin = finger["t_s"][0]  # the plate's sample 0 on the host's clock
    start_s = origin + sensors["sample"] / SENSOR_RATE  # each sensor sample's start, by the plate's clock
    index = sensors["setpoint_index"]

    # each frame: when it was read and its delay beyond its bytes' time on the link
    frame_received, frame_excess = [], []
    for frame in frames_of(sensors):
        if index[frame[0]] < 0:
            continue
        # frames read at once show as one: beyond a frame and a sample, the last one's size is unknown (at least 1)
        wire_s = (18 + 12 * (min(len(frame), REGULAR) if len(frame) <= REGULAR + 1 else 1)) / LINK_BYTES_PER_S
        frame_received.append(sensors["received_s"][frame[0]])
        frame_excess.append(sensors["received_s"][frame[0]] - (start_s[frame[-1]] + 1 / SENSOR_RATE) - wire_s)
    frame_received, frame_excess = np.array(frame_received), np.array(frame_excess)
    assert len(frame_received) > 200  # 5 s of 10 ms frames (frames read at once show as one)
    assert frame_received[-1] - frame_received[0] < DRIFT_SPAN_S  # too short to take a drift: the plate has none

    # the truth of each row's index, where the index advanced evenly from 20 samples before its sample to 20 after
    # (the record's index within a frame is counted on from the one it names: where it stalled, the frames say
    # only between which samples)
    step = np.diff(index)
    even = np.flatnonzero((step == RATE / SENSOR_RATE) & (index[:-1] >= 0))
    uneven = np.flatnonzero(step != RATE / SENSOR_RATE)
    k = envelope["index"]
    at = np.searchsorted(index[even], k, side="right") - 1
    inside = (at >= 0) & (k < index[even[np.clip(at, 0, None)]] + RATE / SENSOR_RATE)
    rows = np.flatnonzero(inside)
    sample = even[at[rows]]
    place = np.searchsorted(uneven, sample)
    since = sample - uneven[np.clip(place - 1, 0, None)]
    until = uneven[np.clip(place, None, len(uneven) - 1)] - sample
    clear = ((since > 20) | (place == 0)) & ((until > 20) | (place == len(uneven)))
    rows, sample = rows[clear], sample[clear]
    assert len(rows) > 3 * RATE  # most of the 5 s (not the 20 ms about each stall)
    truth = start_s[sample] + (k[rows] - index[sample]) / RATE
    late = envelope["t_s"][rows] - truth
    assert late.min() > -1.0 / RATE - 1e-6  # never early
    ahead_s = hold_s(PlayClock(RATE))  # the frames read this long after a row had come when it was placed
    for row, row_late in zip(rows[::97], late[::97], strict=True):  # late by no more than the fastest frame it saw
        plan = envelope["plan_s"][row]
        seen = (frame_received >= plan - WINDOW_S + PIECE_S) & (frame_received <= plan + ahead_s - PIECE_S)
        assert row_late <= max(frame_excess[seen].min(), 0.0) + 1e-6
    # placed by the clock, not the plan (the plan keeps its own column; on this machine it was 0.6-5 ms early)
    assert np.mean(envelope["t_s"][rows] != envelope["plan_s"][rows]) > 0.99
