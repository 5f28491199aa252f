"""The renderer's survivors of scripts/mutation.sh, killed: the settings' checks at their boundaries, the
defaults people rely on (band-limited lookup, 0.5 N, a 10 ms release), the counters from a fresh start,
and the live clock's re-anchoring. Each test was checked against its mutant."""

from __future__ import annotations

import numpy as np
import pytest
from ultraglide.devices.profiles import load_profile
from ultraglide.render.errors import RenderError
from ultraglide.render.friction_models import ExponentialModel, StretchedExponentialModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures import procedural
from ultraglide.textures.effects import Binding, Constant, Trigger

RATE = 12000.0
SIM = load_profile("sim-plate")


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
    amplitude = renderer.control(int(0.3 * RATE)).amplitude_um_pp
    full = amplitude[int(0.1 * RATE)]
    lifted = np.flatnonzero(amplitude[int(0.2 * RATE):] <= 0.05 * full)[0] / RATE
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
