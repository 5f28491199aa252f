"""The play clock (render/engine/play_clock.py): when each stream index plays, from SENSORS frames' arrival.

Synthetic plates with a known clock: the device's sample m (1 kHz) is taken at host time ``A + m (1 + drift) / 1000``;
a frame of 10 samples from sample 10 f names the index playing at its first sample (12 values a sample at 12 kHz,
fewer after a stall), and is read a random, positive delay after its last sample. Index k truly plays at
``A + (k + stalled) (1 + drift) / 12000``. Every index must be placed never early (beyond what the drift's estimate
allows) and late by no more than the fastest frame's delay among those the clock looked at.
"""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.devices.protocol.reports import parse_sensors, sensor_samples, sensors_payload
from ultraglide.render.engine.play_clock import AHEAD_S, NOT_PLAYING, WINDOW_S, WRAP, PlayClock

RATE, SENSOR_RATE, FRAME = 12000.0, 1000.0, 10  # Hz, Hz, samples a frame
PER_FRAME = int(RATE * FRAME / SENSOR_RATE)  # stream values a frame spans (120)
A = 50.0  # the host time of the device's sample 0


class Plate:
    """A plate's frames: (index, samples, received_s, first_sample), and each frame's delay."""

    def __init__(self, seconds: float, delays, drift: float = 0.0, stall_frame: int | None = None, stalled: int = 0):
        self.drift, self.stall_frame, self.stalled = drift, stall_frame, stalled
        self.frames, self.delays = [], []
        for f in range(int(seconds * SENSOR_RATE / FRAME)):
            index = PER_FRAME * f - (stalled if stall_frame is not None and f >= stall_frame else 0)
            received = A + (FRAME * f + FRAME) * (1 + drift) / SENSOR_RATE + float(delays[f])
            self.frames.append((index, FRAME, received, FRAME * f))
            self.delays.append(float(delays[f]))
        self.received = np.array([frame[2] for frame in self.frames])

    def feed(self, clock: PlayClock) -> PlayClock:
        for frame in self.frames:
            clock.take(*frame)
        return clock

    def plays_at(self, index: np.ndarray) -> np.ndarray:
        """When each index truly plays (host s)."""
        after = index >= PER_FRAME * self.stall_frame - self.stalled if self.stall_frame is not None else False
        return A + (index + np.where(after, self.stalled, 0)) * (1 + self.drift) / RATE

    def fastest_near(self, at_s: float) -> float:
        """The fastest delay among the frames a clock looks at for ``at_s``."""
        near = (self.received >= at_s - WINDOW_S) & (self.received <= at_s + AHEAD_S)
        return float(np.array(self.delays)[near].min())


def late_by(clock: PlayClock, plate: Plate, at_s: float) -> np.ndarray:
    """How late the clock places the 120 indices that play from ``at_s`` (s)."""
    first = int((at_s - A) * RATE)
    index = np.arange(first, first + PER_FRAME, dtype=float)
    if plate.stall_frame is not None and first >= PER_FRAME * plate.stall_frame:
        index -= plate.stalled
    return clock.times_s(index, at_s) - plate.plays_at(index)


def test_without_drift_every_index_is_placed_never_early_and_late_by_the_fastest_frame_it_saw():
    rng = np.random.default_rng(3)
    plate = Plate(20.0, 0.2e-3 + rng.exponential(3e-3, 2000))  # every frame at least 0.2 ms late, most a few ms
    clock = plate.feed(PlayClock(RATE, SENSOR_RATE))
    for at in np.arange(50.5, 69.5, 0.37):
        late = late_by(clock, plate, at)
        # the drift's estimate (under a ppm of none here) moves bounds by µs
        assert late.min() >= -2e-6 and late.max() <= plate.fastest_near(at) + 2e-6
        assert late.max() < 0.5e-3  # a fast frame comes within 9 s here


def test_a_drifting_plate_is_followed_with_its_drift_estimated_from_the_lower_hull():
    rng = np.random.default_rng(4)
    drift = 80e-6  # the plate's clock 80 ppm slower than the host's: 1.6 ms over the 20 s
    plate = Plate(20.0, 0.1e-3 + rng.uniform(0.0, 4e-3, 2000), drift=drift)
    clock = plate.feed(PlayClock(RATE, SENSOR_RATE))
    assert clock.drift() == pytest.approx(drift, abs=5e-6)
    late = np.concatenate([late_by(clock, plate, at) for at in np.arange(50.5, 69.5, 0.5)])
    assert late.min() > -50e-6 and late.max() < 0.3e-3  # never early beyond the drift's error (5 ppm over 8 s)


def test_before_the_drift_is_known_a_drifting_plate_is_placed_within_its_windows_drift():
    rng = np.random.default_rng(5)
    drift = 50e-6
    plate = Plate(5.0, 0.1e-3 + rng.uniform(0.0, 2e-3, 500), drift=drift)  # under DRIFT_SPAN_S: no drift taken
    clock = plate.feed(PlayClock(RATE, SENSOR_RATE))
    assert clock.drift() == 0.0
    for at in (50.5, 52.5, 54.5):
        late = late_by(clock, plate, at)
        assert np.all(np.abs(late) < 0.3e-3 + drift * 5.0)


def test_after_a_stall_later_indices_play_later_by_what_the_devices_counts_say_at_once():
    rng = np.random.default_rng(6)
    plate = Plate(10.0, 0.1e-3 + rng.uniform(0.0, 1e-3, 1000), stall_frame=500, stalled=36)  # 3 ms at 55.0 s
    clock = plate.feed(PlayClock(RATE, SENSOR_RATE))
    for at in (53.0, 54.9, 55.01, 55.5, 58.0):  # just after the stall too: no window to wait out
        late = late_by(clock, plate, at)
        assert late.min() >= -1e-9 and late.max() < 0.3e-3
    # the values of the frame the stall came in (it came at its end here; the frames cannot say where): placed at
    # the latest they can have played, never early, late by no more than the stall; the one it names, exactly
    index = np.arange(PER_FRAME * 499, PER_FRAME * 500 - 36, dtype=float)
    late = clock.times_s(index, 55.0) - plate.plays_at(index)
    assert late[0] < 0.3e-3 and np.all((late[1:] >= 0.0) & (late[1:] < 3e-3 + 0.3e-3))


def test_a_links_byte_time_is_taken_off_and_a_long_frame_counts_as_a_regular_one():
    # a 921 600-baud UART (92 160 bytes/s): a 10-sample frame's 138 bytes take 1.497 ms to cross it
    rng = np.random.default_rng(7)
    link = 92160.0
    wire = (18 + 12 * FRAME) / link
    plate = Plate(4.0, wire + 0.05e-3 + rng.uniform(0.0, 2e-3, 400))
    clock = plate.feed(PlayClock(RATE, SENSOR_RATE, link_bytes_per_s=link))
    late = late_by(clock, plate, 52.0)
    assert late.min() >= 0.0 and late.max() < 0.1e-3
    # a 60-sample frame (sent at once on a link that does not pace its bytes): a 10-sample frame's time taken off
    clock = PlayClock(RATE, SENSOR_RATE, link_bytes_per_s=link)
    clock.take(0, 60, A + 0.060 + wire + 0.2e-3, 0)
    assert clock.times_s(np.array([0.0]), A)[0] - A == pytest.approx(0.2e-3, abs=1e-9)


def round_trips(rng, seconds: float, lag_s: float = 0.0, every_s: float = 0.05, drift: float = 0.0):
    """CLOCK requests every ``every_s`` to the synthetic plate: written at t1, taken at a random moment of a round
    trip of 0.1-3 ms, its clock then stated ``lag_s`` behind (sensor samples), read back at t2. Returns
    (stated samples, t1, t2) and each reply's slack, t2 less the time it was taken."""
    replies, slack = [], []
    for t1 in A + 0.02 + np.arange(0.0, seconds - 0.05, every_s):
        trip = rng.uniform(0.1e-3, 3e-3)
        taken = t1 + rng.uniform(0.0, trip)
        replies.append(((taken - A) / (1 + drift) * SENSOR_RATE - lag_s * SENSOR_RATE, t1, t1 + trip))
        slack.append(t1 + trip - taken + lag_s)
    return replies, np.array(slack)


def test_clock_replies_place_every_index_within_the_fastest_round_trip_whatever_the_frames_delay():
    """Frames 1-4 ms late (a device whose send loop holds them) place indices that late; with CLOCK replies (round
    trips of 0.1-3 ms, the device's clock taken inside each, stated up to 1 ms behind as allowed) every index is
    placed never early and late by no more than the tightest reply near it, and within what late_at_most_s says."""
    rng = np.random.default_rng(8)
    plate = Plate(20.0, 1e-3 + rng.uniform(0.0, 3e-3, 2000))
    frames_only = plate.feed(PlayClock(RATE, SENSOR_RATE))
    assert late_by(frames_only, plate, 55.0).min() > 0.9e-3  # the frames alone: as late as the fastest of them
    for lag_s in (0.0, 1e-3):
        replies, slack = round_trips(rng, 20.0, lag_s)
        clock = plate.feed(PlayClock(RATE, SENSOR_RATE))
        for reply in replies:
            clock.take_clock(*reply)
        asked = np.array([t1 for _, t1, _ in replies])
        drift = clock.drift()  # none here: what the hull finds moves a bound by its slope over the window
        assert abs(drift) < 5e-6  # (the hull of random bounds over 20 s: a few ppm at most)
        for at in np.arange(50.5, 69.5, 0.37):
            late = late_by(clock, plate, at)
            near = (asked >= at - WINDOW_S) & (asked <= at + AHEAD_S)
            moved = abs(drift) * (WINDOW_S + AHEAD_S) + 1e-9
            assert late.min() >= -moved and late.max() <= slack[near].min() + moved
            assert late.max() <= clock.late_at_most_s(at) + moved
    assert frames_only.late_at_most_s(55.0) is None


def test_clock_replies_of_a_drifting_plate_and_replies_from_before_a_restart():
    """A plate 60 ppm slow: the replies join the frames' hull (the drift found as before) and place it within
    their round trips. Replies stated on a clock the frames have left (a restart: numbers far from theirs) are
    not taken."""
    rng = np.random.default_rng(9)
    drift = 60e-6
    plate = Plate(20.0, 1e-3 + rng.uniform(0.0, 3e-3, 2000), drift=drift)
    replies, slack = round_trips(rng, 20.0, drift=drift)
    clock = plate.feed(PlayClock(RATE, SENSOR_RATE))
    for reply in replies:
        clock.take_clock(*reply)
    assert clock.drift() == pytest.approx(drift, abs=5e-6)
    late = np.concatenate([late_by(clock, plate, at) for at in np.arange(50.5, 69.5, 0.5)])
    assert late.min() > -50e-6 and late.max() < 0.3e-3  # the frames alone: 1 ms late at least
    stale = plate.feed(PlayClock(RATE, SENSOR_RATE))
    for samples, t1, t2 in replies:
        stale.take_clock(samples + 3e6, t1, t2)  # another clock's numbers: 50 min away
    assert stale.late_at_most_s(55.0) is None
    np.testing.assert_array_equal(late_by(stale, plate, 55.0), late_by(plate.feed(PlayClock(RATE, SENSOR_RATE)),
                                                                        plate, 55.0))


def test_frames_while_nothing_plays_say_nothing_and_counts_wrap():
    clock = PlayClock(RATE, SENSOR_RATE)
    clock.take(NOT_PLAYING, FRAME, 10.0, 0)
    clock.take(7, 0, 10.0, 0)
    assert clock.frames == 0 and clock.times_s(np.arange(3), 10.0) is None
    # the device's sample number and the index both wrap past 2**32 between two frames: one clock goes on
    clock.take(WRAP - 60, FRAME, 10.0105, WRAP - 5)  # read 0.5 ms after its last sample
    clock.take(60, FRAME, 10.0205 + 0.3e-3, 5)  # 10 samples on, 120 values on: read 0.8 ms after
    times = clock.times_s(np.array([WRAP - 60, WRAP + 60.0]), 10.0)
    np.testing.assert_allclose(times, [10.0005, 10.0105], atol=1e-8)  # by the first, the faster


def test_a_device_that_restarts_is_a_new_clock():
    clock = PlayClock(RATE, SENSOR_RATE)
    for f in range(100):  # one second of a first connection's frames, read 0.1 ms late
        clock.take(1000 + PER_FRAME * f, FRAME, 20.0 + 0.01 * f + 0.0101, 5000 + FRAME * f)
    for f in range(100):  # restarted: samples from 0 again, its stream from index 0, read 0.4 ms late
        clock.take(PER_FRAME * f, FRAME, 30.0 + 0.01 * f + 0.0104, FRAME * f)
    assert clock.times_s(np.array([0.0, 6000.0]), 30.5).round(6).tolist() == [30.0004, 30.5004]


def test_a_packed_sensors_frame_places_the_indices_that_follow_it():
    clock = PlayClock(RATE, SENSOR_RATE)
    frame = parse_sensors(sensors_payload(1000, 24000, sensor_samples(np.full(FRAME, 3.0))))
    clock.take_frame(frame, 20.0105)  # samples 1000-1009 from index 24000, read 0.5 ms after the last
    np.testing.assert_allclose(clock.times_s(np.array([24000, 24012, 36000]), 20.0),
                               [20.0005, 20.0015, 21.0005], atol=1e-9)


@pytest.mark.parametrize("kwargs", [{"stream_rate_hz": 0.0}, {"stream_rate_hz": RATE, "sensor_rate_hz": -1.0},
                                    {"stream_rate_hz": RATE, "window_s": 0.0},
                                    {"stream_rate_hz": RATE, "ahead_s": -1.0},
                                    {"stream_rate_hz": RATE, "link_bytes_per_s": -5.0}])
def test_a_clock_that_cannot_be_is_refused(kwargs):
    with pytest.raises(ValueError, match="play clock"):
        PlayClock(**kwargs)
