"""Rig files (devices/rig.py, ``ultraglide rig check``, ``--rig``) and the rule that no real output is driven by a
plate nobody named: the drive chain's arithmetic against hand-computed figures, the smallest limit binding on
what a real PortAudio device plays (ALSA's ``file`` PCM), hostile files, strict JSON."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from test_devices import ASOUNDRC  # the ALSA file-PCM capture, one definition
from ultraglide.devices.rig import DriveChain, RigError, TouchPanel, load_plate, load_rig

EXAMPLE = ROOT / "examples" / "rig.toml"

INLINE = """
name = "bench"
[plate]
resonance_hz = 26400.0
q = 180.0
max_amplitude_um_pp = 5.0
carrier_min_hz = 24000.0
carrier_max_hz = 28000.0
[drive]
interface_full_scale_v = 2.0
amplifier_gain_v_per_v = 20.0
plate_um_pp_per_v = 0.25
"""


def write(tmp_path, text: str, name: str = "rig.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_drive_chain_multiplies_volts_gain_and_motion(tmp_path):
    rig = load_rig(write(tmp_path, INLINE))
    assert rig.full_scale_um_pp == pytest.approx(2.0 * 20.0 * 0.25)  # 10 µm p-p at a sample of 1.0
    assert rig.max_amplitude_um_pp == 5.0 and rig.limit_from == "the plate"
    assert rig.plate.resonance_hz == 26400.0 and rig.plate.q == 180.0
    assert rig.plate.max_drive_um_pp == 5.0  # no overdrive unless the plate grants it
    # the amplifier's own µm/V replaces gain × plate: 1.5 V × 4 µm/V = 6 µm p-p
    direct = INLINE.replace("amplifier_gain_v_per_v = 20.0\nplate_um_pp_per_v = 0.25",
                            "amplifier_um_pp_per_v = 4.0").replace("2.0\n", "1.5\n", 1)
    assert "interface_full_scale_v = 1.5" in direct
    assert load_rig(write(tmp_path, direct, "direct.toml")).full_scale_um_pp == pytest.approx(6.0)
    assert DriveChain(2.0, 20.0, 0.25).words().startswith("2 V full scale × 20 V/V × 0.25 µm p-p/V = 10 µm p-p")


@pytest.mark.parametrize(("extra", "limit", "whose"), [
    ("amplifier_max_v = 12.0\n", 3.0, "the amplifier's rated output"),  # 12 V × 0.25 µm/V = 3 µm p-p
    ("max_amplitude_um_pp = 4.0\n", 4.0, "[drive] max_amplitude_um_pp"),
    ("amplifier_max_v = 100.0\nmax_amplitude_um_pp = 4.5\n", 4.5, "[drive] max_amplitude_um_pp"),
    ("amplifier_max_v = 100.0\n", 5.0, "the plate"),  # 25 µm p-p at the amplifier's rating: the plate's binds
])
def test_the_smallest_limit_binds(tmp_path, extra, limit, whose):
    rig = load_rig(write(tmp_path, INLINE + extra))
    assert rig.max_amplitude_um_pp == limit and rig.limit_from == whose
    assert rig.limits_um_pp["the plate"] == 5.0 and rig.limits_um_pp["full scale"] == 10.0


def test_a_chain_that_cannot_reach_the_plates_limit_limits_it_at_full_scale(tmp_path):
    rig = load_rig(write(tmp_path, INLINE.replace("plate_um_pp_per_v = 0.25", "plate_um_pp_per_v = 0.1")))
    assert rig.full_scale_um_pp == pytest.approx(4.0)  # 2 V × 20 × 0.1
    assert rig.max_amplitude_um_pp == pytest.approx(4.0) and rig.limit_from == "full scale"


def test_a_named_profile_takes_the_chains_full_scale_and_keeps_its_own_limit(tmp_path):
    (tmp_path / "plate.toml").write_text("resonance_hz = 25000.0\nq = 150.0\nfull_scale_um_pp = 5.0\n"
                                         "max_amplitude_um_pp = 4.0\nmax_drive_um_pp = 5.0\n")
    rig = load_rig(write(tmp_path, '[plate]\nprofile = "plate.toml"\n[drive]\ninterface_full_scale_v = 1.0\n'
                                   'amplifier_gain_v_per_v = 30.0\nplate_um_pp_per_v = 0.2\n'))
    assert rig.plate_source == str(tmp_path / "plate.toml")  # read beside the rig, wherever the command runs
    assert rig.full_scale_um_pp == pytest.approx(6.0)  # 1 V × 30 × 0.2: larger than the profile's 5, so it binds
    assert rig.max_amplitude_um_pp == 4.0 and rig.plate.max_drive_um_pp == 5.0
    # a chain that says less than the (measured) profile: the profile's 5 µm p-p binds, and rig check says so
    smaller = load_rig(write(tmp_path, '[plate]\nprofile = "plate.toml"\n[drive]\ninterface_full_scale_v = 1.0\n'
                                       'amplifier_um_pp_per_v = 3.0\n', "smaller.toml"))
    assert smaller.full_scale_um_pp == 5.0 and smaller.drive.full_scale_um_pp == 3.0
    assert smaller.max_amplitude_um_pp == 4.0 and smaller.limit_from == "the plate"  # a sample of 0.8 at most
    assert any("set amplifier_um_pp_per_v = 5 so that they agree" in line for line in smaller.unverified())
    bundled = load_rig(write(tmp_path, '[plate]\nprofile = "sim-plate"\n', "bundled.toml"))
    assert bundled.full_scale_um_pp == 8.0 and bundled.max_amplitude_um_pp == 6.0 and bundled.drive is None
    assert load_plate(f"rig:{tmp_path / 'bundled.toml'}") == bundled.plate


def test_the_example_rig_is_the_labs(tmp_path):
    rig = load_rig(EXAMPLE)
    assert rig.plate.resonance_hz == 26400.0 and rig.max_amplitude_um_pp == 5.0
    assert rig.full_scale_um_pp == pytest.approx(10.0)
    assert rig.device.startswith("audio:") and "rate=192000" in rig.device
    assert rig.touch.pressure_full_scale_n == 4.0 and rig.display_width_mm == 221.0


@pytest.mark.parametrize(("text", "words"), [
    ("[plate\n", "not a valid TOML file"),
    ("colour = 'blue'\n" + INLINE, "unknown tables or keys colour"),
    (INLINE + "gain = 3\n", "unknown keys in [drive]: gain"),
    ("plate = 3\n", "plate must be a table"),
    ("[drive]\ninterface_full_scale_v = 1.0\namplifier_um_pp_per_v = 1.0\n", "no [plate]"),
    (INLINE.replace("2.0\n", "-2.0\n", 1), "interface_full_scale_v = -2.0 is outside"),
    (INLINE.replace("2.0\n", "nan\n", 1), "interface_full_scale_v = nan is outside"),
    (INLINE.replace("2.0\n", "inf\n", 1), "interface_full_scale_v = inf is outside"),
    (INLINE.replace("2.0\n", "'2 V'\n", 1), "must be a number of V peak"),
    (INLINE.replace("2.0\n", "true\n", 1), "must be a number"),
    (INLINE.replace("2.0\n", "1" + "0" * 400 + "\n", 1), "is outside"),
    (INLINE.replace("plate_um_pp_per_v = 0.25\n", ""), "plate_um_pp_per_v (or amplifier_um_pp_per_v alone)"),
    (INLINE + "amplifier_um_pp_per_v = 4.0\n", "give one way or the other"),
    (INLINE.replace("q = 180.0\n", ""), "lacks q"),
    (INLINE.replace("q = 180.0\n", "q = 180.0\nfull_scale_um_pp = 9.0\n"), "leave it to [drive]"),
    (INLINE.split("[drive]")[0], "nothing says the plate's full scale"),
    (INLINE.replace("resonance_hz = 26400.0", "resonance_hz = 15000.0"), "audible"),
    (INLINE.replace("resonance_hz = 26400.0", "resonance_hz = 26400.0\nprofile = 'sim-plate'"),
     "name a profile or give its fields, not both"),
    ('[plate]\nprofile = "no-such.toml"\n', "no plate profile file"),
    ('[plate]\nprofile = "/dev/zero"\n', "character device"),
    (INLINE + "[output]\ndevice = 'bluetooth:x'\n", "is not a device"),
    (INLINE + "[output]\ndevice = 'audio?rate=48000'\n", "needs a sample rate of at least 66,000 Hz"),
    (INLINE + "[output]\ndevice = 3\n", "must be a line of text"),
    (INLINE + "[touch]\nrotation_deg = 45\n", "must be 0, 90, 180 or 270"),
    (INLINE + "[touch]\nrotation_deg = true\n", "must be 0, 90, 180 or 270"),
    (INLINE + "[touch]\ndrives = 'middle'\n", 'must be "first", "latest" or "none"'),
    (INLINE + "[touch]\narea_mm = [0, 0, 100]\n", "[left, top, width, height]"),
    (INLINE + "[touch]\narea_mm = [0, 0, 0, 100]\n", "more than 0"),
    (INLINE + "[touch]\narea_mm = [0, 0, 'a', 100]\n", "must be a number"),
    (INLINE + "[touch]\nflip_x = 'yes'\n", "must be true or false"),
    (INLINE + "[touch]\npressure_full_scale_n = 0\n", "is outside 0.01..100 N"),
    (INLINE + "[display]\n", "width_mm is missing"),
    (INLINE + "[display]\nwidth_mm = 1e9\n", "is outside"),
    ('name = "\\u001b[31mred"\n' + INLINE.replace('name = "bench"\n', ""), "must be a line of text"),
    ("a" + ".a" * 5000 + " = 1\n", "which no rig file has"),  # many parts: refused before parsing
])
def test_hostile_rig_files_are_one_line_and_exit_2(tmp_path, text, words):
    path = write(tmp_path, text)
    with pytest.raises(RigError) as raised:
        load_rig(path)
    message = str(raised.value)
    assert "\n" not in message and words in message, message
    for command in (("rig", "check", path), ("play", "grating-1mm", "--rig", path, "--duration-s", "0.2")):
        result = run_cli(*command)
        line = assert_one_line_error(result)
        assert result.returncode == 2 and words in line and result.stdout == "", line


@pytest.mark.parametrize("special", ["/dev/zero", "/dev/null", "."])
def test_a_rig_that_is_not_a_regular_file_is_refused_unread(special):
    result = run_cli("rig", "check", special, timeout=60)
    assert result.returncode == 2 and "not a rig file" in assert_one_line_error(result)


def test_rig_check_says_what_it_resolves_to_in_words_and_strict_json():
    human = run_cli("rig", "check", EXAMPLE, check=True).stdout
    assert "2 V full scale × 20 V/V × 0.25 µm p-p/V = 10 µm p-p" in human
    assert "limit: 5 µm p-p (the plate" in human and "not verified:" in human
    result = run_cli("rig", "check", EXAMPLE, "--json", check=True)
    figures = json.loads(result.stdout, parse_constant=lambda name: pytest.fail(f"{name} is not JSON"))
    assert figures["full_scale_um_pp"] == 10.0 and figures["max_amplitude_um_pp"] == 5.0
    assert figures["plate"]["resonance_hz"] == 26400.0 and figures["limit_from"] == "the plate"
    assert figures["drive"]["um_pp_per_input_v"] == pytest.approx(5.0)
    assert figures["touch"]["area_mm"] == [0.0, 0.0, 221.0, 124.0] and figures["display"] == {"width_mm": 221.0}
    assert figures["unverified"] and all(isinstance(sentence, str) for sentence in figures["unverified"])


REAL_OUTPUTS = [
    ("play", "grating-1mm", "--duration-s", "0.3"), ("demo", "--windowed"), ("latency", "--steps", "3"),
    ("plate", "sweep", "-o", "{d}/p.toml"), ("plate", "check"),
    ("calibrate", "--participant", "P01", "-o", "{d}/c.toml"),
    ("experiment", "threshold", "grating-1mm", "--trials", "3", "--out", "{d}/s"),
]


@pytest.mark.parametrize("command", REAL_OUTPUTS, ids=lambda command: " ".join(command[:2]))
@pytest.mark.parametrize("device", ["audio", "audio:0?rate=96000", "serial:/dev/ttyACM0"])
def test_a_real_output_without_a_plate_named_is_refused_in_one_line(tmp_path, command, device):
    capture = tmp_path / "capture.raw"
    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=capture))  # a real PortAudio output is there
    args = [part.format(d=tmp_path) for part in command]
    result = run_cli(*args, "--device", device, env={"HOME": str(tmp_path)}, timeout=120)
    line = assert_one_line_error(result)
    assert result.returncode == 2 and result.stdout == ""
    assert f"--device {device} drives a real plate" in line and "--rig RIG.toml" in line and "--profile" in line
    assert not capture.exists()  # nothing reached the output
    assert sorted(path.name for path in tmp_path.iterdir()) == [".asoundrc"]


def test_simulated_and_recorded_outputs_keep_the_sim_plate(tmp_path):
    """wav:, null and sim play without a profile named: without pre-compensation's overdrive, the built-in
    sim-plate's 6 µm limit over its 8 µm full scale is the most a recorded sample asks."""
    import soundfile

    run_cli("play", "grating-1mm", "--device", f"wav:{tmp_path / 'x.wav'}", "--duration-s", "0.5",
            "--no-precompensation", check=True)
    samples, _ = soundfile.read(tmp_path / "x.wav")
    assert 0.2 < np.max(np.abs(samples)) <= 6.0 / 8.0 + 1e-4
    for device in ("null", "sim"):
        run_cli("play", "grating-1mm", "--device", device, "--duration-s", "0.2", check=True)


def test_the_rigs_limit_binds_on_a_real_audio_output(tmp_path):
    """The rig's plate, its drive chain and its device through real PortAudio: a sample never asks for more
    than the limit over full scale (5 / 10), and the carrier is the rig's plate's resonance."""
    capture = tmp_path / "capture.raw"
    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=capture))
    rig = write(tmp_path, INLINE + "[output]\ndevice = 'audio?rate=96000&latency=0.02&blocksize=256'\n")
    status = json.loads(run_cli("play", "grating-1mm", "--rig", rig, "--duration-s", "0.6", "--json",
                                env={"HOME": str(tmp_path)}, check=True).stdout)
    assert status["rate_hz"] == 96000
    played = np.frombuffer(capture.read_bytes(), dtype="<f4")
    assert np.max(np.abs(played)) <= 5.0 / 10.0 + 1e-6
    assert np.max(np.abs(played)) > 0.2  # it did play
    start = int(np.flatnonzero(np.abs(played) > 0.1 * np.max(np.abs(played)))[0])
    window = played[start:start + 24000]
    spectrum = np.abs(np.fft.rfft(window * np.hanning(len(window))))
    assert np.argmax(spectrum) * 96000 / len(window) == pytest.approx(26400, abs=4)  # 4 Hz bins


def test_rig_and_profile_are_one_or_the_other(tmp_path):
    result = run_cli("play", "grating-1mm", "--rig", EXAMPLE, "--profile", "sim-plate", "--device", "null")
    assert result.returncode == 2 and "not allowed with" in assert_one_line_error(result)


def test_the_rigs_device_is_used_unless_device_overrides_it(tmp_path):
    rig = write(tmp_path, INLINE + f"[output]\ndevice = 'wav:{tmp_path / 'rig.wav'}'\n")
    run_cli("play", "grating-1mm", "--rig", rig, "--duration-s", "0.2", check=True)
    assert (tmp_path / "rig.wav").is_file()
    run_cli("play", "grating-1mm", "--rig", rig, "--device", f"wav:{tmp_path / 'other.wav'}", "--duration-s", "0.2",
            check=True)
    assert (tmp_path / "other.wav").is_file()


def test_touch_panel_mapping_turns_flips_and_places():
    area = (10.0, 20.0, 200.0, 100.0)
    assert TouchPanel(area).to_mm(0.0, 0.0) == (10.0, 20.0)
    assert TouchPanel(area).to_mm(1.0, 1.0) == (210.0, 120.0)
    # a panel mounted a quarter turn clockwise: its x runs down the display, its y from right to left
    assert TouchPanel(area, rotation_deg=90).to_mm(0.0, 0.0) == (210.0, 20.0)
    assert TouchPanel(area, rotation_deg=90).to_mm(1.0, 0.0) == (210.0, 120.0)
    assert TouchPanel(area, rotation_deg=180).to_mm(0.0, 0.0) == (210.0, 120.0)
    assert TouchPanel(area, rotation_deg=270).to_mm(0.0, 0.0) == (10.0, 120.0)
    assert TouchPanel(area, rotation_deg=270).to_mm(1.0, 0.0) == (10.0, 20.0)
    assert TouchPanel(area, flip_x=True).to_mm(0.25, 0.5) == (160.0, 70.0)
    assert TouchPanel(area, flip_y=True).to_mm(0.25, 0.25) == (60.0, 95.0)
    # four quarter turns are none: the mapping is a rotation of the unit square
    for u, v in [(0.1, 0.7), (0.9, 0.3)]:
        x0, y0 = TouchPanel(area, rotation_deg=180).to_mm(u, v)
        x1, y1 = TouchPanel(area, rotation_deg=90).to_mm(*[(c - o) / s for c, o, s in
                                                          zip(TouchPanel(area, rotation_deg=90).to_mm(u, v),
                                                              area[:2], area[2:], strict=True)])
        assert (x0, y0) == pytest.approx((x1, y1))
    assert TouchPanel(None).to_mm(0.5, 0.5, full_area_mm=(300.0, 200.0)) == (150.0, 100.0)
    assert TouchPanel(pressure_full_scale_n=4.0).force_n(0.25) == 1.0
    assert TouchPanel(pressure_full_scale_n=4.0).force_n(1.5) == 4.0
    assert TouchPanel().force_n(0.5) is None
    assert math.isclose(TouchPanel(pressure_full_scale_n=2.5).force_n(0.5), 1.25)


def test_an_experiment_records_the_rigs_plate_and_resumes_with_it(tmp_path):
    """The rig's plate reaches a session's log (its resonance and limit), and a resumed session loads it again; the
    rig's display width is for a participant's window, not refused for a simulated observer."""
    args = ("experiment", "threshold", "grating-1mm", "--observer", "sim:threshold=0.3,slope=3", "--out",
            tmp_path / "s", "--rig", EXAMPLE, "--device", "null", "--no-figures")
    run_cli(*args, "--trials", "3", check=True)
    session = json.loads((tmp_path / "s" / "session.json").read_text())
    assert session["profile"] == {"name": f"rig:{EXAMPLE}", "resonance_hz": 26400.0, "q": 180.0,
                                  "max_amplitude_um_pp": 5.0}
    run_cli("experiment", "threshold", "--resume", tmp_path / "s", "--trials", "5", "--no-figures", check=True)
    assert len((tmp_path / "s" / "trials.csv").read_text().splitlines()) == 1 + 5
