"""The renderer: spectra, block joins, limits, ramps, trajectories, latency, pre-compensation."""

import dataclasses
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import signal
from ultraglide.devices.output.carrier import Carrier
from ultraglide.devices.profiles import PlateProfile, load_profile
from ultraglide.render.engine.sources import offline_stage
from ultraglide.render.errors import RenderError
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.friction_models import ExponentialModel, PaperModel, StretchedExponentialModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.trajectory import LiveTrajectory, RecordedTrajectory
from ultraglide.textures import procedural
from ultraglide.textures.effects import Binding, Constant, Sine, Trigger
from ultraglide.textures.texture import Texture

SIM = load_profile("sim-plate")
RATE = 96000


def spectrum_db(samples, rate=RATE):
    windowed = samples * np.hanning(len(samples))
    magnitude = np.abs(np.fft.rfft(windowed))
    return np.fft.rfftfreq(len(samples), 1 / rate), 20 * np.log10(magnitude / magnitude.max() + 1e-12)


def level_at(freqs, db, f):
    return db[np.argmin(np.abs(freqs - f))]


def audio(renderer, frames):
    """What a plate would get from ``renderer``: its drive through the output stage (limiter, carrier)."""
    return offline_stage(renderer).pull(frames, None)


def swipe_renderer(wavelength_mm=1.0, speed=100.0, duration=3.0, carrier=None, **kw):
    texture = procedural.grating(wavelength_mm, ratio_range=(0.5, 1.0))
    path = SwipePath("straight", speed, duration, (5.0, 25.0))
    return Renderer(texture, ExponentialModel(), SIM, RenderSettings(carrier_hz=carrier, **kw), trajectory=path)


def test_sidebands_sit_at_speed_over_wavelength():
    for speed, wavelength in ((100.0, 1.0), (150.0, 2.0)):
        samples = audio(swipe_renderer(wavelength, speed), 3 * RATE)[RATE:2 * RATE]
        freqs, db = spectrum_db(samples)
        modulation = speed / wavelength
        assert level_at(freqs, db, 25000) == pytest.approx(0, abs=0.1)  # the carrier is the peak
        for side in (25000 - modulation, 25000 + modulation):
            assert level_at(freqs, db, side) > -12
        # nothing at unrelated frequencies: e.g. a third of the way to the sideband
        assert level_at(freqs, db, 25000 + modulation / 3) < -60


def test_carrier_is_configurable_and_checked_against_the_rate():
    samples = audio(swipe_renderer(carrier=22000.0), RATE)[RATE // 2:]
    freqs, db = spectrum_db(samples)
    assert freqs[np.argmax(db)] == pytest.approx(22000, abs=2)
    with pytest.raises(RenderError, match="sample rate of at least"):
        swipe_renderer(carrier=25000.0, audio_rate_hz=48000)
    with pytest.raises(RenderError, match="outside"):
        swipe_renderer(carrier=35000.0, audio_rate_hz=192000, control_rate_hz=12000)


@pytest.mark.parametrize("carrier_hz", [25000.0, 23456.7])  # table mode and accumulator mode
def test_carrier_phase_is_continuous_across_blocks_of_any_size(carrier_hz):
    whole = Carrier(carrier_hz, RATE).block(5000)
    pieces = Carrier(carrier_hz, RATE)
    sizes = [1, 2, 3, 64, 97, 1000, 1, 3832]
    joined = np.concatenate([pieces.block(n) for n in sizes])
    assert np.max(np.abs(joined - whole)) < 1e-5
    expected = np.sin(2 * np.pi * carrier_hz * np.arange(5000) / RATE)
    assert np.max(np.abs(whole - expected)) < 1e-5


def test_rendered_output_does_not_depend_on_block_sizes():
    whole = audio(swipe_renderer(), 40000)
    rng = np.random.default_rng(3)
    sizes = rng.integers(1, 700, 200)
    sizes = sizes[np.cumsum(sizes) <= 40000]
    pieces = offline_stage(swipe_renderer())
    joined = np.concatenate([pieces.pull(int(n), None) for n in sizes])
    assert np.max(np.abs(joined - whole[:len(joined)])) < 1e-5  # float32 output


def test_ramps_at_finger_down_and_up_do_not_click():
    renderer = swipe_renderer(duration=0.5, attack_s=0.005, release_s=0.010)
    envelope = np.abs(signal.hilbert(audio(renderer, int(0.6 * RATE))))
    first_ms = envelope[: RATE // 1000]
    assert first_ms.max() < 0.5 * np.median(envelope[RATE // 10: RATE // 5])  # rises, not a step
    assert renderer.counters.ramps == 2  # down at the start, up at the end
    assert envelope[-RATE // 50:].max() < 1e-3  # at rest after the release and the plate's decay


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    values=st.lists(st.floats(0, 1), min_size=4, max_size=4),
    xs=st.lists(st.floats(-200, 200), min_size=2, max_size=6),
    force=st.one_of(st.none(), st.floats(0.001, 20)),
    limit=st.floats(0.1, 7.9),
    precompensate=st.booleans(),
    model_name=st.sampled_from(["paper", "exponential"]),
)
def test_amplitude_never_exceeds_the_plate_limit(values, xs, force, limit, precompensate, model_name):
    texture = Texture(np.array(values, np.float32).reshape(2, 2), 2.0, 2.0, outside="tile")
    profile = PlateProfile("test", 25000.0, 200.0, 8.0, limit)
    times = np.arange(len(xs)) * 0.013
    forces = None if force is None else np.full(len(xs), force)
    path = RecordedTrajectory(times, xs, np.array(xs)[::-1], forces)
    model = PaperModel() if model_name == "paper" else ExponentialModel()
    renderer = Renderer(texture, model, profile, RenderSettings(precompensate=precompensate), trajectory=path)
    blocks = []
    renderer.observers.append(blocks.append)
    samples = audio(renderer, int(0.1 * RATE))
    assert np.all(np.isfinite(samples)) and np.max(np.abs(samples)) <= 1.0
    for block in blocks:
        assert block.amplitude_um_pp.max() <= limit + 1e-12
        assert block.plate_um_pp.max() <= limit + 1e-9
        assert block.drive_um_pp.max() <= profile.full_scale_um_pp + 1e-12
        assert block.drive_um_pp.min() >= 0


def test_unreachable_ratios_are_clamped_and_counted():
    texture = procedural.grating(2.0, ratio_range=(0.0, 1.0))
    path = SwipePath("straight", 100.0, 1.0, (5.0, 25.0))
    renderer = Renderer(texture, PaperModel(), SIM, trajectory=path)
    blocks = []
    renderer.observers.append(blocks.append)
    audio(renderer, RATE)
    assert renderer.counters.clipped_samples > 0
    assert max(b.target_um_pp.max() for b in blocks) == pytest.approx(SIM.max_amplitude_um_pp)


# ---- trajectories -----------------------------------------------------------------------------------

def test_recorded_trajectory_interpolates_uneven_records():
    t = np.array([0.0, 0.013, 0.021, 0.040, 0.051])
    path = RecordedTrajectory(t, 100 * t, 50 - 30 * t)  # a straight line at constant speed
    state = path.state(np.linspace(0, 0.051, 50))
    assert state.x_mm == pytest.approx(100 * np.linspace(0, 0.051, 50), abs=1e-9)
    assert state.down.all()
    assert not np.any(path.state([0.06]).down)


def test_a_recorded_path_gives_numpys_force_and_scipys_pchip_at_any_times():
    """The compiled pass against numpy and scipy, each asked on its own: positions as scipy's PCHIP, the force as
    numpy's interp to the bit, times held at the ends (before, after, on records, unsorted, any shape; NaN)."""
    from scipy.interpolate import PchipInterpolator

    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(1 / 240, 1 / 60, 300))
    x, y, force = np.cumsum(rng.normal(0, 1, 300)), rng.uniform(0, 50, 300), rng.uniform(0.1, 2, 300)
    path = RecordedTrajectory(t, x, y, force)
    times = np.concatenate([rng.uniform(t[0] - 0.5, t[-1] + 0.5, 4000), t[::6], [t[0], t[-1]]])
    state = path.state(times.reshape(-1, 2))
    held = np.clip(times, t[0], t[-1])
    np.testing.assert_array_equal(state.force_n.reshape(-1), np.interp(held, t, force))
    np.testing.assert_array_equal(state.down.reshape(-1), (times >= t[0]) & (times <= t[-1]))
    assert state.x_mm.reshape(-1) == pytest.approx(PchipInterpolator(t, x)(held), abs=1e-9)
    assert state.y_mm.reshape(-1) == pytest.approx(PchipInterpolator(t, y)(held), abs=1e-9)
    nowhere = path.state(np.array([np.nan]))
    assert np.isnan([nowhere.x_mm[0], nowhere.force_n[0]]).all() and not nowhere.down[0]
    assert np.isnan(RecordedTrajectory(t, x, y).state(times).force_n).all()  # no force logged
    assert path.state(np.zeros(0)).x_mm.shape == (0,)


def test_the_steps_along_a_path_are_numpys_differences_and_lengths():
    from ultraglide.render import kernels

    rng = np.random.default_rng(6)
    x, y = np.cumsum(rng.normal(0, 0.01, 5000)), np.cumsum(rng.normal(0, 0.01, 5000))
    dx, dy, step = np.empty(5000), np.empty(5000), np.empty(5000)
    kernels.motion(x, y, 0.3, -0.2, dx, dy, step)
    want_x, want_y = np.diff(x, prepend=0.3), np.diff(y, prepend=-0.2)
    want_x[0], want_y[0] = want_x[1], want_y[1]  # the jump from the block before is not motion
    np.testing.assert_array_equal(dx, want_x)
    np.testing.assert_array_equal(dy, want_y)
    np.testing.assert_array_equal(step, np.hypot(want_x, want_y))
    one = np.empty(1)
    kernels.motion(x[:1], y[:1], 0.0, 0.0, one, np.empty(1), np.empty(1))
    assert one[0] == x[0]  # one sample: its move from the last


@pytest.mark.parametrize("bad, message", [
    (([0, 1, 0.5], [0, 1, 2], [0, 0, 0]), "does not increase"),
    (([0, 1, 2], [0, np.nan, 2], [0, 0, 0]), "not a finite number"),
    (([0], [0], [0]), "at least two"),
])
def test_recorded_trajectory_refuses_bad_records(bad, message):
    with pytest.raises(RenderError, match=message):
        RecordedTrajectory(*bad)


def test_live_prediction_cancels_latency_on_a_constant_velocity_swipe():
    latency = 0.05
    track = LiveTrajectory("lsq", lookahead_s=latency)
    speed = 120.0
    for k in range(10):  # 60 Hz reports of where the finger was 50 ms before
        t = k / 60
        track.push(t, speed * (t - latency), 20.0)
    query = 9 / 60 + 0.004  # between reports
    assert track.state(np.array([query])).x_mm[0] == pytest.approx(speed * query, abs=1e-9)


def test_least_squares_velocity_beats_two_point_extrapolation_on_jittery_reports():
    rng = np.random.default_rng(0)
    errors = {"lsq": [], "linear": [], "hold": []}
    for _ in range(300):
        reports = np.arange(8) / 120
        jitter = rng.normal(0, 0.15, 8)  # 0.15 mm of panel noise
        for name in errors:
            track = LiveTrajectory(name, lookahead_s=0.0)
            for t, j in zip(reports, jitter, strict=True):
                track.push(t, 100 * t + j, 0.0)
            query = reports[-1] + 1 / 240
            errors[name].append(track.state(np.array([query])).x_mm[0] - 100 * query)
    rms = {name: np.sqrt(np.mean(np.square(e))) for name, e in errors.items()}
    assert rms["lsq"] < 0.6 * rms["linear"]
    assert rms["lsq"] < rms["hold"]


def test_prediction_stops_when_reports_stop():
    track = LiveTrajectory("lsq", max_extrapolation_s=0.05)
    for k in range(5):
        track.push(k / 100, 100 * k / 100, 0.0)
    far = track.state(np.array([10.0])).x_mm[0]
    assert far == pytest.approx(100 * (0.04 + 0.05), abs=1e-6)


def test_strokes_are_not_fitted_across_a_lift():
    track = LiveTrajectory("lsq")
    for k in range(5):
        track.push(k / 100, 100 * k / 100, 0.0)
    track.push(0.05, 0, 0, down=False)
    assert not np.any(track.state(np.array([0.06])).down)
    track.push(0.2, 50.0, 10.0)
    state = track.state(np.array([0.2]))
    assert np.all(state.down) and state.x_mm[0] == 50.0  # a fresh stroke: no velocity from the old one


def test_a_report_pushed_now_shapes_the_very_next_block():
    texture = Texture(np.array([[0.3, 1.0]], np.float32), 20.0, 10.0, outside="clamp")  # left slippery
    renderer = Renderer(texture, ExponentialModel(), SIM)
    now = 100.0
    renderer.push(now, 15.0, 5.0)  # on the sticky right half
    first = renderer.control(8, now_s=now)
    renderer.push(now + 0.0005, 15.0, 5.0, down=False)
    renderer.push(now + 0.001, 2.0, 5.0)  # lands on the slippery left half
    second = renderer.control(8, now_s=now + 8 / 12000)
    assert first.ratio.min() > 0.9
    assert second.ratio.max() < 0.35


# ---- the plate ------------------------------------------------------------------------------------

def resonator_envelope(drive_audio, profile, rate=RATE):
    """An independent plate: a digital resonator at f0 with quality Q, its envelope by Hilbert."""
    b, a = signal.iirpeak(profile.resonance_hz, profile.q, fs=rate)
    return np.abs(signal.hilbert(signal.lfilter(b, a, drive_audio))) * profile.full_scale_um_pp


def test_first_order_envelope_model_agrees_with_the_resonator():
    renderer = swipe_renderer(0.5, 100.0, 1.0)
    blocks = []
    renderer.observers.append(blocks.append)
    plate = resonator_envelope(audio(renderer, RATE).astype(float), SIM)[12::8]  # 1.5 control periods late
    modelled = np.concatenate([b.plate_um_pp for b in blocks])
    steady = slice(2000, 11000)
    assert np.sqrt(np.mean((plate[steady] - modelled[steady]) ** 2)) < 0.05  # µm


def test_precompensation_brings_a_200_hz_texture_closer_to_its_target():
    profile = PlateProfile("f25q200", 25000.0, 200.0, 16.0, 6.0, max_drive_um_pp=16.0)
    texture = procedural.grating(0.5, ratio_range=(0.3, 0.9))
    path = SwipePath("straight", 100.0, 1.2, (5.0, 25.0))  # 100 mm/s over 0.5 mm: 200 Hz
    errors = {}
    for precompensate in (False, True):
        renderer = Renderer(texture, ExponentialModel(), profile, RenderSettings(precompensate=precompensate),
                            trajectory=path)
        blocks = []
        renderer.observers.append(blocks.append)
        plate = resonator_envelope(audio(renderer, RATE).astype(float), profile)[12::8]
        wanted = np.concatenate([b.amplitude_um_pp for b in blocks])
        steady = slice(3000, 11000)
        errors[precompensate] = np.sqrt(np.mean((plate[steady] - wanted[steady]) ** 2))
    assert errors[True] < 0.4 * errors[False]


CONTROL_RATE = 12000.0


def _uniform(ratio: float = 0.5):
    return procedural.grating(2.0, size_mm=(80, 50), ratio_range=(ratio, ratio))


def test_control_rates_from_10_khz_are_accepted_and_below_refused_in_words():
    assert RenderSettings(control_rate_hz=10000.0, audio_rate_hz=100000).upsampling == 10
    with pytest.raises(RenderError) as error:
        RenderSettings(control_rate_hz=9999.0)
    assert str(error.value) == "the control rate must be at least 10 kHz, got 9999 Hz"


def test_the_audio_rate_must_be_a_whole_multiple_of_the_control_rate():
    assert RenderSettings(audio_rate_hz=96000, control_rate_hz=12000.0).upsampling == 8
    assert RenderSettings(audio_rate_hz=12000, control_rate_hz=12000.0).upsampling == 1  # once is whole
    for audio_hz in (96000, 44100):
        with pytest.raises(RenderError) as error:
            RenderSettings(audio_rate_hz=audio_hz, control_rate_hz=11000.0)  # 8.73 and 4.01 times
        assert str(error.value) == (f"the audio rate ({audio_hz}) must be a whole multiple of the control rate "
                                    "(11000)")


@pytest.mark.parametrize("force_n", [0.0, -0.5])
def test_a_default_force_of_zero_or_less_is_refused(force_n):
    with pytest.raises(RenderError) as error:
        RenderSettings(default_force_n=force_n)
    assert str(error.value) == "the default force must be positive"


def _swipe(seconds: float, speed_mm_s: float = 100.0) -> RecordedTrajectory:
    return RecordedTrajectory([0.0, seconds], [10.0, 10.0 + speed_mm_s * seconds], [25.0, 25.0])


def test_a_panel_without_force_is_rendered_at_0_5_n_by_default():
    model = StretchedExponentialModel()  # force-aware: the amplitude a ratio needs grows with the force
    assert model.amplitude_um_pp(0.5, 1.5).amplitude_um_pp != pytest.approx(model.amplitude_um_pp(0.5, 0.5)
                                                                             .amplitude_um_pp)
    block = Renderer(_uniform(0.5), model, SIM, trajectory=_swipe(0.1)).control(600)
    np.testing.assert_allclose(block.target_um_pp, model.amplitude_um_pp(0.5, 0.5).amplitude_um_pp, rtol=1e-6)


def test_the_default_lookup_is_band_limited():
    # a 0.5 mm grating swept at 1 m/s moves 0.083 mm a sample: 6 samples a period, well followed, but the
    # pixel (0.05 mm) is finer than the step, so the default lookup reads a blurred level: a smaller swing
    texture = procedural.grating(0.5, size_mm=(200, 20), px_per_mm=20.0, ratio_range=(0.3, 1.0))
    path = RecordedTrajectory([0.0, 0.1], [10.0, 110.0], [10.0, 10.0])
    default = Renderer(texture, ExponentialModel(), SIM, trajectory=path).control(1200).ratio
    sharp = Renderer(texture, ExponentialModel(), SIM, RenderSettings(band_limited_lookup=False),
                     trajectory=path).control(1200).ratio
    assert np.ptp(sharp) > 0.6
    assert np.ptp(default) < 0.9 * np.ptp(sharp)


def test_the_default_release_takes_10_ms():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM,
                        RenderSettings(band_hz=5000.0, slew_um_per_ms=1000.0, precompensate=False),
                        trajectory=_swipe(0.2))
    amplitude = renderer.control(int(0.3 * CONTROL_RATE)).amplitude_um_pp
    full = amplitude[int(0.1 * CONTROL_RATE)]
    lifted = np.flatnonzero(amplitude[int(0.2 * CONTROL_RATE):] <= 0.05 * full)[0] / CONTROL_RATE
    assert lifted == pytest.approx(0.95 * 0.010, abs=0.0006)  # the gate's linear ramp from 1 to 0 in 10 ms


def test_counters_start_from_nothing():
    texture = procedural.grating(2.0, size_mm=(80, 50), ratio_range=(0.02, 0.02))  # below what the plate reaches
    renderer = Renderer(texture, ExponentialModel(), SIM, trajectory=_swipe(0.1))
    renderer.control(100)
    assert renderer.counters.control_samples == 100
    assert renderer.counters.clipped_samples == 100  # every sample held at the limit, and no more
    renderer.control(50)
    assert renderer.counters.control_samples == 150
    assert renderer.counters.clipped_samples == 150


def test_the_live_clock_follows_the_device_until_it_drifts_more_than_20_ms():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM)
    renderer.push(100.0, 20.0, 20.0)
    first = renderer.control(120, now_s=100.0)
    assert first.time_s[0] == 100.0
    # 10 ms of device clock off the renderer's own: within the tolerance, the renderer's clock runs on
    second = renderer.control(120, now_s=100.0 + 0.010 + 0.010)
    assert second.time_s[0] == pytest.approx(100.010, abs=1e-12)
    # 50 ms off: re-anchored to the device's time (and counted late, the device being ahead)
    third = renderer.control(120, now_s=100.070)
    assert third.time_s[0] == pytest.approx(100.070, abs=1e-12)
    assert renderer.counters.late_blocks == 1


def test_a_live_renderer_does_not_look_ahead_unless_told():
    # reports of a swipe at 120 mm/s, 60 Hz: by default the finger is where the reports put it at that time
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM)
    for k in range(10):
        renderer.push(k / 60, 10.0 + 120.0 * k / 60, 20.0)
    block = renderer.control(12, now_s=9 / 60 + 0.004)
    np.testing.assert_allclose(block.x_mm, 10.0 + 120.0 * block.time_s, atol=1e-6)


def _live(texture, **settings):
    """A live renderer writing into preallocated buffers (the engine's real-time path), a finger swiping
    along x at 100 mm/s reported at 120 Hz for the 50 ms up to t = 100 s, and the blocks its observer saw."""
    renderer = Renderer(texture, ExponentialModel(), SIM, RenderSettings(**settings))
    buffers = renderer.control_buffers(256)
    seen = []
    renderer.observers.append(seen.append)
    for k in range(7):
        renderer.push(100.0 - (6 - k) / 120, 15.0 - 100.0 * (6 - k) / 120, 25.0)
    return renderer, buffers, seen


def _blocks(renderer, buffers, count, n=240, start_s=100.0):
    """``count`` live blocks of ``n`` samples at the control clock from ``start_s``: (ratio, amplitude, drive)
    copies of each."""
    rate = renderer.settings.control_rate_hz
    blocks = (renderer.control(n, start_s + i * n / rate, buffers) for i in range(count))
    return [(block.ratio.copy(), block.amplitude_um_pp.copy(), block.drive_um_pp.copy()) for block in blocks]


def test_a_live_block_into_buffers_counts_its_samples_and_clips_and_reaches_its_observers():
    renderer, buffers, seen = _live(_uniform(0.0))  # a ratio of 0 is below what the plate reaches: all clipped
    blocks = _blocks(renderer, buffers, 2)
    assert renderer.counters.control_samples == 480
    assert renderer.counters.clipped_samples == 480
    # the limit's 6 µm asked at once: the pre-compensated attack wants more than the 8 µm of drive headroom
    at_headroom = sum(int(np.count_nonzero(drive >= SIM.max_drive_um_pp - 1e-9)) for _, _, drive in blocks)
    assert at_headroom > 0 and renderer.counters.drive_clipped_samples == at_headroom
    np.testing.assert_allclose(np.diff(renderer.last_block.time_s), 1 / 12000, rtol=1e-6)  # the control clock
    assert len(seen) == 2 and seen[-1] is renderer.last_block and renderer.last_block.time_s[0] == pytest.approx(
        100.0 + 240 / 12000, abs=1e-12)


def test_a_live_finger_drives_the_plate_and_a_pause_releases_it():
    renderer, buffers, _ = _live(_uniform(0.5))
    target = ExponentialModel().amplitude_um_pp(0.5, 0.5).amplitude_um_pp  # exp(-(a_pp / 2)^2 / (2 tau^2)) = 0.5
    assert target == pytest.approx(2 * 1.32 * np.sqrt(2 * np.log(2)), rel=1e-3)
    (_, amplitude, _), = _blocks(renderer, buffers, 1)  # 20 ms: past the 5 ms attack and the band's settling
    assert amplitude[-1] == pytest.approx(target, rel=0.02)
    renderer.pause()
    (_, amplitude, _), = _blocks(renderer, buffers, 1, start_s=100.02)  # the 10 ms release, then rest
    assert amplitude[-1] == pytest.approx(0.0, abs=1e-3)
    assert renderer.counters.ramps >= 2  # up and down
    assert not renderer.finished  # paused, not stopped
    renderer.stop()
    # the tail: the 10 ms release, 7 time constants of the plate, 5 periods of the 1 kHz band limit
    assert renderer.tail_s == pytest.approx(0.010 + 7 * SIM.time_constant_s + 0.005, rel=1e-12)
    assert renderer.tail_s < 0.06
    _blocks(renderer, buffers, 3, start_s=100.04)  # 60 ms: longer than the output's tail
    assert renderer.finished


def test_a_live_finger_reads_a_fine_grating_in_full_at_its_own_speed():
    # a 2 mm grating from 0.3 to 0.9 at 100 mm/s: 8.3 µm a sample, far finer than a pixel, so the band-limited
    # lookup reads the full-resolution texture and a 20 ms block (one period) swings across the range
    texture = procedural.grating(2.0, size_mm=(80, 50), ratio_range=(0.3, 0.9))
    renderer, buffers, _ = _live(texture)
    (ratio, _, _), = _blocks(renderer, buffers, 1)
    assert ratio.max() == pytest.approx(0.9, abs=0.02) and ratio.min() == pytest.approx(0.3, abs=0.02)


def test_a_live_block_mixes_the_effects_and_counts_what_they_push_above_rest():
    renderer, buffers, _ = _live(_uniform(0.5))
    # a constant -0.7 subtracted while the finger is down: 0.5 + 0.7 is more friction than at rest, held at 1
    renderer.set_effects((Binding(Trigger("while"), Constant(-0.7), release_s=0.0),))
    blocks = _blocks(renderer, buffers, 2)
    for ratio, amplitude, _ in blocks:
        np.testing.assert_array_equal(ratio, 1.0)
        np.testing.assert_array_equal(amplitude, 0.0)  # the plate at rest
    assert renderer.counters.clipped_samples == 480


# ---- the renderer's second mutation run: the general control() path, buffers, live changes ----------------


def test_a_fresh_renderer_has_rendered_nothing_and_one_stopped_at_once_is_finished():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM)
    counters = renderer.counters
    assert (counters.control_samples, counters.clipped_samples, counters.drive_clipped_samples, counters.ramps,
            counters.late_blocks, counters.render_times_s) == (0, 0, 0, 0, 0, [])
    assert renderer.last_block is None
    assert not renderer.finished  # running: a finger may land at any time
    renderer.stop()
    assert renderer.finished  # nothing was ever driven: at rest at once


def test_a_live_report_to_a_recorded_path_is_refused_in_words():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(0.1))
    with pytest.raises(RenderError) as error:
        renderer.push(0.0, 10.0, 10.0)
    assert str(error.value) == "this renderer plays a recorded trajectory; it takes no live reports"


def _in(block, buffers, live: bool = False) -> bool:
    """Whether the arrays of ``block`` are views of ``buffers``: the clock, the finger and the envelope; on the
    live path also the lookup's ratio and the model's amplitude (elsewhere those stages allocate)."""
    names = ["time_s", "x_mm", "y_mm", "amplitude_um_pp", "drive_um_pp", "plate_um_pp"]
    return all(np.shares_memory(getattr(block, name), getattr(buffers, name))
               for name in names + (["ratio", "target_um_pp"] if live else []))


@pytest.mark.parametrize("live", [True, False])
def test_blocks_up_to_the_capacity_are_written_into_the_buffers_and_longer_ones_are_not(live):
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=None if live else _swipe(1.0))
    assert renderer.control_buffers().capacity == 4096  # the default
    buffers = renderer.control_buffers(300)
    if live:
        renderer.push(100.0, 20.0, 20.0)
    first = renderer.control(300, 100.0, buffers)  # exactly the capacity
    assert _in(first, buffers, live)
    assert renderer.control(300, 100.025, buffers) is first  # the same block, overwritten
    assert renderer.last_block is first
    longer = renderer.control(301, 100.05, buffers)
    assert not any(np.shares_memory(getattr(longer, name), getattr(buffers, name)) for name in ("ratio", "drive_um_pp"))
    assert renderer.control(20, 100.0751, buffers) is renderer.control(20, 100.0768, buffers)
    if live:  # the lookup writes into the buffers at every length, also past the 64 lengths whose blocks are kept
        now = 100.1
        for n in range(1, 80):
            assert np.shares_memory(renderer.control(n, now, buffers).ratio, buffers.ratio), n
            now += n / 12000


@pytest.mark.parametrize("always", [False, True])
def test_blocks_asked_without_buffers_use_them_only_when_always(always):
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(1.0))
    buffers = renderer.control_buffers(256, always=always)
    kept = renderer.control(200)
    assert _in(kept, buffers) == always
    assert renderer.control_buffers(256).capacity == 256  # asked again without always: the choice stays
    assert _in(renderer.control(200), buffers) == always


def test_a_recorded_path_into_buffers_gives_the_finger_its_ratio_and_amplitude():
    # a swipe from (10, 25) mm at 100 mm/s over a uniform ratio of 0.5: exp(-(a_pp / 2)^2 / (2 tau^2)) = 0.5
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(1.0))
    buffers = renderer.control_buffers(512)
    target = 2 * 1.32 * np.sqrt(2 * np.log(2))
    for _ in range(3):
        block = renderer.control(400, out=buffers)
        assert _in(block, buffers)
        np.testing.assert_allclose(block.x_mm, 10.0 + 100.0 * block.time_s, atol=1e-9)
        np.testing.assert_allclose(block.y_mm, 25.0, atol=1e-9)
        np.testing.assert_allclose(block.ratio, 0.5, atol=1e-6)
        np.testing.assert_allclose(block.target_um_pp, target, rtol=1e-3)
        assert np.all(block.down)
    assert block.time_s[-1] == pytest.approx(1199 / 12000, abs=1e-12)
    assert block.amplitude_um_pp[-1] == pytest.approx(target, rel=0.02)  # 100 ms: long past the 5 ms attack


def test_texture_model_and_force_changed_live_apply_from_the_next_block():
    model = StretchedExponentialModel()  # d + (1 - d) exp(-(a / s)^2), d = 0.1, s = 3.73 µm (F / 0.5 N)^(1/3)
    renderer = Renderer(_uniform(0.5), model, SIM, trajectory=_swipe(1.0))
    scale = 2 * np.sqrt(2) * 1.32

    def depth(ratio):  # a = s sqrt(ln((1 - d) / (ratio - d)))
        return np.sqrt(np.log(0.9 / (ratio - 0.1)))

    np.testing.assert_allclose(renderer.control(100).target_um_pp, scale * depth(0.5), rtol=1e-6)
    renderer.set_texture(_uniform(0.8))
    block = renderer.control(100)
    np.testing.assert_allclose(block.ratio, 0.8, atol=1e-6)
    np.testing.assert_allclose(block.target_um_pp, scale * depth(0.8), rtol=1e-6)
    renderer.set_default_force(1.5)  # s grows by 3^(1/3)
    np.testing.assert_allclose(renderer.control(100).target_um_pp, scale * 3 ** (1 / 3) * depth(0.8), rtol=1e-6)
    renderer.set_model(ExponentialModel(2.0))  # no force term: a = 2 sqrt 2 tau sqrt(ln(1 / ratio))
    np.testing.assert_allclose(renderer.control(100).target_um_pp, 2 * np.sqrt(2) * 2.0 * np.sqrt(np.log(1 / 0.8)),
                               rtol=1e-6)


@pytest.mark.parametrize("force_n", [0.0, -1.0])
def test_a_default_force_set_live_must_be_positive(force_n):
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM)
    renderer.set_default_force(0.3)
    assert renderer.default_force_n == 0.3
    with pytest.raises(RenderError) as error:
        renderer.set_default_force(force_n)
    assert str(error.value) == f"the default force must be positive, got {force_n}"
    assert renderer.default_force_n == 0.3


HOLD_AT_REST = (Binding(Trigger("while"), Constant(-0.7), release_s=0.0),)  # 0.5 + 0.7: held at 1, no vibration


def test_effects_given_to_the_renderer_or_with_a_texture_are_played_on_a_recorded_path():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(1.0), effects=HOLD_AT_REST)
    for _ in range(2):
        block = renderer.control(240)
        np.testing.assert_array_equal(block.ratio, 1.0)
        np.testing.assert_array_equal(block.amplitude_um_pp, 0.0)
    assert renderer.counters.clipped_samples == 480  # pushed above rest, each sample counted once
    plain = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(1.0))
    plain.set_texture(dataclasses.replace(_uniform(0.5), effects=HOLD_AT_REST))  # a texture with its own effects
    np.testing.assert_array_equal(plain.control(240).ratio, 1.0)


def test_a_recorded_block_keeps_its_own_ratio_when_the_effects_play_on():
    # a 50 Hz sine of depth 0.3 on 0.5: a 20 ms block holds one period, the next block another stretch of it
    wobble = (Binding(Trigger("while"), Sine(50.0, 0.3), release_s=0.0),)
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(1.0), effects=wobble)
    first = renderer.control(120)  # 10 ms: half a period
    kept = first.ratio.copy()
    assert kept.max() - kept.min() > 0.25
    second = renderer.control(120)
    assert np.abs(second.ratio - kept).max() > 0.25  # the second half period differs ...
    np.testing.assert_array_equal(first.ratio, kept)  # ... and the first block's ratio is untouched


def test_an_event_triggered_without_a_time_starts_now():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM,
                        effects=(Binding(Trigger("event", name="tap"), Constant(-0.7, 1.0), release_s=0.0),))
    buffers = renderer.control_buffers(256)
    now = time.perf_counter()
    renderer.push(now, 20.0, 20.0)
    assert renderer.trigger("tap") and not renderer.trigger("other")
    block = renderer.control(120, time.perf_counter() + 0.001, buffers)  # within the second the effect lasts
    np.testing.assert_array_equal(block.ratio, 1.0)


def test_every_late_block_is_counted():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM)
    renderer.push(100.0, 20.0, 20.0)
    renderer.control(120, now_s=100.0)
    for late in (1, 2, 3):  # the device 50 ms ahead of the renderer's clock each time
        renderer.control(120, now_s=100.0 + late * 0.060)
        assert renderer.counters.late_blocks == late
    renderer.control(120, now_s=99.0)  # behind: re-anchored, not late
    assert renderer.counters.late_blocks == 3


def test_render_times_are_the_seconds_each_block_took():
    renderer = Renderer(_uniform(0.5), ExponentialModel(), SIM, trajectory=_swipe(1.0))
    started = time.perf_counter()
    for _ in range(3):
        renderer.control(240)
    took = time.perf_counter() - started
    times = renderer.counters.render_times_s
    assert len(times) == 3 and all(0 < t <= took for t in times)


def test_the_drive_clips_of_a_recorded_path_are_counted():
    renderer = Renderer(_uniform(0.0), ExponentialModel(), SIM, trajectory=_swipe(1.0))  # the limit, asked at once
    drive = np.concatenate([renderer.control(240).drive_um_pp for _ in range(2)])
    at_headroom = int(np.count_nonzero(drive >= SIM.max_drive_um_pp - 1e-9))
    assert at_headroom > 0 and renderer.counters.drive_clipped_samples == at_headroom


def test_only_the_samples_the_finger_touches_count_as_clipped():
    # a swipe of 15.04 ms over a ratio below reach: samples k / 12000 s touch for k <= 180 (181 of them)
    renderer = Renderer(_uniform(0.0), ExponentialModel(), SIM, trajectory=_swipe(0.01504))
    renderer.control(100)
    assert renderer.counters.clipped_samples == 100
    block = renderer.control(200)
    assert int(np.count_nonzero(block.down)) == 81
    assert renderer.counters.clipped_samples == 181


FINE = dict(wavelength_mm=0.5, size_mm=(80, 50), ratio_range=(0.3, 0.9), px_per_mm=20.0)  # 10 pixels a period


def _fine(axis: str):
    return procedural.grating(angle_deg=0.0 if axis == "x" else 90.0, **FINE)


@pytest.mark.parametrize("buffered", [False, True])
def test_a_live_finger_reads_a_fine_grating_in_full_when_slow_and_averaged_when_fast(buffered):
    """At 100 mm/s (8 µm a sample, finer than the 50 µm pixels) the 0.5 mm grating swings over its range; at
    3 m/s (0.25 mm a sample, 2.3 pyramid levels down: a period of 10 pixels keeps about 0.2 of its swing there)
    the band-limited lookup averages it out."""
    swings = {}
    for speed in (100.0, 3000.0):
        renderer = Renderer(_fine("x"), ExponentialModel(), SIM)
        buffers = renderer.control_buffers(256) if buffered else None
        for k in range(7):
            renderer.push(100.0 - (6 - k) / 120, 40.0 - speed * (6 - k) / 120, 25.0)
        ratio = renderer.control(240, 100.0, buffers).ratio
        swings[speed] = ratio.max() - ratio.min()
    assert swings[100.0] == pytest.approx(0.6, abs=0.03)
    assert swings[3000.0] < 0.2


@pytest.mark.parametrize("axis", ["x", "y"])
def test_a_fast_recorded_finger_is_band_limited_from_its_first_sample_in_blocks_of_any_size(axis):
    """3 m/s along the grating's wave: every sample reads the average, within the swing left at 2.3 levels
    down, from the first block's second sample on (a 2-sample first block takes its second step for its
    first sample too; a 1-sample first block has no motion yet, and reads the texture as at rest)."""
    for start in np.arange(10) * 0.05:  # a period in ten starting points: some at a ridge, some in a valley
        begin = (10.0 + start, 25.0) if axis == "x" else (25.0, 10.0 + start)
        end = (begin[0] + 30.0, begin[1]) if axis == "x" else (begin[0], begin[1] + 30.0)
        path = RecordedTrajectory([0.0, 0.01], [begin[0], end[0]], [begin[1], end[1]])
        for first in (1, 2):
            renderer = Renderer(_fine(axis), ExponentialModel(), SIM, trajectory=path)
            ratio = np.concatenate([renderer.control(first).ratio] + [renderer.control(1).ratio for _ in range(20)])
            np.testing.assert_allclose(ratio[2 - first:], 0.6, atol=0.12, err_msg=f"{axis} {start} {first}")
