"""The engine at rest: while paused with nothing moving it serves zeros without running the renderer,
and the first touch after that renders again. The simulated plate is served here on a real pty."""

import math
import time

import numpy as np
import pytest
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.pty_plate import PtyPlate
from ultraglide.render.engine import Engine, EngineConfig
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture

# the default model, Monnoyer's law above a floor d = 0.1: d + (1 - d) exp(-(a_pp/2)^2 / (2 tau^2)), tau = 1.32 µm
# zero-to-peak, solved by hand for 0.5
HALF_FRICTION_UM_PP = 2 * 1.32 * math.sqrt(-2 * math.log((0.5 - 0.1) / (1 - 0.1)))  # 3.362 µm p-p
SLIPPERY = (60.0, 25.0)


def until(condition, timeout=30.0, engine=None, where=None):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if engine is not None:
            engine.touch(time.perf_counter(), *where)
        if condition():
            return True
        time.sleep(1 / 120)
    return False


def test_paused_engine_rests_the_renderer_and_wakes_on_a_touch(tmp_path):
    texture = Texture(np.array([[1.0, 0.5]], dtype=np.float32), 80.0, 50.0, outside="clamp", name="steps")
    path = str(save_texture(texture, tmp_path / "steps.png"))
    plate = PtyPlate(load_profile("sim-plate")).start()
    sim = plate.simulator
    try:
        with Engine.start(EngineConfig(texture=path, device=f"serial:{plate.path}", start_paused=True)) as engine:
            engine.wait_ready(60)
            # paused from the start: after the first block everything is at zero, so blocks are served resting
            assert until(lambda: engine.status().resting_blocks > 100)
            status = engine.status()
            assert status.blocks - status.resting_blocks < 50 and sim.amplitude_um_pp < 0.01
            engine.pause(False)
            assert until(lambda: abs(sim.amplitude_um_pp - HALF_FRICTION_UM_PP) < 0.02, engine=engine, where=SLIPPERY)
            rendering = engine.status()
            assert rendering.history.target_ratio[-1] == pytest.approx(0.5, abs=1e-3)
            assert rendering.block_p50_us is not None
            engine.pause(True)  # ramps down, then rests again
            assert until(lambda: engine.status().resting_blocks > rendering.resting_blocks + 100)
            assert until(lambda: sim.amplitude_um_pp < 0.01)
            assert engine.status().history.commanded_um_pp[-1] == 0.0
    finally:
        plate.stop()
