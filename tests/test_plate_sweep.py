"""``ultraglide plate sweep`` against ``ultraglide plate-sim``, each in a process of its own, on a real pty; the
resonance fit."""

import json
import math
import os
import signal
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, may_run_in_real_time, run_cli, start_cli, thread_scheduling
from PIL import Image
from test_plate_sim_cli import Server
from ultraglide.devices.characterisation.resonance import FitError, fit_resonance, resonance_curve
from ultraglide.devices.profiles import load_profile


def test_the_resonance_curve_is_down_3_db_at_half_the_bandwidth_from_the_peak():
    # f0 = 24 kHz, Q = 120: f0/(2Q) = 100 Hz, where 2Q(f - f0)/f0 = 1 and A = A0/sqrt(2)
    assert resonance_curve(24100.0, 2.0, 24000.0, 120.0) == pytest.approx(2.0 / math.sqrt(2.0))
    assert resonance_curve(23900.0, 2.0, 24000.0, 120.0) == pytest.approx(2.0 / math.sqrt(2.0))
    assert resonance_curve(24000.0, 2.0, 24000.0, 120.0) == pytest.approx(2.0)
    assert resonance_curve(24300.0, 2.0, 24000.0, 120.0) == pytest.approx(2.0 / math.sqrt(10.0))  # x = 3


def test_the_fit_recovers_a_noisy_resonance_within_its_stated_uncertainty():
    rng = np.random.default_rng(7)
    carriers = np.linspace(23000.0, 24500.0, 61)
    true = (5.0, 23712.0, 140.0)
    fits = []
    for _ in range(40):
        noisy = resonance_curve(carriers, *true) + rng.normal(0.0, 0.05, carriers.size)
        fits.append(fit_resonance(carriers, noisy))
    f0 = np.array([fit.resonance_hz for fit in fits])
    q = np.array([fit.q for fit in fits])
    sigma_f0 = np.median([fit.resonance_sigma_hz for fit in fits])
    sigma_q = np.median([fit.q_sigma for fit in fits])
    # the stated one-sigma uncertainties match the scatter over repeated noisy sweeps (within a factor 1.6)
    assert 1 / 1.6 < np.std(f0) / sigma_f0 < 1.6 and 1 / 1.6 < np.std(q) / sigma_q < 1.6
    assert abs(f0.mean() - true[1]) < 3 * sigma_f0 and abs(q.mean() - true[2]) < 3 * sigma_q
    assert fits[0].bandwidth_hz == pytest.approx(fits[0].resonance_hz / fits[0].q)


@pytest.mark.parametrize("believed, measured_full_scale, limit, drive", [
    ({}, 8.02, 6.0, 8.0),  # sim-plate: limit 6, drive up to 8, kept
    ({}, 7.5, 6.0, 7.5),  # the plate reaches less than the drive asked: the headroom lowered to its full scale
    ({}, 5.0, 5.0, 5.0),  # less than the limit: both lowered
    ({"max_drive_um_pp": None}, 9.0, 6.0, 6.0),  # no overdrive in the profile: none in the measured one
])
def test_the_measured_profile_keeps_the_limit_and_the_overdrive_headroom(believed, measured_full_scale, limit,
                                                                         drive):
    from ultraglide.devices.characterisation.resonance import ResonanceFit
    from ultraglide.devices.characterisation.sweep import measured_profile

    old = replace(load_profile("sim-plate"), **believed)
    found = measured_profile(old, ResonanceFit(24900.0, 180.0, measured_full_scale, 1.0, 2.0, 0.01, 0.001), "m")
    assert (found.full_scale_um_pp, found.max_amplitude_um_pp, found.max_drive_um_pp) == \
        (measured_full_scale, limit, drive)


def test_the_fit_refuses_what_has_no_peak():
    with pytest.raises(FitError, match="did not move"):
        fit_resonance(np.linspace(20000, 28000, 9), np.zeros(9))
    with pytest.raises(FitError, match="at least 4"):
        fit_resonance([24000.0, 25000.0], [1.0, 2.0])


def _sweep(*args, **kwargs):
    return run_cli("plate", "sweep", *args, **kwargs)


def _stopped(server) -> dict:
    assert server.finish(signal.SIGTERM) == 128 + signal.SIGTERM, server.err  # stopped by a signal, as every command
    return json.loads(next(line for line in server.seen if '"stopped"' in line))


def test_a_sweep_finds_the_simulated_plates_resonance_q_and_gain_and_writes_its_profile(tmp_path):
    # the host's profile is wrong on purpose: resonance 25 kHz, Q 200, full scale 16 µm p-p, limit 5 µm p-p;
    # the plate (plate-sim's sim-plate profile) really has 23.7 kHz, Q 150 and 8 µm p-p at full scale
    believed = tmp_path / "believed.toml"
    believed.write_text('resonance_hz = 25000.0\nq = 200.0\nfull_scale_um_pp = 16.0\nmax_amplitude_um_pp = 5.0\n'
                        'max_drive_um_pp = 7.0\n')
    link = tmp_path / "plate"
    server = Server("--link", link, "--resonance-hz", 23700, "--q", 150, "--json")
    try:
        server.wait_line(lambda line: '"serving"' in line)
        result = _sweep("--device", f"serial:{link}", "--profile", believed, "-o", tmp_path / "measured.toml",
                        "--plot", tmp_path / "response.png", "--json")
        assert result.returncode == 0, result.stdout + result.stderr
        found = json.loads(result.stdout)
        stopped = _stopped(server)
    finally:
        server.kill()
    assert abs(found["resonance_hz"] - 23700.0) <= 20.0, found
    assert abs(found["q"] - 150.0) <= 15.0, found
    assert 0 <= found["resonance_sigma_hz"] < 20 and 0 <= found["q_sigma"] < 15
    profile = load_profile(str(tmp_path / "measured.toml"))
    assert profile.resonance_hz == pytest.approx(found["resonance_hz"], abs=0.01)
    assert profile.q == pytest.approx(found["q"], abs=0.01)
    assert profile.full_scale_um_pp == pytest.approx(8.0, rel=0.02)  # from the measured gain, not the 16 believed
    assert profile.max_amplitude_um_pp == 5.0  # the user's limit, kept
    assert profile.max_drive_um_pp == found["max_drive_um_pp"] == 7.0  # and the overdrive headroom
    assert found["stream_threads"] == ("SCHED_FIFO 1" if may_run_in_real_time() else
                                       "normal (no permission to raise it)")
    # safe throughout: the plate never moved more than the sweep's low drive (15 % of 5 µm p-p at the
    # believed gain, so half that on this plate), and the sweep ended by resting it
    assert stopped["peak_um_pp"] <= 0.15 * 5.0 + 1e-6
    assert stopped["faults"]["trip"] == 0 and stopped["faults"]["over-limit"] == 0
    events = [json.loads(line) for line in server.seen if line.startswith("{")]
    carriers = [event["carrier_hz"] for event in events if event["event"] == "carrier"]
    assert len(carriers) >= 41 and min(carriers) == 20000.0 and max(carriers) == 28000.0
    disabled = [event for event in events if event["event"] == "disabled"]
    assert disabled and disabled[-1]["reason"] == "host"
    with Image.open(tmp_path / "response.png") as image:
        # print quality: 300 dpi at one IEEE column (3.5 in, the default --figure-width), within the 2 % a tight
        # bounding box trims
        assert image.width >= 0.98 * 3.5 * 300 and round(image.info["dpi"][0]) >= 300


def test_a_sweep_rests_the_plate_and_writes_nothing_when_terminated(tmp_path):
    link = tmp_path / "plate"
    server = Server("--link", link, "--json")
    try:
        server.wait_line(lambda line: '"serving"' in line)
        sweep = start_cli("plate", "sweep", "--device", f"serial:{link}", "--profile", "sim-plate",
                          "-o", tmp_path / "p.toml", "--steps", 200,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        server.wait_line(lambda line: '"stream_started"' in line)
        server.wait_line(lambda line: '"carrier"' in line)
        threads = thread_scheduling(sweep.pid)  # the stream's writer and reader at work, from the kernel's account
        sweep.send_signal(signal.SIGTERM)
        out, err = sweep.communicate(timeout=60)
        server.wait_line(lambda line: '"disabled"' in line and '"host"' in line)
        stopped = _stopped(server)
    finally:
        server.kill()
    assert sweep.returncode == 128 + signal.SIGTERM and "Traceback" not in err, err
    assert not list(tmp_path.glob("p*.toml")) and not list(tmp_path.glob(".p.*"))
    assert stopped["faults"]["watchdog"] == 0  # rested by the host, not by the device's watchdog
    # the stream's threads (writer, reader) in real time where this machine allows it; the main thread ordinary
    assert threads[sweep.pid] == (os.SCHED_OTHER, 0)
    others = [scheduling for tid, scheduling in threads.items() if tid != sweep.pid]
    fifo = others.count((os.SCHED_FIFO, 1))
    assert fifo >= 2 if may_run_in_real_time() else fifo == 0, threads


def test_a_resonance_outside_the_sweep_is_one_line_and_no_profile(tmp_path):
    link = tmp_path / "plate"
    server = Server("--link", link, "--resonance-hz", 23700, "--q", 150, "--json")
    try:
        server.wait_line(lambda line: '"serving"' in line)
        result = _sweep("--device", f"serial:{link}", "--profile", "sim-plate",
                        "--from-hz", 24500, "--to-hz", 27000, "--steps", 11,
                        "-o", tmp_path / "p.toml")
        server.wait_line(lambda line: '"disabled"' in line and '"host"' in line)
    finally:
        server.kill()
    line = assert_one_line_error(result)
    assert "outside" in line and "--from-hz" in line
    assert not (tmp_path / "p.toml").exists()


@pytest.mark.parametrize(("args", "words"), [
    (["--device", "audio", "--profile", "sim-plate"], "needs a vibration sensor"),
    (["--device", "wav:x.wav"], "measures nothing"),
    (["--from-hz", "26000", "--to-hz", "24000"], "must be below"),
    (["--from-hz", "19000"], "outside plate"),
    (["--steps", "2"], "from 5 to 2000, got 2"),
    (["--plot", "x.jpg"], "PNG, PDF or SVG"),
])
def test_bad_sweep_options_are_one_line(tmp_path, args, words):
    output = tmp_path / "p.toml"
    line = assert_one_line_error(run_cli("plate", "sweep", "-o", output, *args, cwd=tmp_path))
    assert words in line
    assert not output.exists()


AUDIO_ASOUNDRC = """pcm.out {{
    type plug
    slave {{ pcm "outfile"; format FLOAT_LE; channels 1 }}
}}
pcm.outfile {{
    type file
    slave.pcm "null"
    file "{played}"
    format "raw"
}}
pcm.sensor {{
    type plug
    slave {{ pcm "sensorfile"; format FLOAT_LE; channels 1; rate 96000 }}
}}
pcm.sensorfile {{
    type file
    slave.pcm "null"
    file "/dev/null"
    infile "{sensor}"
    format "raw"
}}
"""


def test_an_audio_sweep_reads_the_resonance_from_a_sensor_on_an_alsa_input(tmp_path):
    """Real PortAudio through ALSA: the output goes to a ``file`` PCM, the sensor input is an ALSA ``file``
    PCM whose ``infile`` holds what a sensor on a 23.7 kHz, Q 150 plate would give for the sweep's schedule
    (each carrier 0.1 s, amplitude from the resonance curve, with noise)."""
    rate, dwell = 96000, 9600
    carriers = np.linspace(23200.0, 24200.0, 51)
    rng = np.random.default_rng(5)
    frequency = np.repeat(carriers, dwell)
    amplitude = np.repeat(resonance_curve(carriers, 0.4, 23700.0, 150.0), dwell)
    sensor = amplitude * np.sin(2 * np.pi * np.cumsum(frequency) / rate) + rng.normal(0.0, 0.01, frequency.size)
    sensor_file, played_file = tmp_path / "sensor.raw", tmp_path / "played.raw"
    np.concatenate((sensor, np.zeros(rate))).astype("<f4").tofile(sensor_file)
    (tmp_path / ".asoundrc").write_text(AUDIO_ASOUNDRC.format(played=played_file, sensor=sensor_file))
    result = run_cli("plate", "sweep", "--device", "audio:out", "--profile", "sim-plate",
                     "--sensor", "audio:sensor", "--from-hz", 23200,
                     "--to-hz", 24200, "--steps", 51, "--sensor-um-per-unit", 2.0, "-o", tmp_path / "p.toml", "--json",
                     env={"HOME": str(tmp_path)})
    assert result.returncode == 0, result.stdout + result.stderr
    found = json.loads(result.stdout)
    assert abs(found["resonance_hz"] - 23700.0) <= 20.0 and abs(found["q"] - 150.0) <= 15.0, found
    # full scale: the sensor's 0.4 peak × 2 µm p-p per unit at the sweep's drive (15 % of 6 of 8 µm p-p)
    assert found["full_scale_um_pp"] == pytest.approx(0.4 * 2.0 / (0.15 * 6.0 / 8.0), rel=0.03)
    assert load_profile(str(tmp_path / "p.toml")).max_amplitude_um_pp == 6.0
    # what reached the output: the carrier steps, at the low sweep level, ending at rest
    played = np.fromfile(played_file, dtype="<f4")
    assert np.max(np.abs(played)) <= 0.15 * 6.0 / 8.0 + 1e-6 and np.max(np.abs(played[-96:])) < 0.01
    start = int(np.flatnonzero(np.abs(played) > 0)[0])
    first = played[start + 2000:start + dwell]
    spectrum = np.abs(np.fft.rfft(first * np.hanning(first.size)))
    assert np.argmax(spectrum) * rate / first.size == pytest.approx(carriers[0], abs=rate / first.size)


# A fresh interpreter (not the tests' command server, which has scipy imported already) running the command,
# with an audit hook noting every module imported while a plate driver's writer thread exists in the process.
IMPORTS_WHILE_STREAMING = """
import json, sys, threading
late = []
def hook(event, args):
    if event == "import" and any(thread.name == "serial-plate" for thread in threading.enumerate()):
        late.append(args[0])
sys.addaudithook(hook)
from ultraglide.apps.cli.main import main
status = main(sys.argv[1:])
print(json.dumps({"status": status, "imported": late}), file=sys.stderr)
"""


def test_a_sweep_imports_nothing_while_it_streams(tmp_path):
    # an import holds the interpreter's lock for tens of ms at a time: the writer thread, which must send
    # within the plate's 100 ms watchdog, would wait on it (the fit's scipy.optimize was imported mid-sweep)
    result = subprocess.run([sys.executable, "-c", IMPORTS_WHILE_STREAMING, "plate", "sweep", "--device", "sim",
                             "-o", tmp_path / "p.toml", "--json"], capture_output=True, text=True, cwd=ROOT,
                            timeout=300)
    said = json.loads(result.stderr.strip().splitlines()[-1])
    assert said == {"status": 0, "imported": []}
    assert json.loads(result.stdout)["points"] >= 41
