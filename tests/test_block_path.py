"""The engine's block path allocates nothing once running, and its allocation-free stages (``out=``)
give what the allocating ones give.

The block path is :class:`render.engine_process.EngineSource`'s ``pull``: drain the shared touch ring,
render (finger line, texture lookup, model inverse, envelope), limit, put on the carrier, publish the
status. Memory is measured with tracemalloc, which sees numpy's array data too (its own domain)."""

import math
import tracemalloc
import types

import numpy as np
import pytest
from ultraglide.devices.carrier import Carrier
from ultraglide.devices.output_stage import OutputStage
from ultraglide.devices.profiles import load_profile
from ultraglide.render.calibration import load_model
from ultraglide.render.engine_process import EngineSource
from ultraglide.render.engine_shm import SharedBlock
from ultraglide.render.friction_models import ExponentialModel, PaperModel, StretchedExponentialModel
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


def block_path_memory(texture: str, model: str, signal: str, frames: int, blocks: int) -> tuple[int, int, int]:
    """(bytes kept, peak bytes above the start, numpy data bytes kept) over ``blocks`` pulls of ``frames``."""
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
                    ui.push_touch(t, *finger(t), 0.5 if k % 8 else math.nan, 1.0)
                source.pull(frames, clock["t"])
                clock["t"] += period_s

        pulls(300)  # every stage has run, every lookup level has been read
        tracemalloc.start()
        try:
            before, _ = tracemalloc.get_traced_memory()
            first = tracemalloc.take_snapshot()
            tracemalloc.reset_peak()
            pulls(blocks)
            after, peak = tracemalloc.get_traced_memory()
            numpy_only = tracemalloc.DomainFilter(True, np.lib.tracemalloc_domain)
            last = tracemalloc.take_snapshot()
            kept_data = sum(stat.size_diff for stat in last.filter_traces([numpy_only]).compare_to(
                first.filter_traces([numpy_only]), "filename"))
        finally:
            tracemalloc.stop()
        assert ui.touch_index[1] == ui.touch_index[0] > 0  # every touch went through the ring into the renderer
        assert renderer.counters.control_samples > 0 and float(np.abs(source.limiter.fast_plate_um_pp)) > 0
        return after - before, peak - before, kept_data
    finally:
        engine_side.close()
        ui.close()


@pytest.mark.parametrize("texture, model, signal", [("grating-1mm", "exponential", "audio"),
                                                    ("bumps", "paper", "audio"),
                                                    ("bumps", "stretched", "control")])
def test_the_engine_block_path_allocates_nothing_once_running(texture, model, signal):
    """A block of 8 control samples (64 audio frames) and one of 1024 (8192 frames) use the same memory:
    one array of the block's length made anywhere on the path (a lookup, an inverse, the envelope, knots,
    the output) would be 8 kB or more in the larger. Nothing is kept, block after block."""
    up = RATE_HZ // 12000 if signal == "audio" else 1
    small = block_path_memory(texture, model, signal, 8 * up, 200)
    large = block_path_memory(texture, model, signal, 1024 * up, 200)
    longer = block_path_memory(texture, model, signal, 8 * up, 400)
    assert large[1] - small[1] < 1024
    assert small[2] == large[2] == longer[2] == 0  # no array data kept
    assert abs(longer[0] - small[0]) < 512  # nothing kept per block
