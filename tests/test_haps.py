"""Interhaptics .haps files: the texture block (an amplitude over distance) as a grating along x, the vibration
block as friction effects; what a friction display cannot render said; hostile files refused in one line."""

import json
import math
import os

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from PIL import Image


def block(*melodies, loop=0):
    return {"m_loop": loop, "m_maximum": 1.0, "m_gain": 1.0, "m_signalEvaluationMethod": 3,
            "m_melodies": [{"m_mute": 0, "m_gain": gain, "m_notes": notes} for gain, notes in melodies]}


def note(start, length, keyframes=None, gain=1.0, frequencies=None, underlying_hz=None):
    effect = {}
    if underlying_hz is not None:
        effect["m_underlyingSignal"] = {"m_phase": 0.0, "m_amplitude": 1.0, "m_frequency": underlying_hz,
                                        "m_verticalOffset": 0.0, "m_signalType": 1}
    if keyframes is not None:
        effect["m_amplitudeModulation"] = {"m_extrapolationStrategy": 0,
                                           "m_keyframes": [{"m_time": t, "m_value": v} for t, v in keyframes]}
    if frequencies is not None:
        effect["m_frequencyModulation"] = {"m_extrapolationStrategy": 0,
                                           "m_keyframes": [{"m_time": t, "m_value": v} for t, v in frequencies]}
    return {"m_startingPoint": start, "m_length": length, "m_priority": 1, "m_gain": gain, "m_hapticEffect": effect}


def haps(texture=None, vibration=None, stiffness=None):
    return {"m_version": "5", "m_description": "", "m_HDFlag": 0, "m_time_unit": 0, "m_length_unit": 7,
            "m_stiffness": stiffness or block(), "m_texture": texture or block(),
            "m_vibration": vibration or block(), "m_gain": 1.0}


def png_ratios(path):
    """The texture file's first row as friction ratios, read by Pillow (16-bit gray codes over 65535)."""
    with Image.open(path) as image:
        codes = np.asarray(image, dtype=np.float64)
    assert np.all(codes == codes[0])  # constant across y: every row the same
    return codes[0] / 65535.0


def centres_mm(cols, width_mm):
    return (np.arange(cols) + 0.5) * width_mm / cols


def triangle(x):  # 0 at 0 mm, 1 at 2 mm, 0 at 4 mm: the first note below
    return np.where(x < 2.0, x / 2.0, (4.0 - x) / 2.0)


def test_a_texture_block_becomes_a_grating_along_x_in_metres(tmp_path):
    # a triangle 4 mm long (metres in the file: unit 7), then a transient bump 0.5 × 0.8 = 0.4 high for 2 mm
    path = tmp_path / "ridge.haps"
    path.write_text(json.dumps(haps(texture=block(
        (1.0, [note(0.0, 0.004, [(0.0, 0.0), (0.002, 1.0), (0.004, 0.0)])]),
        (0.8, [note(0.004, 0.002, gain=0.5)]), loop=1))))
    out = tmp_path / "ridge.png"
    result = run_cli("texture", "import", path, "--texel-range", "0.2", "1", "-o", out, check=True)
    assert "6 mm long" in result.stdout and "0.2 + 0.8" in result.stdout
    ratios = png_ratios(out)
    cols = ratios.size
    assert cols == 60  # 10 pixels per mm, the least density (the closest keyframes are 2 mm apart)
    x = centres_mm(cols, 6.0)
    amplitude = np.where(x < 4.0, triangle(x), 0.4)
    np.testing.assert_allclose(ratios, 0.2 + 0.8 * amplitude, atol=1.5 / 65535)
    info = json.loads(run_cli("texture", "info", out, "--json", check=True).stdout)
    assert info["width_mm"] == pytest.approx(6.0) and info["height_mm"] == pytest.approx(6.0)
    assert info["outside"] == "tile"  # the block loops: the grating repeats

    # --width-mm: the whole length spans it (the triangle's peak at 12 × 2/6 = 4 mm); no loop: its end held
    path.write_text(json.dumps(haps(texture=block((1.0, [note(0.0, 0.004, [(0.0, 0.0), (0.002, 1.0),
                                                                            (0.004, 0.0)])])))))
    run_cli("texture", "import", path, "--width-mm", "12", "-o", out, check=True)
    ratios = png_ratios(out)
    x = centres_mm(ratios.size, 12.0)
    np.testing.assert_allclose(ratios, triangle(x / 3.0), atol=1.5 / 65535)
    assert json.loads(run_cli("texture", "info", out, "--json", check=True).stdout)["outside"] == "clamp"


def test_haptic_composers_texture_file_its_bumps_and_what_is_not_rendered(tmp_path):
    # the shape of Interhaptics' own Texture.haps (Unity_CoreSDK/Assets/HapticEffects): square bumps with steep
    # edges over 1.017 m, a 182.5 Hz vibration under them, and a vibration block over time
    edges = [(0.0, 1.0), (0.030533, 1.0), (0.031671, 0.0), (0.101841, 0.0), (0.102789, 1.0), (0.132184, 1.0),
             (0.132943, 0.0), (1.017322, 0.0)]
    document = haps(texture=block((1.0, [note(0.0, 1.017322, edges, frequencies=[(0.0, 181.8), (1.017322, 180.4)],
                                              underlying_hz=182.5)])),
                    vibration=block((1.0, [note(0.0, 4.0, [(0.0, 0.0), (4.0, 1.0)])])))
    path = tmp_path / "Texture.haps"
    path.write_text(json.dumps(document))
    out = tmp_path / "bumps.png"
    result = run_cli("texture", "import", path, "-o", out, check=True)
    assert "1017.32 mm long" in result.stdout
    said = result.stderr
    assert "182.5 Hz" in said and "frequency modulation" in said and "--effects" in said  # said, not dropped
    ratios = png_ratios(out)
    x = centres_mm(ratios.size, 1017.322)
    # by hand, in mm: 1 to 30.533, down to 0 at 31.671, 0 to 101.841, up to 1 at 102.789, 1 to 132.184, down
    # to 0 at 132.943, then 0
    expected = np.select(
        [x <= 30.533, x <= 31.671, x <= 101.841, x <= 102.789, x <= 132.184, x <= 132.943],
        [1.0, (31.671 - x) / (31.671 - 30.533), 0.0, (x - 101.841) / (102.789 - 101.841), 1.0,
         (132.943 - x) / (132.943 - 132.184)], 0.0)
    np.testing.assert_allclose(ratios, expected, atol=1.5 / 65535)
    # the closest keyframes are 132.943 - 132.184 = 0.759 mm apart: 8 pixels to them, so every edge has pixels on it
    assert ratios.size == math.ceil(1017.322 * 8 / 0.759)
    on_edge = (x > 132.184) & (x < 132.943)
    assert np.count_nonzero(on_edge) >= 7 and np.all((ratios[on_edge] > 0) & (ratios[on_edge] < 1))


def test_the_vibration_block_is_taken_as_effects(tmp_path):
    from ultraglide.render.effects import sample
    from ultraglide.textures.effects import load_effects

    # a swell from 0 to 1 over 1 s at 100 Hz, and a transient 0.6 high at 1.5 s (22 ms: played 20 ms)
    document = haps(vibration=block((1.0, [note(0.0, 1.0, [(0.0, 0.0), (1.0, 1.0)],
                                                 frequencies=[(0.0, 100.0), (1.0, 100.0)])]),
                                    (0.75, [note(1.5, 0.022, gain=0.8)])),
                    texture=block((1.0, [note(0.0, 0.01)])))
    path = tmp_path / "swell.haps"
    path.write_text(json.dumps(document))
    with pytest.warns(UserWarning) as said:
        bindings = load_effects(path)
    assert "texture import" in " ".join(str(w.message) for w in said)

    def total(t):
        return sum(sample(binding.effect, np.asarray(t, float)) for binding in bindings)

    # depth t × (1 - cos 2π·100·t)/2: at 0.505 s the modulation is at its full swing (101 half periods)
    assert total([0.505])[0] == pytest.approx(0.505, abs=2e-3)
    assert total([0.5])[0] == pytest.approx(0.0, abs=2e-3)  # whole periods: no drop
    assert total([1.51])[0] == pytest.approx(0.6) and total([1.525])[0] == pytest.approx(0.0, abs=1e-9)

    texture = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    summary = json.loads(run_cli("export", texture, "--effects", path, "-o", tmp_path / "e.wav", "--duration-s",
                                 "0.5", "--json", check=True).stdout)
    assert summary["effects_started"] >= 1


def test_a_file_without_vibration_says_so_in_one_line(tmp_path):
    texture, path = tmp_path / "g.png", tmp_path / "only_texture.haps"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    path.write_text(json.dumps(haps(texture=block((1.0, [note(0.0, 0.01)])))))
    result = run_cli("texture", "effects", texture, "--set", path, "-o", tmp_path / "out.png", check=True)
    assert "m_vibration block has no notes" in result.stderr


def test_hostile_haps_files_are_refused_in_one_line(tmp_path):
    one = note(0.0, 0.01, [(0.0, 1.0), (0.01, 0.0)])
    many_notes = haps(texture=block((1.0, [note(k * 0.001, 0.001) for k in range(10_001)])))
    many_keyframes = haps(texture=block((1.0, [note(0.0, 1.0, [(k * 1e-5, 0.5) for k in range(9_000)])] * 12)))
    cases = {
        "nan.haps": json.dumps(haps(texture=block((1.0, [one])))).replace('"m_length": 0.01', '"m_length": NaN'),
        "deep.haps": '{"m_texture": ' + "[" * 50_000 + "]" * 50_000 + "}",
        "notes.haps": json.dumps(many_notes),
        "keyframes.haps": json.dumps(many_keyframes),
        "type.haps": json.dumps(haps(texture={"m_melodies": [{"m_notes": "bumps"}]})),
        "order.haps": json.dumps(haps(texture=block((1.0, [note(0.0, 0.01, [(0.005, 1.0), (0.001, 0.0)])])))),
        "value.haps": json.dumps(haps(texture=block((1.0, [note(0.0, 0.01, [(0.0, 7.0)])])))),
        "gain.haps": json.dumps(haps(texture=block((-1.0, [one])))),
        "time_unit.haps": json.dumps({**haps(texture=block((1.0, [one]))), "m_time_unit": 3}),
        "length_unit.haps": json.dumps({**haps(texture=block((1.0, [one]))), "m_length_unit": 2}),
        "empty.haps": json.dumps(haps()),
        "list.haps": "[1, 2, 3]",
        "large.haps": '{"m_texture": {"m_melodies": [' + ",".join(["{}"] * 2_000_000) + "]}}",
    }
    os.mkfifo(tmp_path / "pipe.haps")
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
    for name in [*cases, "pipe.haps"]:
        result = run_cli("texture", "import", tmp_path / name, "-o", tmp_path / "out.png", timeout=60)
        line = assert_one_line_error(result)
        assert name in line, line
        assert not (tmp_path / "out.png").exists()
    # the same files as effects
    texture = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    for name in ("nan.haps", "deep.haps", "type.haps", "keyframes.haps", "time_unit.haps", "pipe.haps"):
        result = run_cli("texture", "effects", texture, "--set", tmp_path / name, "-o", tmp_path / "out.png",
                         timeout=60)
        assert name in assert_one_line_error(result)
        assert not (tmp_path / "out.png").exists()
