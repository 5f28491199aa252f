"""Apple AHAP patterns as friction effects: intensity as depth, sharpness as the modulation's frequency, transients
as pulses, intensity curves as envelopes; what a friction display cannot render said; bad files refused."""

import json
import math
import os

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli

TAP = {"Version": 1.0, "Metadata": {"Project": "test"}, "Pattern": [
    {"Event": {"Time": 0.0, "EventType": "HapticTransient", "EventParameters": [
        {"ParameterID": "HapticIntensity", "ParameterValue": 0.8},
        {"ParameterID": "HapticSharpness", "ParameterValue": 1.0}]}},
    {"Event": {"Time": 0.1, "EventType": "HapticContinuous", "EventDuration": 0.5, "EventParameters": [
        {"ParameterID": "HapticIntensity", "ParameterValue": 0.6},
        {"ParameterID": "HapticSharpness", "ParameterValue": 0.2}]}},
    {"Event": {"Time": 0.2, "EventType": "AudioCustom", "EventWaveformPath": "x.wav"}},
    {"ParameterCurve": {"ParameterID": "HapticIntensityControl", "Time": 0.1, "ParameterCurveControlPoints": [
        {"Time": 0.0, "ParameterValue": 1.0}, {"Time": 0.5, "ParameterValue": 0.5}]}},
    {"ParameterCurve": {"ParameterID": "HapticSharpnessControl", "Time": 0.1, "ParameterCurveControlPoints": [
        {"Time": 0.0, "ParameterValue": 0.0}]}},
]}


def total(bindings, t):
    """The friction drop of every binding (all start when the finger lands) at times ``t``."""
    from ultraglide.render.effects import sample

    return sum(sample(binding.effect, np.asarray(t, float)) for binding in bindings)


@pytest.fixture
def tap(tmp_path):
    path = tmp_path / "tap.ahap"
    path.write_text(json.dumps(TAP))
    return path


def test_a_transient_is_a_pulse_and_a_continuous_event_a_modulation_under_its_intensity_curve(tap):
    from ultraglide.textures.effects import load_effects

    with pytest.warns(UserWarning) as said:
        bindings = load_effects(tap)
    notes = " ".join(str(w.message) for w in said)
    assert "AudioCustom" in notes and "HapticSharpnessControl" in notes  # said, not dropped silently
    # the transient: 0.8 deep, 5 ms long at sharpness 1
    assert total(bindings, [0.002, 0.004])[0] == pytest.approx(0.8)
    assert total(bindings, [0.006])[0] == pytest.approx(0.0, abs=1e-9)
    # the continuous event from 0.1 s: 50 + 0.2 × 250 = 100 Hz, depth 0.6 times the curve 1 -> 0.5 over 0.5 s;
    # (1 - cos 2πft)/2 is 1 at half periods: 0.255 s into it
    local = 0.255
    envelope = 0.6 * (1.0 - 0.5 * local / 0.5)
    assert total(bindings, [0.1 + local])[0] == pytest.approx(envelope, abs=1e-3)
    assert total(bindings, [0.1 + 0.25])[0] == pytest.approx(0.0, abs=1e-3)  # whole periods: no drop
    assert total(bindings, [0.65])[0] == pytest.approx(0.0, abs=1e-9)  # after its end


def test_attack_and_release_ramp_the_depth(tmp_path):
    from ultraglide.textures.effects import load_effects

    pattern = {"Pattern": [{"Event": {"Time": 0.0, "EventType": "HapticContinuous", "EventDuration": 1.0,
                                      "EventParameters": [{"ParameterID": "HapticIntensity", "ParameterValue": 1.0},
                                                          {"ParameterID": "HapticSharpness", "ParameterValue": 0.0},
                                                          {"ParameterID": "AttackTime", "ParameterValue": 0.2},
                                                          {"ParameterID": "ReleaseTime", "ParameterValue": 0.4}]}}]}
    path = tmp_path / "swell.ahap"
    path.write_text(json.dumps(pattern))
    bindings = load_effects(path)
    # 50 Hz: peaks at odd hundredths of a second
    assert total(bindings, [0.11])[0] == pytest.approx(0.11 / 0.2, abs=1e-3)
    assert total(bindings, [0.41])[0] == pytest.approx(1.0, abs=1e-3)
    assert total(bindings, [0.81])[0] == pytest.approx((1.0 - 0.81) / 0.4, abs=1e-3)


def test_effects_set_export_and_play_take_an_ahap(tap, tmp_path):
    texture, with_effects = tmp_path / "g.png", tmp_path / "ge.png"
    run_cli("texture", "new", "grating", "--size-mm", "40x20", "-o", texture, check=True)
    result = run_cli("texture", "effects", texture, "--set", tap, "-o", with_effects, check=True)
    assert "AudioCustom events are sound" in result.stderr
    listed = json.loads(run_cli("texture", "effects", with_effects, "--json", check=True).stdout)
    assert listed["bindings"][0]["trigger"] == {"on": "start"} and listed["bindings"][0]["label"] == "tap"
    summary = json.loads(run_cli("export", texture, "--effects", tap, "-o", tmp_path / "e.wav", "--duration-s", "0.5",
                                 "--json", check=True).stdout)
    assert summary["effects_started"] == 1


def test_bad_ahap_files_are_refused_in_one_line(tmp_path):
    texture = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    transient = {"Event": {"Time": 0.0, "EventType": "HapticTransient", "EventParameters": []}}
    many = {"Pattern": [{"Event": {**transient["Event"], "Time": k * 0.05}} for k in range(1000)]}
    cases = {
        "nan.ahap": '{"Pattern": [{"Event": {"Time": NaN, "EventType": "HapticTransient"}}]}',
        "deep.ahap": '{"Pattern": ' + "[" * 50_000 + "]" * 50_000 + "}",
        "late.ahap": json.dumps({"Pattern": [{"Event": {**transient["Event"], "Time": 500.0}}]}),
        "kind.ahap": json.dumps({"Pattern": [{"Event": {"Time": 0, "EventType": "HapticBuzz"}}]}),
        "many.ahap": json.dumps(many),
        "intensity.ahap": json.dumps({"Pattern": [{"Event": {"Time": 0, "EventType": "HapticTransient",
            "EventParameters": [{"ParameterID": "HapticIntensity", "ParameterValue": 3}]}}]}),
        "large.ahap": '{"Pattern": [' + ",".join([json.dumps(transient)] * 60_000) + "]}",
    }
    os.mkfifo(tmp_path / "pipe.ahap")
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
    for name in [*cases, "pipe.ahap"]:
        result = run_cli("texture", "effects", texture, "--set", tmp_path / name, "-o", tmp_path / "out.png",
                         timeout=60)
        line = assert_one_line_error(result)
        assert name in line, line
        assert not (tmp_path / "out.png").exists()


def test_sharpness_maps_into_what_a_plate_renders():
    from ultraglide.textures.formats.timeline import RENDERABLE_MAX_HZ, pulse_length_s, sharpness_hz

    assert sharpness_hz(0.0) == 50.0 and sharpness_hz(1.0) == 300.0 <= RENDERABLE_MAX_HZ
    assert pulse_length_s(0.0) == 0.020 and math.isclose(pulse_length_s(1.0), 0.005)


def test_demo_takes_effects_for_the_textures_given_and_refuses_a_bad_file_before_its_window(tap, tmp_path):
    refused = run_cli("demo", "--effects", tap)
    assert "--effects" in assert_one_line_error(refused)
    texture, bad = tmp_path / "g.png", tmp_path / "bad.ahap"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    bad.write_text('{"Pattern": [{"Event": {"Time": -1, "EventType": "HapticTransient"}}]}')
    result = run_cli("demo", texture, "--effects", bad, "--windowed", env={"DISPLAY": "", "SDL_VIDEODRIVER": "dummy"})
    assert "bad.ahap" in assert_one_line_error(result)
