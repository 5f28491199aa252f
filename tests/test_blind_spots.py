"""Tests for mistakes the rest of the suite once let through (each was made on purpose, one at a time):
integer WAVs at the wrong scale, a bundled texture gone, a slew limit the defaults never reach, a
band-limited lookup one pyramid level too coarse, attack and release swapped."""

from __future__ import annotations

import re

import numpy as np
import pytest
import soundfile
from conftest import ROOT, run_cli
from ultraglide.devices.profiles import load_profile
from ultraglide.render.envelope import EnvelopeChain
from ultraglide.render.errors import RenderError
from ultraglide.render.physics.friction_models import ExponentialModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.trajectory import LiveTrajectory, RecordedTrajectory
from ultraglide.textures import procedural
from ultraglide.textures.library import library_entries
from ultraglide.textures.sampling import Sampler

# ---- integer exports carry the same samples as float ones, to within one step -----------------------


@pytest.mark.slow
@pytest.mark.parametrize("fmt, bits", [("int16", 16), ("int24", 24)])
def test_integer_export_samples_match_the_float_export(tmp_path, fmt, bits):
    common = ("checkerboard-5mm", "--duration-s", "0.4", "--speed-mm-s", "150")
    run_cli("export", *common, "-o", tmp_path / "f.wav", check=True)
    run_cli("export", *common, "-o", tmp_path / "i.wav", "--format", fmt, check=True)
    reference, _ = soundfile.read(tmp_path / "f.wav", dtype="float64")
    integer, _ = soundfile.read(tmp_path / "i.wav", dtype="float64")  # libsndfile scales by 2**(bits-1)
    assert len(integer) == len(reference)
    assert np.max(np.abs(reference)) > 0.3  # a real signal, not silence that any scale would match
    step = 2.0 ** -(bits - 1)
    assert np.max(np.abs(integer - reference)) <= step  # rounding only: not half (or double) scale


# ---- the bundled library is the one the documentation lists ---------------------------------------


def _documented_library() -> list[str]:
    table = (ROOT / "docs" / "textures.md").read_text(encoding="utf-8")
    return re.findall(r"^\|[^|]*\| `([^`]+)` \|", table, flags=re.MULTILINE)


def test_every_documented_texture_is_bundled_and_listed_by_the_command():
    documented = _documented_library()
    assert len(documented) >= 20  # the page's table was read (29 textures when this was written)
    bundled = [entry.name for entry in library_entries()]
    assert len(documented) == len(set(documented)) and set(documented) == set(bundled)
    listed = run_cli("textures", check=True).stdout
    missing = [name for name in documented if not re.search(rf"(^|\s){re.escape(name)}(\s|$)", listed, re.M)]
    assert not missing, f"`ultraglide textures` does not list {missing}"
    for name in documented:  # each thumbnail the page shows exists
        assert (ROOT / "docs" / "textures" / f"{name}.png").is_file(), name


# ---- the slew limit holds when it binds (the defaults never reach it) -------------------------------

RATE = 12000.0


def _chain(**overrides) -> EnvelopeChain:
    settings = dict(rate_hz=RATE, attack_s=1 / RATE, release_s=1 / RATE, band_hz=5000.0, slew_um_per_ms=1.0,
                    limit_um_pp=6.0, time_constant_s=0.0025, drive_max_um_pp=8.0, precompensate=False)
    settings.update(overrides)
    return EnvelopeChain(**settings)


def test_slew_limit_bounds_every_step_and_is_reached():
    chain = _chain()
    target = np.concatenate([np.full(2400, 6.0), np.zeros(2400)])  # full scale up, then down
    amplitude = chain.process(target, np.concatenate([np.ones(2400, bool), np.ones(2400, bool)])).amplitude_um_pp
    steps = np.abs(np.diff(np.concatenate([[0.0], amplitude])))
    bound = 1.0 * 1e3 / RATE  # 1 µm/ms at 12 kHz: 0.0833 µm a sample
    assert steps.max() <= bound * (1 + 1e-9)
    assert steps.max() == pytest.approx(bound, rel=1e-6)  # the first step from rest is exactly the bound
    # a one-pole smoother with k = bound / limit: 63 % of the way after 1/k samples, not after a 5 kHz corner
    k = bound / 6.0
    reached = np.argmax(amplitude >= 6.0 * (1 - np.exp(-1.0)))
    assert reached == pytest.approx(1 / k, abs=2)


def test_renderer_applies_a_slew_limit_it_is_given():
    texture = procedural.grating(2.0, size_mm=(80, 50), ratio_range=(0.5, 0.5))  # uniform: 0.5 everywhere
    path = RecordedTrajectory([0.0, 0.5], [10.0, 60.0], [25.0, 25.0])
    slew = 2.0  # µm/ms; the defaults (30 µm/ms) leave the band limit in charge
    settings = RenderSettings(slew_um_per_ms=slew, attack_s=1 / RATE, precompensate=False)
    renderer = Renderer(texture, ExponentialModel(), load_profile("sim-plate"), settings, trajectory=path)
    amplitude = renderer.control(600).amplitude_um_pp
    # the finger lands at t = 0: the target jumps from rest to A, and a one-pole smoother with
    # k = (slew / rate) / limit closes the gap geometrically, A (1 - (1 - k)^(n + 1))
    target = ExponentialModel().amplitude_um_pp(0.5).amplitude_um_pp
    k = slew * 1e3 / RATE / renderer.limit_um_pp
    expected = target * (1 - (1 - k) ** np.arange(1, 601))
    np.testing.assert_allclose(amplitude, expected, rtol=1e-6)
    assert np.abs(np.diff(amplitude)).max() <= slew * 1e3 / RATE


# ---- the band-limited lookup reads the level the step asks for --------------------------------------


def _gain(step_px: float, per_sample: bool = False) -> float:
    """How much of a 16-pixel sine grating's swing the band-limited lookup keeps at this step,
    against the plain bilinear lookup at the same points (projection on the grating's frequency)."""
    texture = procedural.grating(2.0, size_mm=(64.0, 40.0), px_per_mm=8.0, ratio_range=(0.0, 1.0))
    pixel_mm = texture.pixel_mm[0]
    assert pixel_mm == pytest.approx(0.125)
    x = 0.37 * pixel_mm + np.arange(4000) * step_px * pixel_mm
    y = np.full_like(x, 20.0)
    step_mm = np.full_like(x, step_px * pixel_mm) if per_sample else step_px * pixel_mm
    limited = Sampler(texture).ratio(x, y, step_mm=step_mm)
    plain = Sampler(texture, band_limited=False).ratio(x, y)
    tone = np.exp(-2j * np.pi * x / 2.0)
    return abs(np.mean((limited - limited.mean()) * tone)) / abs(np.mean((plain - plain.mean()) * tone))


@pytest.mark.parametrize("per_sample", [False, True], ids=["one-step", "step-per-sample"])
@pytest.mark.parametrize("step_px", [0.25, 1.0])
def test_band_limited_lookup_reads_full_resolution_while_the_step_is_a_pixel_or_less(step_px, per_sample):
    assert _gain(step_px, per_sample) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("per_sample", [False, True], ids=["one-step", "step-per-sample"])
def test_band_limited_lookup_reads_the_level_the_step_asks_for(per_sample):
    # a step of two pixels reads pyramid level 1: a Gaussian of sigma 1 pixel keeps exp(-2 pi^2 / 16^2)
    # of a 16-pixel period, the 2:1 linear decimation cos(pi / 16), and linear interpolation between
    # level-1 pixels (8 a period) sinc^2(1/8) on average. One level coarser keeps about 0.5.
    expected = np.exp(-2 * np.pi ** 2 / 16 ** 2) * np.cos(np.pi / 16) * np.sinc(1 / 8) ** 2
    assert _gain(2.0, per_sample) == pytest.approx(expected, abs=0.03)


# ---- attack and release: each takes its own time --------------------------------------------------


def _ramp_lengths(attack_s, release_s):
    chain = _chain(attack_s=attack_s, release_s=release_s, band_hz=1e9, slew_um_per_ms=1e9)
    gate = np.concatenate([np.ones(1200, bool), np.zeros(1200, bool)])
    amplitude = chain.process(np.full(2400, 4.0), gate).amplitude_um_pp
    rising = np.flatnonzero(amplitude[:1200] >= 4.0 - 1e-9)[0] + 1  # samples to full
    falling = np.flatnonzero(amplitude[1200:] <= 1e-9)[0] + 1  # samples to rest
    return rising, falling


def test_attack_opens_and_release_closes_in_their_own_times():
    rising, falling = _ramp_lengths(attack_s=0.002, release_s=0.007)
    assert rising == pytest.approx(0.002 * RATE, abs=1)
    assert falling == pytest.approx(0.007 * RATE, abs=1)
    rising, falling = _ramp_lengths(attack_s=0.008, release_s=0.001)
    assert rising == pytest.approx(0.008 * RATE, abs=1)
    assert falling == pytest.approx(0.001 * RATE, abs=1)


def test_renderer_passes_attack_and_release_through():
    texture = procedural.grating(2.0, size_mm=(80, 50), ratio_range=(0.5, 0.5))  # uniform: 0.5 everywhere
    path = RecordedTrajectory([0.0, 0.3], [10.0, 40.0], [25.0, 25.0])
    settings = RenderSettings(attack_s=0.003, release_s=0.012, band_hz=5000.0, slew_um_per_ms=1000.0,
                              precompensate=False)
    renderer = Renderer(texture, ExponentialModel(), load_profile("sim-plate"), settings, trajectory=path)
    amplitude = renderer.control(int(0.4 * RATE)).amplitude_um_pp
    full = amplitude[int(0.2 * RATE)]
    assert full == pytest.approx(ExponentialModel().amplitude_um_pp(0.5).amplitude_um_pp, rel=1e-3)
    rise = np.flatnonzero(amplitude >= 0.95 * full)[0] / RATE
    lifted = np.flatnonzero(amplitude[int(0.3 * RATE):] <= 0.05 * full)[0] / RATE
    assert rise == pytest.approx(0.95 * 0.003, abs=0.0006)  # the gate's linear ramp, a little smoothed
    assert lifted == pytest.approx(0.95 * 0.012, abs=0.0006)


# ---- export options through the command (each was tested only in the library, or not at all) ----------


def _export_envelope(tmp_path, *options):
    csv = tmp_path / "env.csv"
    run_cli("export", "grating-2mm", "-o", tmp_path / "out.wav", "--duration-s", "0.5", "--envelope-csv", csv,
            *options, check=True)
    return np.genfromtxt(csv, delimiter=",", names=True)


@pytest.mark.slow
def test_export_no_precompensation_drives_the_amplitude_itself(tmp_path):
    plain = _export_envelope(tmp_path, "--no-precompensation")
    np.testing.assert_allclose(plain["drive_um_pp"], plain["amplitude_um_pp"], atol=1e-5)
    compensated = _export_envelope(tmp_path)
    # pre-compensated, the drive leads the plate: it differs from the amplitude wherever the texture moves
    assert np.max(np.abs(compensated["drive_um_pp"] - compensated["amplitude_um_pp"])) > 0.1


@pytest.mark.slow
def test_export_swipe_geometry_options(tmp_path):
    down = _export_envelope(tmp_path, "--direction-deg", "90", "--start", "20,5", "--speed-mm-s", "60")
    touching = down["down"] > 0
    t = down["t_s"][touching] - down["t_s"][touching][0]
    np.testing.assert_allclose(down["x_mm"][touching], 20.0, atol=1e-6)  # 90°: straight down the screen
    np.testing.assert_allclose(down["y_mm"][touching], 5.0 + 60.0 * t, atol=0.02)

    circle = _export_envelope(tmp_path, "--path", "circle", "--radius-mm", "7", "--start", "30,25")
    touching = circle["down"] > 0
    radius = np.hypot(circle["x_mm"][touching] - 37.0, circle["y_mm"][touching] - 25.0)  # starts on its left
    np.testing.assert_allclose(radius, 7.0, atol=0.01)

    zigzag = _export_envelope(tmp_path, "--path", "zigzag", "--zigzag-width-mm", "12", "--start", "10,10",
                              "--speed-mm-s", "100")
    touching = zigzag["down"] > 0
    assert zigzag["x_mm"][touching].min() == pytest.approx(10.0, abs=0.01)
    assert zigzag["x_mm"][touching].max() == pytest.approx(22.0, abs=0.01)  # passes of 12 mm


# ---- live prediction: the speed cap and the merging of near-simultaneous reports (defaults never reach them)


@pytest.mark.parametrize("predictor", ["linear", "lsq"])
def test_a_glitch_faster_than_any_finger_is_capped_at_3_m_per_s(predictor):
    track = LiveTrajectory(predictor)
    track.push(0.0, 10.0, 20.0)
    track.push(0.010, 60.0, 20.0 + 50.0 * np.tan(np.radians(30)))  # 5.8 m/s at 30° below the x axis
    vx, vy = track.state(np.array([0.010, 0.011])).velocity_mm_s
    assert np.hypot(vx, vy) == pytest.approx(3000.0, rel=1e-9)
    assert np.degrees(np.arctan2(vy, vx)) == pytest.approx(30.0, abs=1e-9)  # capped, not turned


def test_reports_within_2_ms_are_one_instant_and_the_newest_stands():
    track = LiveTrajectory("linear")
    track.push(0.0, 0.0, 0.0)
    track.push(0.010, 1.0, 0.0)
    track.push(0.0115, 5.0, 0.0)  # 1.5 ms later: queued with the one before, read in one go
    vx, _ = track.state(np.array([0.0115, 0.012])).velocity_mm_s
    assert vx == pytest.approx(5.0 / 0.0115, rel=1e-9)  # through the first report and the newest


# ---- mutants that survived the suite (scripts/mutation.sh), killed --------------------------------------


@pytest.mark.parametrize("attack_s, release_s", [(0.0, 0.01), (0.005, 0.0), (-0.001, 0.01), (0.005, -0.001)])
def test_a_ramp_of_no_length_is_refused_alone(attack_s, release_s):
    with pytest.raises(RenderError, match="attack and release must be longer than 0 s"):
        _chain(attack_s=attack_s, release_s=release_s)


@pytest.mark.parametrize("band_hz, slew", [(0.0, 30.0), (1000.0, 0.0), (-1.0, 30.0), (1000.0, -1.0)])
def test_a_band_or_slew_limit_of_zero_is_refused_alone(band_hz, slew):
    with pytest.raises(RenderError, match="band and slew limits must be positive"):
        _chain(band_hz=band_hz, slew_um_per_ms=slew)


def test_the_envelope_pre_compensates_unless_told_not_to():
    settings = dict(rate_hz=RATE, attack_s=1 / RATE, release_s=0.01, band_hz=1e9, slew_um_per_ms=1e9,
                    limit_um_pp=6.0, time_constant_s=0.0025, drive_max_um_pp=8.0)
    block = EnvelopeChain(**settings).process(np.full(10, 3.0), True)
    # a step to 3 µm drives the plate's inverse first: d = (y - alpha a) / (1 - alpha), clipped at 8 µm
    alpha = np.exp(-1 / (RATE * 0.0025))
    assert block.drive_um_pp[0] == pytest.approx(min(3.0 / (1 - alpha), 8.0))
