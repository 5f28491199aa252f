"""The engine's block path allocates nothing once running, and its allocation-free stages (``out=``)
give what the allocating ones give.

The block path is :class:`render.engine.process.EngineSource`'s ``pull``: drain the shared touch ring,
render (finger line, texture lookup, model inverse, envelope), limit, put on the carrier, publish the
status. Memory is measured with tracemalloc, which sees numpy's array data too (its own domain)."""

import math
import tracemalloc
import types

import numpy as np
import pytest
from conftest import ROOT
from ultraglide.devices.output.carrier import Carrier
from ultraglide.devices.output.stage import OutputStage
from ultraglide.devices.profiles import load_profile
from ultraglide.render.engine.process import EngineSource
from ultraglide.render.engine.shm import SharedBlock
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.friction_models import ExponentialModel, PaperModel, StretchedExponentialModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

RATE_HZ = 96000


def finger(t_s: float) -> tuple[float, float]:
    """A finger circling at 0.2-1.9 m/s (mm): slow enough to read the full-resolution level, fast
    enough to blend coarser levels of the band-limited lookup."""
    speed = 1.0 + 0.8 * math.sin(3.0 * t_s)
    return 40 + 30 * math.cos(speed * t_s * 20), 25 + 15 * math.sin(speed * t_s * 20)


TRACE_DEPTH = 64  # frames kept per allocation: from the deepest stage of the block path up to ``pulls``
TABLE = f"table:{ROOT / 'apps' / 'data' / 'monnoyer2018-fit.csv'}"


def block_path_memory(texture: str, model: str, signal: str, frames: int, blocks: int,
                      pressing: bool = False) -> tuple[int, int, int]:
    """(bytes kept, peak bytes above the start, numpy data bytes kept) over ``blocks`` pulls of ``frames``;
    ``pressing``: the finger's force moves every report (0.05-0.55 N, as a pressure panel's), else 0.5 N."""
    ui = SharedBlock.create()
    engine_side = SharedBlock.attach(ui.name)
    try:
        rate = RATE_HZ if signal == "audio" else 12000
        renderer = Renderer(resolve_texture(texture), load_model(model), load_profile("sim-plate"),
                            RenderSettings(audio_rate_hz=RATE_HZ))
        # the facts a device states about itself: all the block path reads of it
        device = types.SimpleNamespace(signal=signal, rate_hz=rate, carrier_hz=None)
        source = EngineSource(renderer, engine_side, device, raise_priority_=False)
        period_s = frames / rate
        clock = {"t": 1000.0}

        def pulls(count):
            for k in range(count):
                if k % 4 == 0:  # touch reports at a few per block, as a fast panel gives them
                    t = clock["t"]
                    force = 0.3 + 0.25 * math.sin(7.0 * t) if pressing else 0.5 if k % 8 else math.nan
                    ui.push_touch(t, *finger(t), force, 1.0)
                source.pull(frames, clock["t"])
                clock["t"] += period_s

        pulls(300)  # every stage has run, every lookup level has been read
        # what is kept is counted from the allocations made under ``pulls`` (tracebacks deep enough to reach it):
        # a test worker's other threads (pytest-xdist's messages) allocate at moments of their own, which the
        # process's total counted as kept (1170 bytes, in some runs only, on a loaded machine)
        tracemalloc.start(TRACE_DEPTH)
        try:
            first = tracemalloc.take_snapshot()
            before, _ = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            pulls(blocks)
            _, peak = tracemalloc.get_traced_memory()
            last = tracemalloc.take_snapshot()
        finally:
            tracemalloc.stop()

        def kept(*only):  # the filters each narrow (a list of inclusive filters would keep what any one matches)
            snapshots = [snapshot.filter_traces([tracemalloc.Filter(True, __file__, all_frames=True)])
                         for snapshot in (first, last)]
            for one in only:
                snapshots = [snapshot.filter_traces([one]) for snapshot in snapshots]
            return sum(stat.size_diff for stat in snapshots[1].compare_to(snapshots[0], "filename"))
        assert ui.touch_index[1] == ui.touch_index[0] > 0  # every touch went through the ring into the renderer
        assert renderer.counters.control_samples > 0 and float(np.abs(source.limiter.fast_plate_um_pp)) > 0
        return kept(), peak - before, kept(tracemalloc.DomainFilter(True, np.lib.tracemalloc_domain))
    finally:
        engine_side.close()
        ui.close()


@pytest.mark.parametrize("texture, model, signal, pressing", [
    ("grating-1mm", "exponential", "audio", False), ("bumps", "paper", "audio", False),
    ("bumps", "stretched", "control", False), ("grating-1mm", TABLE, "audio", False),
    ("grating-1mm", "dynamic", "control", False), ("grating-1mm", "speed:0.5:stretched", "audio", False),
    ("grating-1mm", "speed:0.5:dynamic", "control", False), ("grating-1mm", "dynamic", "control", True),
    ("grating-1mm", "speed:0.5:stretched", "audio", True), ("grating-1mm", "speed:0.5:dynamic", "control", True)],
    ids=["exponential", "paper", "stretched", "table", "dynamic-planned", "speed-law", "speed-law-planned",
         "dynamic-planned-pressing", "speed-law-pressing", "speed-law-planned-pressing"])
def test_the_engine_block_path_allocates_nothing_once_running(texture, model, signal, pressing):
    """A block of 8 control samples (64 audio frames) and one of 1024 (8192 frames) use the same memory:
    one array of the block's length made anywhere on the path (a lookup, an inverse, the envelope, knots,
    the output) would be 8 kB or more in the larger. Nothing is kept, block after block, also when the force
    moves with every report (a floor remembered per force would be kept)."""
    up = RATE_HZ // 12000 if signal == "audio" else 1
    small = block_path_memory(texture, model, signal, 8 * up, 200, pressing)
    large = block_path_memory(texture, model, signal, 1024 * up, 200, pressing)
    longer = block_path_memory(texture, model, signal, 8 * up, 400, pressing)
    # the peak counts every thread's allocations, a test worker's message thread too (6-8 kB at moments of its
    # own, beside other workers): an array of the path's is made on every pass, so the least of three is judged
    for _ in range(2):
        if large[1] - small[1] < 4096:
            break
        large = min(large, block_path_memory(texture, model, signal, 1024 * up, 200, pressing),
                    key=lambda measured: measured[1])
    assert large[1] - small[1] < 4096  # an array of 1024 control samples is 8 kB
    assert small[2] == large[2] == longer[2] == 0  # no array data kept
    assert abs(longer[0] - small[0]) < 512  # nothing kept per block


def textures_for_lookup():
    ramp = np.linspace(0.2, 1.0, 64 * 48, dtype=np.float32).reshape(48, 64)
    noise = np.random.default_rng(3).random((48, 64)).astype(np.float32)
    return [resolve_texture("grating-1mm"), resolve_texture("bumps"),
            Texture(noise, 64.0, 48.0, outside="fixed", outside_ratio=0.3, name="fixed"),
            Texture(ramp * noise, 64.0, 48.0, outside="clamp", name="clamped"),
            Texture(noise, 64.0, 48.0, kind="gradient", outside="fixed", outside_ratio=0.7, name="hills")]


@pytest.mark.parametrize("texture", textures_for_lookup(), ids=lambda t: t.name)
def test_the_lookup_into_a_buffer_gives_what_the_allocating_lookup_gives(texture):
    """Positions inside and beyond the edges; steps finer than a pixel, between levels and beyond the
    coarsest; directions along x, diagonal and at rest. Friction maps: bit for bit (the same float32
    steps); height maps: to float32 rounding (the compiled pass blends in float64)."""
    sampler = Sampler(texture)
    x = np.linspace(-3.0, texture.width_mm + 3.0, 40)
    y = np.linspace(texture.height_mm + 2.0, -2.0, 40)
    out = np.empty(40, dtype=np.float32)
    for step in (None, 0.001, 0.37 * sampler.base_pixel_mm, 1.5 * sampler.base_pixel_mm, 5.0, 1e4):
        for direction in ((1.0, 0.0), (0.3, -0.3), (0.0, 0.0)):
            expected = sampler.ratio(x, y, step_mm=step, direction=direction)
            got = sampler.ratio(x, y, step_mm=step, direction=direction, out=out)
            assert got is out
            if texture.kind == "friction":
                np.testing.assert_array_equal(got, expected)
            else:
                np.testing.assert_allclose(got, expected, atol=2e-6)
    if texture.outside == "fixed":  # beyond the edges: the texture's outside ratio
        assert out[0] == out[-1] == np.float32(texture.outside_ratio)


@pytest.mark.parametrize("model", [ExponentialModel(), PaperModel(), StretchedExponentialModel(shape=1.3),
                                   load_model(f"table:{ROOT / 'apps' / 'data' / 'monnoyer2018-fit.csv'}")],
                         ids=lambda m: m.name)
def test_the_inverse_into_a_buffer_gives_what_the_allocating_inverse_gives(model):
    ratio = np.array([1.2, 1.0, 0.97, 0.6, 0.3, 0.05, 0.0], dtype=np.float32)
    out = np.empty(len(ratio))
    for force in (0.5, 0.2, np.array([0.5, 0.1, 0.3, 2.0, 0.5, 0.5, 0.05])):
        expected = model.amplitude_um_pp(ratio, force, 6.0)
        got = model.amplitude_um_pp(ratio, force, 6.0, out=out)
        assert got.amplitude_um_pp is out and got.clamped == expected.clamped
        np.testing.assert_array_equal(out, expected.amplitude_um_pp)
    assert out[0] == out[1] == 0.0 and out[-1] == 6.0  # rest at 1 and above; out of reach: the limit


def test_the_table_models_compiled_inverse_at_one_force_gives_the_interpolated_tables():
    """The scalar-force kernel (a panel without pressure sensing) against the model's general numpy path
    (interpolating the same per-force tables in numpy) at forces between, on and beyond the measured ones."""
    from ultraglide.render.physics.friction_models import FrictionModel
    model = load_model(TABLE)
    ratio = np.linspace(1.1, 0.0, 400)
    out = np.empty(len(ratio))
    for force in (0.05, *model.forces, 0.37, 3.0):
        expected = FrictionModel.amplitude_um_pp(model, ratio, force, 4.0)
        got = model.amplitude_um_pp(ratio, force, 4.0, out=out)
        np.testing.assert_allclose(out, expected.amplitude_um_pp, rtol=1e-12, atol=1e-12)
        assert got.clamped == expected.clamped > 0


class Ramp:
    """An envelope source: a drive rising 0.05 µm p-p a control sample, past the limit."""

    control_rate_hz = 12000.0
    finished = False

    def __init__(self):
        self.sent = 0

    def pull(self, n, now_s):
        values = 0.05 * np.arange(self.sent, self.sent + n)
        self.sent += n
        return values

    def request_stop(self):
        pass


@pytest.mark.parametrize("carrier_hz", [25000.0, 25000.123456])  # one exact period; an accumulated phase
def test_the_output_stage_into_a_buffer_gives_what_it_gives_without(carrier_hz):
    """Blocks that end inside control periods and whole ones, through the limiter and onto the carrier."""
    profile = load_profile("sim-plate")
    plain = OutputStage(Ramp(), profile, "audio", RATE_HZ, carrier_hz)
    buffered = OutputStage(Ramp(), profile, "audio", RATE_HZ, carrier_hz)
    assert (plain.carrier.period > 0) == (carrier_hz == 25000.0)
    out = np.empty(4096, dtype=np.float32)
    for frames in (64, 61, 3, 8, 128, 1000, 64, 2048, 7):
        expected = plain.pull(frames, None)
        got = buffered.pull(frames, None, out[:frames])
        np.testing.assert_array_equal(got, expected)
    assert plain.limiter.limited_samples == buffered.limiter.limited_samples > 0  # the ramp passed the limit
    # and on the carrier the envelope reaches the limit, no more: |sample| <= limit / full scale
    assert np.abs(out[:7]).max() <= profile.max_amplitude_um_pp / profile.full_scale_um_pp + 1e-6
    carrier = Carrier(carrier_hz, RATE_HZ)
    first = carrier.block(100)
    again = Carrier(carrier_hz, RATE_HZ)
    into = np.empty(100, dtype=np.float32)
    np.testing.assert_array_equal(again.block(100, into if not again.period else None), first)


@pytest.mark.parametrize("texture", [t for t in textures_for_lookup() if t.kind == "friction"], ids=lambda t: t.name)
def test_a_step_per_sample_reads_what_each_sample_reads_alone(texture):
    """An export's lookup (a step per sample, one compiled pass over the pyramid) against asking for each
    sample alone with its step as one number (the per-level numpy path): the same float32 values, at steps
    from finer than a pixel to coarser than the whole pyramid, inside and beyond the texture's edges."""
    sampler = Sampler(texture)
    rng = np.random.default_rng(11)
    n = 400
    x = rng.uniform(-0.2 * texture.width_mm, 1.2 * texture.width_mm, n)
    y = rng.uniform(-0.2 * texture.height_mm, 1.2 * texture.height_mm, n)
    step = np.exp(rng.uniform(math.log(1e-3), math.log(4 * texture.width_mm), n))
    step[::9] = 0.0
    together = sampler.ratio(x, y, step)
    alone = np.concatenate([sampler.ratio(x[i:i + 1], y[i:i + 1], float(step[i])) for i in range(n)])
    assert together.dtype == np.float32
    np.testing.assert_array_equal(together, alone)
    assert len(np.unique(together)) > n // 3  # the positions and levels really differ
