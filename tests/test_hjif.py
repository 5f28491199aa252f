"""MPEG-I haptics (.hjif) out of export (the friction ratio over the stroke's time, the drive's envelope) and in as
friction effects; the structure checked against what the reference software's reader requires."""

import json

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli

# what the reference software's .hjif reader (MPEGGroup/HapticReferenceSoftware, IOJson::loadFile and its
# loaders) refuses a file without, and the type each must have; and its semantic checks (avatar 0 reserved, the
# profiles, the levels, the Main profile's largest timescale)
REQUIRED = {
    "file": {"version": str, "profile": str, "level": int, "date": str, "description": str, "timescale": int,
             "perceptions": list, "avatars": list, "syncs": list},
    "perception": {"id": int, "avatar_id": int, "description": str, "perception_modality": str, "channels": list,
                   "effect_library": list},
    "channel": {"id": int, "description": str, "gain": float, "mixing_coefficient": float, "body_part_mask": int,
                "bands": list},
    "band": {"band_type": str, "lower_frequency_limit": int, "upper_frequency_limit": int, "effects": list},
    "effect": {"effect_type": str, "position": int, "keyframes": list},
    "avatar": {"id": int, "lod": int, "type": str},
}
MODALITIES = {"Other", "Pressure", "Acceleration", "Velocity", "Position", "Temperature", "Vibrotactile", "Water",
              "Wind", "Force", "Vibrotactile Texture", "Stiffness", "Friction", "Electrotactile"}


def check(kind: str, value: dict) -> None:
    for key, type_ in REQUIRED[kind].items():
        assert key in value, f"{kind} lacks {key}"
        assert isinstance(value[key], type_ if type_ is not float else (int, float)), f"{kind}'s {key}"


def check_structure(document: dict) -> None:
    check("file", document)
    for avatar in document["avatars"]:
        check("avatar", avatar)
    avatar_ids = {avatar["id"] for avatar in document["avatars"]}
    assert 0 not in avatar_ids  # reserved for an unspecified avatar
    assert len(avatar_ids) == len(document["avatars"]) and document["profile"] in {"Main", "Simple Parametric"}
    assert document["level"] in {1, 2} and 0 < document["timescale"] <= 48_000
    for perception in document["perceptions"]:
        check("perception", perception)
        assert perception["perception_modality"] in MODALITIES and perception["avatar_id"] in avatar_ids | {0}
        for channel in perception["channels"]:
            check("channel", channel)
            for band in channel["bands"]:
                check("band", band)
                assert band["band_type"] in {"Transient", "Curve", "VectorialWave", "WaveletWave"}
                for effect in band["effects"]:
                    check("effect", effect)
                    positions = [k["relative_position"] for k in effect["keyframes"]]
                    assert all(isinstance(p, int) for p in positions) and positions == sorted(positions)
                    assert all(-1 <= k["amplitude_modulation"] <= 1 for k in effect["keyframes"])


@pytest.fixture
def stroke(tmp_path):
    texture = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--size-mm", "60x20", "--wavelength-mm", "4", "-o", texture, check=True)
    hjif, csv = tmp_path / "s.hjif", tmp_path / "s.csv"
    summary = json.loads(run_cli("export", texture, "-o", tmp_path / "s.wav", "--duration-s", "0.4", "--speed-mm-s",
                                 "50", "--hjif", hjif, "--hjif-drive", "--envelope-csv", csv, "--json",
                                 check=True).stdout)
    assert str(hjif) in summary["extra_files"]
    return json.loads(hjif.read_text()), np.loadtxt(csv, delimiter=",", skiprows=1)


def test_export_writes_a_friction_perception_of_the_ratio_over_time(stroke):
    document, envelope = stroke
    check_structure(document)
    friction, drive, spatial = document["perceptions"]  # the grating is spatial: its signal over distance too
    assert friction["perception_modality"] == "Friction" and drive["perception_modality"] == "Vibrotactile"
    assert spatial["perception_modality"] == "Friction" and spatial["unit_exponent"] == -5
    assert "unit_exponent" not in friction  # the time signal states no length unit
    band = friction["channels"][0]["bands"][0]
    assert band["band_type"] == "Curve" and band["curve_type"] == "Linear"
    keyframes = band["effects"][0]["keyframes"]
    t_ms = np.array([k["relative_position"] for k in keyframes]) * 1000.0 / document["timescale"]
    values = np.array([k["amplitude_modulation"] for k in keyframes])
    # the envelope CSV of the same run, read independently: its target ratio where the finger is down, else 1
    t_s, down, ratio = envelope[:, 0], envelope[:, 3] > 0, envelope[:, 4]
    expected = np.interp(t_ms / 1000.0, t_s, np.where(down, ratio, 1.0))
    assert np.max(np.abs(values - expected)) < 2e-3  # the CSV keeps 6 digits, the .hjif a linear resampling
    assert values.min() < 0.7 and values.max() > 0.95  # the grating's swing is there
    sent = envelope[:, 9]
    drive_values = np.array([k["amplitude_modulation"] for k in drive["channels"][0]["bands"][0]["effects"][0]
                             ["keyframes"]])
    assert np.max(np.abs(drive_values - np.interp(t_ms / 1000.0, t_s, sent / sent.max()))) < 2e-3


def test_a_spatial_texture_writes_its_signal_over_distance_with_its_length_unit(tmp_path):
    from ultraglide.textures.formats.hjif import read_hjif, read_spatial_signal

    # a ramp of friction along x: ratio = x / 40 over 40 mm (an Interhaptics texture block, 0 -> 1 over 0.04 m)
    ramp = {"m_version": "5", "m_time_unit": 0, "m_length_unit": 7, "m_texture": {"m_loop": 0, "m_melodies": [
        {"m_mute": 0, "m_gain": 1.0, "m_notes": [{"m_startingPoint": 0.0, "m_length": 0.04, "m_gain": 1.0,
         "m_hapticEffect": {"m_amplitudeModulation": {"m_extrapolationStrategy": 0, "m_keyframes": [
             {"m_time": 0.0, "m_value": 0.0}, {"m_time": 0.04, "m_value": 1.0}]}}}]}]}}
    (tmp_path / "ramp.haps").write_text(json.dumps(ramp))
    texture, hjif = tmp_path / "ramp.png", tmp_path / "ramp.hjif"
    run_cli("texture", "import", tmp_path / "ramp.haps", "-o", texture, check=True)
    # a straight swipe from x = 2 mm at 100 mm/s for 0.3 s: 30 mm, to x = 32 mm
    run_cli("export", texture, "-o", tmp_path / "ramp.wav", "--start", "2,20", "--speed-mm-s", "100",
            "--duration-s", "0.3", "--hjif", hjif, check=True)
    document = json.loads(hjif.read_text())
    check_structure(document)
    friction, spatial = document["perceptions"]
    assert spatial["perception_modality"] == "Friction" and spatial["unit_exponent"] == -5  # 10 µm units
    positions = [k["relative_position"] for k in spatial["channels"][0]["bands"][0]["effects"][0]["keyframes"]]
    assert positions[:3] == [0, 2, 4] and positions[-1] == 3000  # 30 mm in units of 10 µm, one each 20 µm
    distance_mm, ratio = read_spatial_signal(document, str(hjif))  # read back by our reader
    np.testing.assert_allclose(distance_mm[-1], 30.0)
    np.testing.assert_allclose(ratio, (2.0 + distance_mm) / 40.0, atol=1e-4)  # by hand: ratio = x / 40
    timeline = read_hjif(document, str(hjif))  # as effects: the time signal plays; the spatial one is said not to
    assert any("over distance" in note for note in timeline.notes)
    # read as time, its 3000 positions would be 3 s of ticks: the segments end with the stroke's time signal
    end_s = friction["channels"][0]["bands"][0]["effects"][0]["keyframes"][-1]["relative_position"] / 1000
    assert max(segment.start_s + segment.length_s for segment in timeline.segments) <= end_s < 1.0

    # a uniform texture has no spatial signal: the time signal alone
    flat = tmp_path / "flat.png"
    ramp["m_texture"]["m_melodies"][0]["m_notes"][0]["m_hapticEffect"] = {}
    (tmp_path / "ramp.haps").write_text(json.dumps(ramp))
    run_cli("texture", "import", tmp_path / "ramp.haps", "-o", flat, check=True)
    run_cli("export", flat, "-o", tmp_path / "flat.wav", "--duration-s", "0.2", "--hjif", hjif, check=True)
    assert [p["perception_modality"] for p in json.loads(hjif.read_text())["perceptions"]] == ["Friction"]


def test_an_hjif_curve_reads_back_as_the_same_friction_drop(tmp_path):
    from ultraglide.render.effects import sample
    from ultraglide.textures.effects import load_effects
    from ultraglide.textures.formats.hjif import hjif_document

    ratio = np.array([1.0, 0.4, 0.4, 0.9, 1.0, 1.0])  # at 0, 2, 4 ... ms: one sample every 2 ms
    path = tmp_path / "dip.hjif"
    path.write_text(json.dumps(hjif_document(ratio, 500.0, "a dip")))
    bindings = load_effects(path)
    t = np.array([0.0005, 0.001, 0.002, 0.003, 0.0045, 0.0065])
    drop = sum(sample(binding.effect, t) for binding in bindings)
    # linear between the samples, then between the 1 ms keyframes: 1 - ratio at those times, by hand
    assert drop == pytest.approx([0.15, 0.3, 0.6, 0.6, 0.6 - 0.5 * 0.25, 0.1 - 0.1 * 0.25], abs=1e-6)


def test_vectorial_waves_transients_and_what_is_not_rendered(tmp_path):
    from ultraglide.render.effects import sample
    from ultraglide.textures.effects import load_effects

    band = {"band_type": "VectorialWave", "lower_frequency_limit": 0, "upper_frequency_limit": 1000, "effects": [
        {"effect_type": "Basis", "position": 100, "keyframes": [
            {"relative_position": 0, "amplitude_modulation": 0.5, "frequency_modulation": 100},
            {"relative_position": 200, "amplitude_modulation": 0.5, "frequency_modulation": 100}]}]}
    transient = {"band_type": "Transient", "lower_frequency_limit": 0, "upper_frequency_limit": 1000, "effects": [
        {"effect_type": "Basis", "position": 500, "keyframes": [
            {"relative_position": 0, "amplitude_modulation": -0.9, "frequency_modulation": 300}]}]}
    wavelet = {"band_type": "WaveletWave", "lower_frequency_limit": 0, "upper_frequency_limit": 1000, "effects": []}
    channel = {"id": 0, "description": "", "gain": 1.0, "mixing_coefficient": 1.0, "body_part_mask": 0,
               "bands": [band, transient, wavelet]}
    document = {"version": "2023", "profile": "Main", "level": 1, "date": "2026-01-01", "description": "",
                "timescale": 1000, "avatars": [], "syncs": [], "perceptions": [
                    {"id": 0, "avatar_id": 0, "description": "", "perception_modality": "Vibrotactile",
                     "effect_library": [], "channels": [channel]},
                    {"id": 1, "avatar_id": 0, "description": "", "perception_modality": "Temperature",
                     "effect_library": [], "channels": []}]}
    path = tmp_path / "mix.hjif"
    path.write_text(json.dumps(document))
    with pytest.warns(UserWarning) as said:
        bindings = load_effects(path)
    notes = " ".join(str(w.message) for w in said)
    assert "WaveletWave" in notes and "Temperature" in notes
    total = lambda t: sum(sample(b.effect, np.array([t])) for b in bindings)[0]  # noqa: E731
    assert total(0.1 + 0.005) == pytest.approx(0.5, abs=1e-6)  # 100 Hz from 0.1 s: peak at half a period
    assert total(0.1 + 0.010) == pytest.approx(0.0, abs=1e-6)
    assert total(0.502) == pytest.approx(0.9)  # the transient's |amplitude|, 5 ms at 300 Hz (the sharpest)
    assert total(0.506) == pytest.approx(0.0, abs=1e-9)


def test_bad_hjif_files_are_refused_in_one_line(tmp_path):
    texture = tmp_path / "g.png"
    run_cli("texture", "new", "grating", "--size-mm", "20x20", "-o", texture, check=True)
    curve = {"band_type": "Curve", "effects": [{"position": 0, "keyframes": [
        {"relative_position": 5, "amplitude_modulation": 0.1}, {"relative_position": 1, "amplitude_modulation": 0.2}]}]}
    cases = {
        "notalist.hjif": {"perceptions": 3},
        "backwards.hjif": {"perceptions": [{"perception_modality": "Friction", "channels": [{"bands": [curve]}]}]},
        "band.hjif": {"perceptions": [{"perception_modality": "Friction", "channels": [{"bands": [
            {"band_type": "Noise"}]}]}]},
        "loud.hjif": {"perceptions": [{"perception_modality": "Friction", "channels": [{"bands": [
            {"band_type": "Curve", "effects": [{"keyframes": [{"amplitude_modulation": 7}]}]}]}]}]},
        "timescale.hjif": {"timescale": 0, "perceptions": []},
    }
    for name, document in cases.items():
        (tmp_path / name).write_text(json.dumps(document))
        result = run_cli("texture", "effects", texture, "--set", tmp_path / name, "-o", tmp_path / "out.png")
        assert name in assert_one_line_error(result)
        assert not (tmp_path / "out.png").exists()
    refused = run_cli("export", texture, "-o", tmp_path / "s.wav", "--hjif", tmp_path / "s.json")
    assert ".hjif" in assert_one_line_error(refused)
