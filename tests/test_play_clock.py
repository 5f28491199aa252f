"""The play clock (render/engine/play_clock.py): when each stream index plays, from SENSORS frames' arrival.

Synthetic frames from a plate with a known clock: index k plays at host time ``origin + k (1 + drift) / rate``;
a frame of 10 samples (1 kHz) starts at index 120 f and is read a random, positive delay after its last sample.
The clock's origin must never be early (beyond what the drift's estimate allows) and late by no more than the
fastest frame's delay within its window.
"""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
from ultraglide.render.engine.play_clock import NOT_PLAYING, PlayClock

RATE, SENSOR_RATE, FRAME = 12000.0, 1000.0, 10  # Hz, Hz, samples a frame
PER_FRAME = int(RATE * FRAME / SENSOR_RATE)  # stream values a frame spans (120)


def plate_frames(seconds: float, delays, origin: float = 50.0, drift: float = 0.0, step_at_s=None, step_s=0.0):
    """(index, samples, received_s, delay_s) of each frame of a plate whose index k plays at
    origin + k (1 + drift) / RATE (+ step_s from step_at_s on: an underrun's stall)."""
    frames = []
    for f in range(int(seconds * SENSOR_RATE / FRAME)):
        index = PER_FRAME * f
        start = origin + index * (1 + drift) / RATE
        if step_at_s is not None and start - origin >= step_at_s:
            start += step_s
        last_sample_end = start + FRAME * (1 + drift) / SENSOR_RATE
        delay = float(delays[f])
        frames.append((index, FRAME, last_sample_end + delay, delay))
    return frames


def true_origin(at_s: float, origin: float = 50.0, drift: float = 0.0) -> float:
    """When index 0 would play by the plate's clock around ``at_s``: the index playing then, less its count."""
    index = (at_s - origin) * RATE / (1 + drift)
    return at_s - index / RATE


def test_without_drift_the_origin_is_never_early_and_late_by_the_fastest_frames_delay_in_its_window():
    rng = np.random.default_rng(3)
    delays = 0.2e-3 + rng.exponential(3e-3, 2000)  # every frame at least 0.2 ms late, most a few ms
    frames = plate_frames(20.0, delays)
    clock = PlayClock(RATE, SENSOR_RATE, window_s=2.0)
    for index, samples, received, _ in frames:
        clock.take(index, samples, received)
    received = np.array([frame[2] for frame in frames])
    delay = np.array([frame[3] for frame in frames])
    for at in np.arange(51.0, 69.0, 0.37):
        fastest = delay[np.abs(received - at) <= 1.0].min()
        late = clock.origin_s(at) - 50.0
        assert -2e-6 <= late <= fastest + 2e-6  # the drift's estimate (under 1 ppm of none here) moves bounds by µs
        assert late < 0.5e-3  # a fast frame comes within every 2 s here


def test_a_drifting_plate_is_followed_with_its_drift_estimated_from_the_lower_hull():
    rng = np.random.default_rng(4)
    drift = 80e-6  # the plate plays 80 ppm slower than the host counts: 1.6 ms over the 20 s
    frames = plate_frames(20.0, 0.1e-3 + rng.uniform(0.0, 4e-3, 2000), drift=drift)
    clock = PlayClock(RATE, SENSOR_RATE)
    for index, samples, received, _ in frames:
        clock.take(index, samples, received)
    assert clock.drift() == pytest.approx(drift, abs=5e-6)
    errors = [clock.origin_s(at) - true_origin(at, drift=drift) for at in np.arange(51.0, 69.0, 0.5)]
    assert min(errors) > -20e-6 and max(errors) < 0.3e-3  # never early beyond the drift's error; late < 0.3 ms


def test_without_drift_terms_a_drifting_plate_is_still_placed_within_its_windows_drift():
    rng = np.random.default_rng(5)
    drift = 50e-6
    frames = plate_frames(5.0, 0.1e-3 + rng.uniform(0.0, 2e-3, 500), drift=drift)  # under DRIFT_SPAN_S: no drift
    clock = PlayClock(RATE, SENSOR_RATE, window_s=2.0)
    for index, samples, received, _ in frames:
        clock.take(index, samples, received)
    assert clock.drift() == 0.0
    for at in (51.0, 52.5, 54.0):
        assert abs(clock.origin_s(at) - true_origin(at, drift=drift)) < 0.3e-3 + drift * 1.0


def test_after_a_stall_the_origin_moves_up_once_the_window_has_passed_it():
    rng = np.random.default_rng(6)
    frames = plate_frames(10.0, 0.1e-3 + rng.uniform(0.0, 1e-3, 1000), step_at_s=5.0, step_s=3e-3)
    clock = PlayClock(RATE, SENSOR_RATE, window_s=2.0)
    for index, samples, received, _ in frames:
        clock.take(index, samples, received)
    before, after = clock.origin_s(53.0) - 50.0, clock.origin_s(57.5) - 50.0
    assert 0.0 <= before < 0.3e-3  # the old clock
    assert 3e-3 <= after < 3.3e-3  # the new one, 3 ms later
    assert clock.origin_s(55.2) - 50.0 < 1e-3  # within the window of the stall: the earlier bound


def test_a_links_byte_time_is_taken_off_and_a_long_frame_counts_as_a_regular_one():
    # a 921 600-baud UART (92 160 bytes/s): a 10-sample frame's 138 bytes take 1.497 ms to cross it
    rng = np.random.default_rng(7)
    link = 92160.0
    wire = (18 + 12 * FRAME) / link
    frames = plate_frames(4.0, wire + 0.05e-3 + rng.uniform(0.0, 2e-3, 400))
    clock = PlayClock(RATE, SENSOR_RATE, link_bytes_per_s=link)
    for index, samples, received, _ in frames:
        clock.take(index, samples, received)
    late = clock.origin_s(52.0) - 50.0
    assert 0.0 <= late < 0.1e-3
    # a 60-sample frame (sent at once on a link that does not pace its bytes) is taken off a 10-sample frame's time
    clock = PlayClock(RATE, SENSOR_RATE, link_bytes_per_s=link)
    clock.take(0, 60, 50.0 + 0.060 + wire + 0.2e-3)
    assert clock.origin_s(50.0) - 50.0 == pytest.approx(0.2e-3, abs=1e-9)


def test_frames_while_nothing_plays_say_nothing_and_any_index_is_taken():
    clock = PlayClock(RATE, SENSOR_RATE)
    clock.take(NOT_PLAYING, FRAME, 10.0)
    clock.take(7, 0, 10.0)
    assert clock.frames == 0 and clock.origin_s(10.0) is None and clock.times_s(np.arange(3), 10.0) is None
    clock.take(NOT_PLAYING - 1, FRAME, 400000.0)  # an index near the wrap (4 days at 12 kHz) is an index
    assert clock.origin_s(400000.0) == pytest.approx(400000.0 - 0.01 - (NOT_PLAYING - 1) / RATE, abs=1e-6)


def test_a_packed_sensors_frame_places_the_indices_that_follow_it():
    clock = PlayClock(RATE, SENSOR_RATE)
    frame = parse_sensors(sensors_payload(1000, 24000, sensor_samples(np.full(FRAME, 3.0))))
    clock.take_frame(frame, 20.0105)  # 10 samples from index 24000 (2 s in), read 0.5 ms after the last
    times = clock.times_s(np.array([24000, 24012, 36000]), 20.0)
    np.testing.assert_allclose(times, [20.0005, 20.0015, 21.0005], atol=1e-9)


@pytest.mark.parametrize("kwargs", [{"stream_rate_hz": 0.0}, {"stream_rate_hz": RATE, "sensor_rate_hz": -1.0},
                                    {"stream_rate_hz": RATE, "window_s": 0.0},
                                    {"stream_rate_hz": RATE, "link_bytes_per_s": -5.0}])
def test_a_clock_that_cannot_be_is_refused(kwargs):
    with pytest.raises(ValueError, match="play clock"):
        PlayClock(**kwargs)
