"""Meta Haptics Studio .haptic files as friction effects: the amplitude envelope as the depth of a modulation whose
frequency follows the frequency envelope, emphasis as pulses; bad files refused in one line."""

import json

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli


def total(bindings, t):
    from ultraglide.render.effects import sample

    return sum(sample(binding.effect, np.asarray(t, float)) for binding in bindings)


def haptic(amplitude, frequency=(), extra=None) -> dict:
    document = {"version": {"major": 1, "minor": 0, "patch": 0}, "metadata": {"editor": "test"},
                "signals": {"continuous": {"envelopes": {"amplitude": list(amplitude), "frequency": list(frequency)}}}}
    document["signals"].update(extra or {})
    return document


def test_the_amplitude_envelope_is_the_depth_and_the_frequency_envelope_the_rate(tmp_path):
    from ultraglide.textures.effects import load_effects

    path = tmp_path / "ramp.haptic"
    path.write_text(json.dumps(haptic(
        [{"time": 0.0, "amplitude": 0.0}, {"time": 0.5, "amplitude": 1.0, "emphasis": {"amplitude": 0.7,
                                                                                       "frequency": 0.0}}],
        [{"time": 0.0, "frequency": 0.0}, {"time": 0.5, "frequency": 1.0}])))
    bindings = load_effects(path)
    # the stretch's frequency is the envelope's at its middle, 0.5: 50 + 0.5 × 250 = 175 Hz; the modulation
    # (1 - cos 2πft)/2 peaks at half periods, where the drop is the amplitude envelope itself (t / 0.5)
    t = 43.5 / 175.0
    assert total(bindings, [t])[0] == pytest.approx(t / 0.5, abs=1e-3)
    assert total(bindings, [44 / 175.0])[0] == pytest.approx(0.0, abs=1e-3)
    # the emphasis at 0.5 s: a pulse of 0.7 for 20 ms (frequency 0: the dullest)
    assert total(bindings, [0.51])[0] == pytest.approx(0.7)
    assert total(bindings, [0.521])[0] == pytest.approx(0.0, abs=1e-9)


def test_other_signals_are_said_not_rendered(tmp_path):
    from ultraglide.textures.effects import load_effects

    path = tmp_path / "two.haptic"
    path.write_text(json.dumps(haptic([{"time": 0.0, "amplitude": 0.5}, {"time": 0.1, "amplitude": 0.5}],
                                      extra={"audio": {}})))
    with pytest.warns(UserWarning, match="'audio' signals are not rendered"):
        assert len(load_effects(path)) == 1


def test_bad_haptic_files_are_refused_in_one_line(tmp_path):
    texture = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    cases = {
        "backwards.haptic": haptic([{"time": 0.5, "amplitude": 0.1}, {"time": 0.1, "amplitude": 0.2}]),
        "loud.haptic": haptic([{"time": 0.0, "amplitude": 0.1}, {"time": 0.1, "amplitude": 2.0}]),
        "one.haptic": haptic([{"time": 0.0, "amplitude": 0.1}]),
        "long.haptic": haptic([{"time": 0.0, "amplitude": 0.1}, {"time": 300.0, "amplitude": 0.2}]),
        "none.haptic": {"version": {"major": 1}},
    }
    for name, document in cases.items():
        (tmp_path / name).write_text(json.dumps(document))
        result = run_cli("texture", "effects", texture, "--set", tmp_path / name, "-o", tmp_path / "out.png")
        assert name in assert_one_line_error(result)
        assert not (tmp_path / "out.png").exists()
