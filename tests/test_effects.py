"""Temporal friction effects: waveforms against hand-computed values, triggers at the samples the path
reaches them, the mix before the model's inverse seen in exported WAVs (read back by soundfile, Hilbert
envelopes by scipy), the limiter holding with effects, the saved description, the engine's door and
the widgets scene.

Hand-computed amplitudes use the default model, the law of Monnoyer et al. (2018) above a floor d = 0.1:
ratio = d + (1 − d) exp(−a²/2τ²), τ = 1.32 µm zero-to-peak, so a = 2 τ sqrt(−2 ln((ratio − d)/(1 − d))) µm p-p;
the WAV's sample
1.0 is the sim-plate's full scale, 8 µm p-p."""

import json
import math
import time
import tracemalloc

import numpy as np
import pytest
import soundfile
from conftest import assert_one_line_error, run_cli
from scipy import signal
from test_limiter import OVERDRIVE, TOLERANCE, plate_amplitude_um_pp, worst_plate_um_pp, write_profile
from ultraglide.render.effects import EffectPlayer, sample
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures import effects as fx
from ultraglide.textures import procedural
from ultraglide.textures.effects import (
    ADSR,
    Binding,
    Constant,
    Sawtooth,
    Sine,
    Square,
    Triangle,
    Trigger,
)
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import load_texture, save_texture
from ultraglide.textures.texture import Texture

RATE = 96000
CONTROL = 12000
FULL_SCALE_UM_PP = 8.0
TAU_UM = 1.32


FLOOR = 0.10  # the default model's floor: a fingertip's ratio at full amplitude (Wiertlewski et al. 2016)


def amplitude_pp(ratio: float) -> float:
    """The default model (Monnoyer's law above its floor, d + (1 - d) exp(-a²/2τ²)) inverted by hand, µm p-p."""
    return 2.0 * TAU_UM * math.sqrt(-2.0 * math.log((ratio - FLOOR) / (1.0 - FLOOR)))


def wav_envelope(path):
    samples, rate = soundfile.read(path)
    assert rate == RATE
    return np.abs(signal.hilbert(samples)), rate


def uniform(tmp_path, ratio: float, effects=(), name="uniform"):
    texture = Texture(np.full((30, 40), ratio, np.float32), 40.0, 30.0, outside="clamp", name=name, effects=effects)
    return save_texture(texture, tmp_path / f"{name}.png")


# ---- the values ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("effect", "times", "expected"), [
    (Sine(100.0, 0.4), [0, 0.0025, 0.005, 0.0075, 0.01], [0, 0.2, 0.4, 0.2, 0]),  # 0.4 (1 − cos 2π f t) / 2
    (Square(100.0, 0.3), [0, 0.004, 0.005, 0.009, 0.01], [0, 0, 0.3, 0.3, 0]),
    (Sawtooth(50.0, 0.8), [0, 0.005, 0.01, 0.015, 0.02], [0, 0.2, 0.4, 0.6, 0]),
    (Triangle(50.0, 0.8), [0, 0.005, 0.01, 0.015, 0.02], [0, 0.4, 0.8, 0.4, 0]),
    (ADSR(0.01, 0.02, 0.03, 0.04, peak=0.6, sustain_level=0.5),  # knots: 0, .6 at 10 ms, .3 at 30-60 ms, 0 at 100
     [-0.001, 0, 0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.1, 0.2], [0, 0, 0.3, 0.6, 0.45, 0.3, 0.3, 0.15, 0, 0]),
    (Constant(0.25, 0.01), [-0.001, 0, 0.0099, 0.01], [0, 0.25, 0.25, 0]),
    (Sine(100.0, 0.4) + Constant(0.1), [0, 0.005], [0.1, 0.5]),
    (Sine(100.0, 0.4) * ADSR(0.01, 0, 0, 0.01, sustain_level=1.0), [0.005, 0.01, 0.015, 0.02], [0.2, 0, 0.2, 0]),
    (0.5 * Square(100.0, 1.0), [0.002, 0.007], [0, 0.5]),
    (Constant(0.2, 0.01) >> Constant(0.0, 0.01) >> Sawtooth(100.0, 1.0) * Constant(1.0, 0.01),
     [0.005, 0.015, 0.0225, 0.0299, 0.03], [0.2, 0, 0.25, 0.99, 0]),
])
def test_effect_values_match_hand_computed_waveforms(effect, times, expected):
    assert sample(effect, times) == pytest.approx(expected, abs=1e-9)


def test_durations_compose_as_stated():
    click = Square(200.0, 0.5) * ADSR(0.001, 0.004, 0.0, 0.01)
    assert click.duration_s == pytest.approx(0.015)
    assert (click >> Constant(0.0, 0.02) >> click).duration_s == pytest.approx(0.05)
    assert (click + Constant(0.1, 0.1)).duration_s == pytest.approx(0.1)
    assert math.isinf(Sine(10.0, 0.1).duration_s)
    with pytest.raises(TextureError, match="lasts for ever"):
        Sine(10.0, 0.1) >> click


# ---- triggers -----------------------------------------------------------------------------------------------

def run_player(bindings, path: RecordedTrajectory, block: int, ratio: float = 1.0, end_s: float | None = None):
    """The player over the path at the control rate in blocks of ``block`` samples: (times, mixed ratio)."""
    player = EffectPlayer(bindings, CONTROL, capacity=4096)
    n = int(round(((path.end_s if end_s is None else end_s) - path.start_s) * CONTROL)) + 1
    times = path.start_s + np.arange(n) / CONTROL
    state = path.state(times)
    mixed = np.empty(n)
    for start in range(0, n, block):
        end = min(n, start + block)
        mixed[start:end] = player.mix(times[start:end], state.x_mm[start:end], state.y_mm[start:end],
                                      state.down[start:end], np.full(end - start, ratio))
    return player, times, mixed


def first_sample_at_or_after(t_s: float) -> float:
    return math.ceil(t_s * CONTROL - 1e-9) / CONTROL


@pytest.mark.parametrize("block", [1, 7, 64, 12000])
def test_triggers_start_at_the_samples_the_path_reaches_them(block):
    """x = 100 t mm (t from 0 to 0.8 s), y = 5 mm: the region x 20-50 is entered at 0.2 s and left at 0.5 s,
    the lines at 10, 60, 70 mm are crossed at 0.1, 0.6, 0.7 s, the finger lands at 0 and lifts after 0.8 s."""
    path = RecordedTrajectory([0.0, 0.8], [0.0, 80.0], [5.0, 5.0])
    short = Constant(0.1, 0.001)
    region = (20.0, 0.0, 30.0, 10.0)
    bindings = (Binding(Trigger("start"), short), Binding(Trigger("start", region), short),
                Binding(Trigger("end", region), short), Binding(Trigger("cross", lines_mm=(10.0, 60.0, 70.0)), short),
                Binding(Trigger("end"), short), Binding(Trigger("cross", (0, 20, 100, 10), lines_mm=(30.0,)), short))
    player, _, _ = run_player(bindings, path, block, end_s=0.9)
    starts = sorted(player.starts)
    expected = sorted([(0, 0.0), (1, 0.2), (2, 0.5), (3, 0.1), (3, 0.6), (3, 0.7), (4, 0.8 + 1 / CONTROL)])
    # (binding 5's line lies outside its region's y span: never crossed)
    assert [k for k, _ in starts] == [k for k, _ in expected]
    assert [t for _, t in starts] == pytest.approx([first_sample_at_or_after(t) for _, t in expected], abs=1e-9)


def test_a_while_trigger_holds_its_effect_and_releases_it_linearly():
    path = RecordedTrajectory([0.0, 0.8], [0.0, 80.0], [5.0, 5.0])
    binding = Binding(Trigger("while", (20.0, 0.0, 30.0, 10.0)), Constant(0.3), release_s=0.02)
    _, times, mixed = run_player((binding,), path, 8, ratio=0.9)
    inside = (times >= 0.2 + 1e-9) & (times < 0.5 - 1e-9)
    assert mixed[inside] == pytest.approx(0.6)
    assert mixed[times < 0.2 - 1e-9] == pytest.approx(0.9)
    release = (times >= 0.5 + 1e-9) & (times < 0.52 - 1e-9)
    left = first_sample_at_or_after(0.5)
    assert mixed[release] == pytest.approx(0.9 - 0.3 * (1 - (times[release] - left) / 0.02))
    assert mixed[times > 0.53] == pytest.approx(0.9)


class StillThenMoving:
    """The finger rests at x = 10 mm until 0.3 s, then moves right at 100 mm/s until 0.6 s."""

    start_s, end_s = 0.0, 0.6

    def state(self, times):
        from types import SimpleNamespace

        x = 10.0 + 100.0 * np.clip(times - 0.3, 0.0, None)
        return SimpleNamespace(x_mm=x, y_mm=np.full(len(times), 5.0), down=np.ones(len(times), bool))


def test_a_moving_trigger_needs_the_speed_and_named_events_start_where_reported():
    binding = Binding(Trigger("while", min_speed_mm_s=20.0), Constant(0.2), release_s=0.0)
    player, times, mixed = run_player((binding,), StillThenMoving(), 8)
    assert [k for k, _ in player.starts] == [0]
    assert player.starts[0][1] == pytest.approx(first_sample_at_or_after(0.3) + 1 / CONTROL, abs=1e-9)
    assert mixed[times <= 0.3] == pytest.approx(1.0)
    assert mixed[times > 0.3 + 1.5 / CONTROL] == pytest.approx(0.8)

    player = EffectPlayer((Binding(Trigger("event", name="pressed"), Constant(0.5, 0.01)),), CONTROL)
    assert player.trigger("pressed", 0.0105) and not player.trigger("unknown", 0.0)
    times = np.arange(480) / CONTROL
    mixed = player.mix(times, np.zeros(480), np.zeros(480), True, np.ones(480)).copy()
    assert mixed == pytest.approx(np.where((times >= 0.0105) & (times < 0.0205), 0.5, 1.0))


# ---- through the renderer to the WAV ---------------------------------------------------------------------------

@pytest.mark.parametrize("model", ["stretched", "dynamic"])
def test_an_edge_crossing_pulse_is_in_the_exported_wav_at_the_crossing_time(tmp_path, model):
    """An edge at x = 20 mm (ratio 0.8 left, 1 right) saved with a 30 ms pulse of depth 0.6 bound to crossing it.
    The default swipe starts at 10 % of the 40 mm width and goes right at 100 mm/s: it crosses at 0.16 s. Before,
    the plate gives ratio 0.8; during the pulse 1 − 0.6 = 0.4; after it, the ratio is 1: at rest.

    Under the default model, dynamic, the renderer plans the texture against the finger's dynamics (it lets
    friction rise before the edge, so the level before it is not 0.8's), but not the effects: the pulse plays when
    the finger crosses, as deep as authored below the planned 1."""
    edge = procedural.edge(size_mm=(40.0, 30.0), ratio_range=(0.8, 1.0))
    pulse = Binding(Trigger("cross", lines_mm=(20.0,)), Constant(0.6, 0.03), label="edge pulse")
    path = save_texture(edge.with_(effects=(pulse,)), tmp_path / "edge.png")
    out = tmp_path / "edge.wav"
    summary = json.loads(run_cli("export", path, "-o", out, "--duration-s", "0.4", "--json", "--model", model,
                                 check=True).stdout)
    assert summary["effects_started"] == 1
    envelope, rate = wav_envelope(out)
    t = np.arange(len(envelope)) / rate
    before, during = amplitude_pp(0.8) / FULL_SCALE_UM_PP, amplitude_pp(0.4) / FULL_SCALE_UM_PP
    window = lambda a, b: envelope[(t >= a) & (t < b)]  # noqa: E731
    if model == "stretched":
        assert window(0.08, 0.15) == pytest.approx(before, rel=0.01)
    else:  # planned: friction rises ahead of the edge (the drive falls below 0.8's) and 0.8 is held before that
        assert window(0.08, 0.1) == pytest.approx(before, rel=0.01)
        assert window(0.15, 0.159).max() < 0.5 * before
    assert window(0.165, 0.189) == pytest.approx(during, rel=0.01)
    assert window(0.2, 0.4).max() < 0.01 * before  # at rest on the sticky side once the pulse is over
    # the pulse's onset: the first time the envelope passes halfway from before to during
    onset = t[np.argmax((t > 0.1) & (envelope > (before + during) / 2))]
    assert onset == pytest.approx(0.16, abs=0.0015)
    assert t[np.argmax((t > onset) & (envelope < before / 2))] == pytest.approx(0.19, abs=0.003)

    plain = tmp_path / "plain.wav"
    summary = json.loads(run_cli("export", path, "-o", plain, "--duration-s", "0.4", "--no-effects", "--json",
                                 check=True).stdout)
    assert summary["effects_started"] == 0
    assert wav_envelope(plain)[0][int(0.17 * RATE)] < 0.01 * before


def test_an_effect_that_asks_for_less_than_the_floor_is_counted_whether_or_not_the_renderer_plans(tmp_path):
    """A 30 ms pulse of depth 0.95 at the edge's crossing, on the sticky side (ratio 1): 1 − 0.95 = 0.05 is below
    what 6 µm p-p reaches at 0.5 N (0.168), so all 0.03 s × 12 kHz = 360 of its samples are held at the limit and
    counted, under the static model and under the default, which plans the texture and subtracts the effects from
    its command."""
    edge = procedural.edge(size_mm=(40.0, 30.0), ratio_range=(0.8, 1.0))
    pulse = Binding(Trigger("cross", lines_mm=(20.0,)), Constant(0.95, 0.03), label="deep pulse")
    path = save_texture(edge.with_(effects=(pulse,)), tmp_path / "edge.png")
    for model in ("stretched", "dynamic"):
        result = run_cli("export", path, "-o", tmp_path / f"{model}.wav", "--duration-s", "0.4", "--json",
                         "--model", model, check=True)
        assert json.loads(result.stdout)["clipped_samples"] == 360, model
        assert "of the time the texture asked for less friction" in result.stderr


def test_a_50_hz_sine_effect_is_a_50_hz_line_in_the_envelope(tmp_path):
    """A uniform ratio 0.7 with a 50 Hz sine of depth 0.2 while the finger is down: the ratio swings 0.5-0.7,
    so the drive's envelope has a 50 Hz line, and an independent plate (the profile's resonator) swings
    between the hand-computed amplitudes."""
    texture = uniform(tmp_path, 0.7)
    description = fx.to_json([Binding(Trigger("while"), Sine(50.0, 0.2))])
    effects = tmp_path / "sine.json"
    effects.write_text(json.dumps(description))
    out = tmp_path / "sine.wav"
    run_cli("export", texture, "-o", out, "--duration-s", "2.2", "--speed-mm-s", "10", "--effects", effects,
            check=True)
    envelope, rate = wav_envelope(out)
    steady = envelope[int(0.2 * rate):int(2.2 * rate)]  # 2 s: 0.5 Hz bins
    spectrum = np.abs(np.fft.rfft(steady - steady.mean()))
    frequencies = np.fft.rfftfreq(len(steady), 1 / rate)
    assert frequencies[np.argmax(spectrum)] == pytest.approx(50.0, abs=0.5)
    assert spectrum[np.argmin(np.abs(frequencies - 100.0))] < 0.2 * spectrum.max()  # harmonics well below
    samples, _ = soundfile.read(out)
    plate = plate_amplitude_um_pp(samples, 25000.0, 200.0, FULL_SCALE_UM_PP)[int(0.2 * rate):int(2.2 * rate)]
    assert plate.max() == pytest.approx(amplitude_pp(0.5), rel=0.02)
    assert plate.min() == pytest.approx(amplitude_pp(0.7), rel=0.02)


def test_the_limiter_holds_with_effects(tmp_path):
    """An overdriven plate (drive up to 4× its 2 µm limit) and a texture whose effects ask for full slipperiness
    in a 200 Hz square: independent resonators with half to twice the profile's Q stay within the limit, and
    the friction the plate cannot reach is counted."""
    profile = write_profile(tmp_path, OVERDRIVE)
    harsh = (Binding(Trigger("while"), Square(200.0, 1.0)),
             Binding(Trigger("cross", lines_mm=(10.0, 20.0, 30.0)), Constant(-0.5, 0.02)))  # stickier pulses too
    texture = uniform(tmp_path, 0.9, effects=harsh, name="harsh")
    out = tmp_path / "harsh.wav"
    summary = json.loads(run_cli("export", texture, "-o", out, "--profile", profile, "--duration-s", "0.4",
                                 "--json", check=True).stdout)
    samples, _ = soundfile.read(out)
    assert np.abs(samples).max() * 8.0 > 2 * 2.0  # pre-compensation overdrove: the test is not trivially true
    assert worst_plate_um_pp(samples, OVERDRIVE, 25000.0) <= TOLERANCE * 2.0
    assert summary["clipped_samples"] > 0 and summary["effects_started"] == 4


# ---- the saved description ---------------------------------------------------------------------------------------

def test_effects_survive_the_texture_file():
    bindings = (Binding(Trigger("start", (1.0, 2.0, 3.0, 4.0)), fx.click(), label="click"),
                Binding(Trigger("cross", lines_mm=(5.0, 6.0), axis="y"), fx.snap()),
                Binding(Trigger("while", min_speed_mm_s=20.0), fx.buzz(), release_s=0.05),
                Binding(Trigger("event", name="value"), fx.pulse() + 0.1 * Triangle(30.0, 1.0) * ADSR(0, 0, 0.1, 0)))
    assert fx.from_json(json.loads(json.dumps(fx.to_json(bindings)))) == bindings


def test_a_texture_file_keeps_its_effects(tmp_path):
    binding = Binding(Trigger("cross", lines_mm=(20.0,)), fx.pulse())
    path = uniform(tmp_path, 0.5, effects=(binding,))
    assert load_texture(path).effects == (binding,)
    assert load_texture(uniform(tmp_path, 0.5, name="none")).effects == ()


@pytest.mark.parametrize(("change", "fragment"), [
    (lambda d: d.update(effects_version=2), "effects version 2 is not one this ultraglide reads"),
    (lambda d: d["bindings"][0]["effect"].update(type="noise"), "unknown effect type 'noise'"),
    (lambda d: d["bindings"][0]["effect"].update(frequency_hz=5000), "frequency_hz must lie in (0, 2000] Hz"),
    (lambda d: d["bindings"][0]["effect"].update(depth=1.5), "depth must lie in [-1, 1]"),
    (lambda d: d["bindings"][0]["trigger"].update(on="cross"), "binding 1: a cross trigger needs 1 to 64 lines_mm"),
    (lambda d: d["bindings"][0]["trigger"].update(on="start"), "needs a finite duration"),
    (lambda d: d["bindings"][0]["trigger"].update(on="sometimes"), "'on' must be one of start, end, while"),
    (lambda d: d["bindings"][0].update(release_s=-1), "release_s must lie in [0, 60] s"),
    (lambda d: d["bindings"][0]["effect"].pop("depth"), "sine effect: missing 1 required positional argument"),
    (lambda d: d.update(bindings="all"), "'bindings' must be a list"),
])
def test_bad_descriptions_are_one_line_and_leave_no_file(tmp_path, change, fragment):
    description = fx.to_json([Binding(Trigger("while"), Sine(50.0, 0.2))])
    change(description)
    with pytest.raises(TextureError) as error:
        fx.from_json(description)
    assert fragment in str(error.value) and "\n" not in str(error.value)
    effects = tmp_path / "bad.json"
    effects.write_text(json.dumps(description))
    out = tmp_path / "out.wav"
    line = assert_one_line_error(run_cli("export", "grating-1mm", "-o", out, "--effects", effects))
    assert fragment in line and str(effects) in line
    assert not out.exists() and list(tmp_path.iterdir()) == [effects]


def test_a_texture_with_bad_effects_metadata_is_refused_in_one_line(tmp_path):
    path = uniform(tmp_path, 0.5, effects=(Binding(Trigger("while"), Sine(50.0, 0.2)),))
    from PIL import Image, PngImagePlugin

    with Image.open(path) as image:
        image.load()
        meta = json.loads(image.info["ultraglide"])
        meta["effects"]["bindings"][0]["effect"]["frequency_hz"] = -3
        info = PngImagePlugin.PngInfo()
        info.add_itxt("ultraglide", json.dumps(meta))
        image.save(path, pnginfo=info)
    line = assert_one_line_error(run_cli("export", path, "-o", tmp_path / "out.wav"))
    assert "effects: binding 1: effect frequency_hz must lie in (0, 2000] Hz, got -3" in line
    assert not (tmp_path / "out.wav").exists()


# ---- the real-time path ----------------------------------------------------------------------------------------

def block_path_memory(n: int) -> tuple[int, int, int]:
    """(bytes kept, peak bytes above the start, voices started) over blocks of ``n`` samples once running."""
    bindings = (Binding(Trigger("while"), fx.buzz()), Binding(Trigger("cross", lines_mm=tuple(np.arange(1.0, 60.0))),
                                                              fx.click()),
                Binding(Trigger("start", (0.0, 0.0, 2.0, 10.0)), fx.snap()))
    player = EffectPlayer(bindings, CONTROL)
    times, x, y, ratio, index = np.zeros(n), np.zeros(n), np.full(n, 5.0), np.full(n, 0.8), np.arange(n, dtype=float)
    step_s = 0.02 / n  # a block is 20 ms of path whatever its length: the same events either way

    def blocks(first, count):
        for k in range(first, first + count):
            np.add(index, k * n, out=times)
            np.multiply(times, step_s, out=times)
            np.multiply(times, 100.0, out=x)  # 100 mm/s: crosses a line every 10 ms, starting and ending clicks
            player.mix(times, x, y, True, ratio)

    blocks(0, 20)  # every kind of voice has started and ended once
    started = player.started
    tracemalloc.start()
    try:
        before, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        blocks(20, 20)
        after, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return after - before, peak - before, player.started - started


def test_the_block_path_allocates_nothing_once_running():
    """No array is made per block: the peak does not grow with the block's length (one temporary of 1024
    samples would be 8 kB), and nothing is kept per block or per voice."""
    kept_small, peak_small, started_small = block_path_memory(8)
    kept_large, peak_large, started_large = block_path_memory(1024)
    assert started_small == started_large >= 15  # clicks go on starting and ending
    assert peak_large - peak_small < 4096, (peak_small, peak_large)
    assert kept_large < 4096  # one block of 1024 samples kept would be 8 kB (and this ran 20)


def test_the_engine_plays_a_named_event(tmp_path):
    """Through the engine's door: the event's pulse lowers the target friction the engine publishes."""
    from ultraglide.render.engine import Engine, EngineConfig, EngineError

    pulse = Binding(Trigger("event", name="pressed"), Constant(0.5, 0.4))
    texture = uniform(tmp_path, 0.9, effects=(pulse,))
    with Engine.start(EngineConfig(texture=str(texture), device="null", realtime_priority=False)) as engine:
        engine.wait_ready(60)
        assert engine.trigger("pressed") is True
        assert engine.trigger("released") is False
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:  # until the pulse has come and gone
            status = engine.status()
            ratio = status.history.target_ratio
            if status.device_status.get("effects_started") == 1 and len(ratio) and ratio.min() < 0.5 \
                    and ratio[-1] > 0.5 and np.argmin(ratio) < len(ratio) - 1:
                break
            time.sleep(0.05)
        ratio, t = status.history.target_ratio, status.history.time_s
        assert ratio.min() == pytest.approx(0.4, abs=1e-4)  # (16-bit texture values)
        assert ratio[-1] == pytest.approx(0.9, abs=1e-4)
        during = t[ratio < 0.5]
        # the pulse's length, seen in one history row a block (5 ms, longer when a loaded machine makes the
        # null sink catch up): never longer than 0.4 s, and not much shorter
        assert 0.3 <= during[-1] - during[0] <= 0.42
        with pytest.raises(EngineError, match="effects version 9"):
            engine.set_effects({"effects_version": 9, "bindings": []})
        engine.set_effects({"effects_version": 1, "bindings": []})
        assert engine.trigger("pressed") is False


# ---- the widgets scene --------------------------------------------------------------------------------------------

def test_the_widgets_scene_clicks_pulses_at_detents_buzzes_and_snaps(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    from ultraglide.apps.demo.app import DemoApp

    demo = DemoApp([], device_url="null", windowed=True, screen_width_mm=338.7)
    try:
        texture, placements = demo.widgets
    finally:
        demo.close()
    labels = [binding.label for binding in texture.effects]
    assert labels == ["button click", "slider detent", "slider buzz", "toggle snap"]
    button, slider, toggle = placements[:3]
    # a finger pressing the button's middle, then dragging along the slider's track at 100 mm/s
    bx, by = button.x_mm + button.texture.width_mm / 2, button.y_mm + button.texture.height_mm / 2
    sy = slider.y_mm + slider.texture.height_mm / 2
    x0, x1 = slider.x_mm + 1.0, slider.x_mm + slider.texture.width_mm - 1.0
    drag_s = (x1 - x0) / 100.0
    press = RecordedTrajectory([0.0, 0.1], [bx, bx], [by, by])
    player, _, _ = run_player(texture.effects, press, 8, end_s=0.1)
    assert [(k, t) for k, t in player.starts] == [(0, 0.0)]
    drag = RecordedTrajectory([0.0, drag_s], [x0, x1], [sy, sy])
    player, _, mixed = run_player(texture.effects, drag, 8)
    detents = slider.texture.authoring["detents"]
    stops = slider.x_mm + np.linspace(0.08, 0.92, detents) * slider.texture.width_mm
    crossings = [start for k, start in player.starts if k == 1]
    assert crossings == pytest.approx([first_sample_at_or_after((s - x0) / 100.0) for s in stops], abs=1e-9)
    assert [k for k, _ in player.starts].count(2) == 1  # the buzz: once, held while moving
    assert mixed.min() < 0.9  # it is felt: friction goes down below the track's own
    tx, ty = toggle.x_mm + toggle.texture.width_mm * 0.75, toggle.y_mm + toggle.texture.height_mm / 2
    player, _, _ = run_player(texture.effects, RecordedTrajectory([0.0, 0.1], [tx, tx], [ty, ty]), 8, end_s=0.1)
    assert [k for k, _ in player.starts] == [3]


# ---- effects beyond the library: play, texture effects, texture compose ------------------------------------
BUZZ = {"effects_version": 1, "bindings": [{"trigger": {"on": "while"}, "label": "buzz everywhere",
                                            "effect": {"type": "sine", "frequency_hz": 40.0, "depth": 0.6}}]}


def _at_rest(tmp_path, bindings=()):
    """A 80 × 50 mm texture at rest everywhere (ratio 1): the plate only moves for its effects."""
    return save_texture(Texture(np.ones((50, 80), np.float32), 80.0, 50.0, name="rest", effects=bindings),
                        tmp_path / "rest.png")


def _peak(wav):
    samples, _ = soundfile.read(wav)
    return float(np.abs(samples).max())


def test_play_plays_effects_from_a_file_and_leaves_them_out_when_asked(tmp_path):
    (tmp_path / "buzz.json").write_text(json.dumps(BUZZ))
    rest = _at_rest(tmp_path)
    result = run_cli("play", rest, "--device", f"wav:{tmp_path / 'buzz.wav'}", "--effects", tmp_path / "buzz.json",
                     "--duration-s", 1, "--json", check=True)
    assert json.loads(result.stdout)["effects_started"] == 1 and _peak(tmp_path / "buzz.wav") > 0.2
    with_buzz = _at_rest(tmp_path, fx.from_json(BUZZ))  # saved with the texture, left out on request
    result = run_cli("play", with_buzz, "--device", f"wav:{tmp_path / 'none.wav'}", "--no-effects",
                     "--duration-s", 1, "--json", check=True)
    assert json.loads(result.stdout)["effects_started"] == 0 and _peak(tmp_path / "none.wav") < 1e-6
    line = assert_one_line_error(run_cli("play", rest, "--effects", tmp_path / "missing.json"))
    assert "no such effects file" in line


def test_texture_effects_lists_sets_adds_and_clears(tmp_path):
    (tmp_path / "buzz.json").write_text(json.dumps(BUZZ))
    rest = _at_rest(tmp_path)
    assert "rest: no temporal effects" in run_cli("texture", "effects", rest, check=True).stdout
    run_cli("texture", "effects", rest, "--set", tmp_path / "buzz.json", "-o", tmp_path / "one.png", check=True)
    assert [b.label for b in load_texture(tmp_path / "one.png").effects] == ["buzz everywhere"]
    words = run_cli("texture", "effects", tmp_path / "one.png", check=True).stdout
    assert words.splitlines() == ["rest: 1 temporal effect", "  1. buzz everywhere: while the finger is down anywhere"]
    listed = json.loads(run_cli("texture", "effects", tmp_path / "one.png", "--json", check=True).stdout)
    assert fx.from_json(listed) == fx.from_json(BUZZ)
    other = {"effects_version": 1, "bindings": [{"trigger": {"on": "cross", "lines_mm": [20.0]}, "label": "edge",
                                                 "effect": {"type": "constant", "level": 0.5, "length_s": 0.02}}]}
    (tmp_path / "edge.json").write_text(json.dumps(other))
    run_cli("texture", "effects", tmp_path / "one.png", "--add", tmp_path / "edge.json", "-o", tmp_path / "one.png",
            check=True)  # in place
    assert [b.label for b in load_texture(tmp_path / "one.png").effects] == ["buzz everywhere", "edge"]
    run_cli("texture", "effects", tmp_path / "one.png", "--clear", "-o", tmp_path / "none.png", check=True)
    assert load_texture(tmp_path / "none.png").effects == ()
    assert load_texture(tmp_path / "none.png").values.tolist() == load_texture(rest).values.tolist()
    assert "give -o" in assert_one_line_error(run_cli("texture", "effects", rest, "--clear"))
    assert "--set, --add or --clear" in assert_one_line_error(run_cli("texture", "effects", rest, "-o",
                                                                      tmp_path / "x.png"))


def _binding(label, region=None, lines=()):
    trigger = Trigger("cross", region, lines_mm=lines) if lines else Trigger("start", region)
    return Binding(trigger, fx.click(), label=label)


def test_composing_keeps_every_inputs_effects_where_they_were():
    from ultraglide.textures import compose as combine

    a = procedural.grating(size_mm=(40.0, 30.0)).with_(name="a", effects=(_binding("a anywhere"),))
    b = procedural.grating(size_mm=(40.0, 30.0)).with_(name="b", effects=(_binding("b box", (5.0, 5.0, 10.0, 10.0)),
                                                                         _binding("a anywhere")))
    mixed = combine.mix([a, b])
    assert [binding.label for binding in mixed.effects] == ["a anywhere", "b box"]  # each once
    assert mixed.effects[1].trigger.region_mm == (5.0, 5.0, 10.0, 10.0)  # where it was: inputs lie from the origin
    assert [binding.label for binding in combine.multiply([a, b]).effects] == ["a anywhere", "b box"]
    # tiled inside a region: what played anywhere plays in the region; a box is repeated in every tile there
    inner = procedural.grating(size_mm=(10.0, 10.0)).with_(name="inner", effects=(
        _binding("inner anywhere"), _binding("inner box", (2.0, 2.0, 4.0, 4.0)), _binding("line", lines=(5.0,))))
    tiled = combine.tile_inside(inner, a, (10.0, 5.0, 20.0, 10.0))
    regions = {binding.trigger.region_mm for binding in tiled.effects if binding.label == "inner box"}
    assert regions == {(12.0, 7.0, 4.0, 4.0), (22.0, 7.0, 4.0, 4.0)}  # two tiles across, one down
    anywhere = next(binding for binding in tiled.effects if binding.label == "inner anywhere")
    assert anywhere.trigger.region_mm == (10.0, 5.0, 20.0, 10.0)
    assert {binding.trigger.lines_mm for binding in tiled.effects if binding.label == "line"} == {(15.0,), (25.0,)}
    assert tiled.effects[0].label == "a anywhere"  # the outer's own, kept
    # placed on a canvas: moved to where each texture sits
    canvas = combine.compose((100.0, 60.0), [combine.Placement(b, 30.0, 20.0)])
    moved = {binding.label: binding.trigger.region_mm for binding in canvas.effects}
    assert moved == {"b box": (35.0, 25.0, 10.0, 10.0), "a anywhere": (30.0, 20.0, 40.0, 30.0)}


def test_compose_from_the_command_line_keeps_effects_or_leaves_them_out(tmp_path):
    with_buzz = _at_rest(tmp_path, fx.from_json(BUZZ))
    result = run_cli("texture", "compose", "mix", with_buzz, "grating-1mm", "-o", tmp_path / "mix.png", check=True)
    assert "the inputs' 1 temporal effect kept" in result.stdout
    assert [b.label for b in load_texture(tmp_path / "mix.png").effects] == ["buzz everywhere"]
    run_cli("texture", "compose", "mix", with_buzz, "grating-1mm", "--no-effects", "-o", tmp_path / "bare.png",
            check=True)
    assert load_texture(tmp_path / "bare.png").effects == ()
