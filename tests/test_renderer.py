"""The renderer: spectra, block joins, limits, ramps, trajectories, latency, pre-compensation."""

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
from ultraglide.render.physics.friction_models import ExponentialModel, PaperModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.trajectory import LiveTrajectory, RecordedTrajectory
from ultraglide.textures import procedural
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
