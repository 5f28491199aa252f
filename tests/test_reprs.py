"""Objects print themselves in words a person reads: name, size, parameters, state; never a whole array or an
address. Models print as the constructor call that makes them again."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
from ultraglide.render.physics.fingerprint import FingerParams

import ultraglide

ADDRESS = re.compile(r"0x[0-9a-f]{6,}|object at")


def test_texture_prints_name_size_and_pixels_not_its_array():
    texture = ultraglide.grating(2.0, (30.0, 20.0)).with_(name="g2")
    text = repr(texture)
    assert text == f"Texture('g2', 30 × 20 mm, {texture.cols} × {texture.rows} px)"
    assert len(text) < 80 and "array" not in text


def test_profile_prints_resonance_q_and_limits():
    assert repr(ultraglide.load_profile("sim-plate")) == "PlateProfile('sim-plate', 25 kHz, Q 200, limit 6 µm p-p, " \
                                                         "drive up to 8)"
    plain = ultraglide.PlateProfile("p", 27830.0, 150.0, 10.0, 4.0)
    assert repr(plain) == "PlateProfile('p', 27.83 kHz, Q 150, limit 4 µm p-p)"


@pytest.mark.parametrize("model", [
    ultraglide.ExponentialModel(1.1),
    ultraglide.StretchedExponentialModel(3.0, 1.5, 0.25),
    ultraglide.PaperModel(),
    ultraglide.PaperModel(FingerParams(youngs_modulus_pa=2.0e6, friction_exponent=0.7)),
])
def test_models_print_as_the_call_that_makes_them_again(model):
    text = repr(model)
    again = eval(text, {**vars(ultraglide), "FingerParams": FingerParams})  # noqa: S307 - our own repr
    amplitudes = np.array([0.5, 2.0, 4.0])
    assert np.allclose(again.relative_friction(amplitudes, 0.4), model.relative_friction(amplitudes, 0.4), atol=1e-12)
    assert not ADDRESS.search(text)


def test_table_model_names_its_source_and_forces(tmp_path):
    data = tmp_path / "finger.csv"
    data.write_text("amplitude_um_pp,relative_friction,force_n\n0,1,0.2\n2,0.7,0.2\n4,0.4,0.2\n"
                    "0,1,1\n2,0.8,1\n4,0.6,1\n")
    assert repr(ultraglide.load_model(f"table:{data}")) == f"TableModel({str(data)!r}, forces 0.2–1 N)"


def test_renderer_and_output_stage_print_what_they_join():
    texture = ultraglide.grating(1.0, (20.0, 10.0)).with_(name="g1")
    profile = ultraglide.load_profile("sim-plate")
    renderer = ultraglide.Renderer(texture, ultraglide.ExponentialModel(), profile)
    assert repr(renderer) == (f"Renderer({texture!r}, ExponentialModel(tau_um_zp=1.32), plate 'sim-plate', live)")
    stage = ultraglide.output_stage(ultraglide.EnvelopeSource(renderer), profile, "audio", 96000)
    assert repr(stage) == "OutputStage(audio at 96000 Hz, carrier 25000 Hz, plate 'sim-plate', limit 6 µm p-p)"
    assert repr(ultraglide.EnvelopeSource(renderer)) == f"EnvelopeSource({renderer!r})"


@pytest.mark.slow
def test_engine_prints_device_state_and_blocks():
    config = ultraglide.EngineConfig(texture="grating-1mm", device="null", realtime_priority=False)
    with ultraglide.Engine.start(config) as engine:
        engine.wait_ready(120)
        deadline = time.monotonic() + 120
        while engine.status().blocks == 0 and time.monotonic() < deadline:  # the first block is on its way
            time.sleep(0.01)
        text = repr(engine)
        assert re.fullmatch(r"Engine<null, (running|paused), \d+ blocks>", text), text
    assert re.fullmatch(r"Engine<null, stopped, \d+ blocks>", repr(engine)), repr(engine)
