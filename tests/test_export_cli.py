"""``ultraglide export`` end to end: files read back by soundfile and sox, and bad input."""

import subprocess

import numpy as np
import pytest
import soundfile
from conftest import assert_one_line_error, run_cli
from PIL import Image


def test_export_float32_wav_read_back_by_soundfile_and_sox(tmp_path):
    out = tmp_path / "swipe.wav"
    envelope = tmp_path / "env.csv"
    plot = tmp_path / "env.png"
    result = run_cli("export", "grating-1mm", "-o", out, "--speed-mm-s", "100", "--duration-s", "1.5",
                     "--envelope-csv", envelope, "--plot", plot, check=True)
    assert "wrote" in result.stdout
    samples, rate = soundfile.read(out, dtype="float32")
    assert rate == 96000
    assert len(samples) / rate == pytest.approx(1.5, abs=0.1)
    assert np.max(np.abs(samples)) <= 1.0
    spectrum = np.abs(np.fft.rfft(samples[rate // 4: rate // 4 + rate] * np.hanning(rate)))
    freqs = np.fft.rfftfreq(rate, 1 / rate)
    assert freqs[np.argmax(spectrum)] == pytest.approx(25000, abs=2)
    sidebands = spectrum[np.argmin(abs(freqs - 24900))], spectrum[np.argmin(abs(freqs - 25100))]
    assert min(sidebands) > 0.1 * spectrum.max()  # 1 mm at 100 mm/s: 100 Hz of modulation
    sox = subprocess.run(["sox", str(out), "-n", "stat"], capture_output=True, text=True)
    assert sox.returncode == 0
    stats = dict(line.split(":", 1) for line in sox.stderr.splitlines() if ":" in line)
    assert float(stats["Length (seconds)"]) == pytest.approx(len(samples) / rate, abs=1e-3)
    assert float(stats["Maximum amplitude"]) == pytest.approx(np.max(samples), abs=1e-4)
    table = np.genfromtxt(envelope, delimiter=",", names=True)
    assert {"t_s", "target_ratio", "drive_um_pp", "x_mm"} <= set(table.dtype.names)
    assert len(table) == pytest.approx(len(samples) / 8, abs=10)
    assert np.all(table["amplitude_um_pp"] <= 6.0)
    with Image.open(plot) as image:
        assert image.width >= 800


@pytest.mark.parametrize("fmt, subtype", [("int16", "PCM_16"), ("int24", "PCM_24")])
def test_integer_formats(tmp_path, fmt, subtype):
    out = tmp_path / "swipe.wav"
    run_cli("export", "checkerboard-5mm", "-o", out, "--format", fmt, "--duration-s", "0.5",
            "--path", "circle", "--rate", "192000", check=True)
    info = soundfile.info(out)
    assert info.subtype == subtype and info.samplerate == 192000


def test_trajectory_csv_at_an_uneven_rate(tmp_path):
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(1 / 240, 1 / 60, 200))  # 60–240 Hz, jittery
    log = tmp_path / "touch.csv"
    rows = [f"{ti:.6f},{10 + 100 * (ti - t[0]):.4f},25.0,0.4" for ti in t]
    log.write_text("# recorded by a touch logger\nt_s,x_mm,y_mm,force_n\n" + "\n".join(rows) + "\n")
    out = tmp_path / "log.wav"
    run_cli("export", "grating-2mm", "--trajectory", log, "-o", out, check=True)
    samples, rate = soundfile.read(out)
    assert len(samples) / rate == pytest.approx(t[-1] - t[0], abs=0.1)
    segment = samples[rate // 4: rate // 4 + rate // 2]
    spectrum = np.abs(np.fft.rfft(segment * np.hanning(len(segment))))
    freqs = np.fft.rfftfreq(len(segment), 1 / rate)
    upper = spectrum[np.argmin(abs(freqs - 25050))]  # 2 mm at 100 mm/s: 50 Hz
    assert upper > 0.1 * spectrum.max()


@pytest.mark.parametrize("content, fragment", [
    ("t_s,x_mm,y_mm\n0,1,1\n0.1,abc,1\n", "x_mm is not a number"),
    ("t_s,x_mm,y_mm\n0,1,1\n0.1,2,1\n0.05,3,1\n", "time goes backwards"),
    ("t_s,x_mm,y_mm\n0,1,1\n0.1,nan,1\n", "finite"),
    ("t_s,x_mm\n0,1\n0.1,2\n", "missing column y_mm"),
    ("t_s,x_mm,y_mm\n0,1\n", "expected 3 values"),
])
def test_bad_trajectories_are_one_line_and_leave_no_file(tmp_path, content, fragment):
    log = tmp_path / "bad.csv"
    log.write_text(content)
    out = tmp_path / "out.wav"
    assert fragment in assert_one_line_error(run_cli("export", "grating-1mm", "--trajectory", log, "-o", out))
    assert not out.exists() and not list(tmp_path.glob(".out*"))


@pytest.mark.parametrize("args, fragment", [
    (["no-such-texture"], "no texture file or library texture"),
    (["grating-1mm", "--rate", "48000"], "sample rate of at least"),
    (["grating-1mm", "--carrier-hz", "40000", "--rate", "192000"], "outside"),
    (["grating-1mm", "--speed-mm-s", "-5"], "positive"),
    (["grating-1mm", "--model", "nonsense"], "unknown model"),
    (["grating-1mm", "--profile", "nonsense"], "plate profile"),
    (["grating-1mm", "--speed-mm-s", "nan"], "must be a positive number"),
])
def test_bad_export_options(tmp_path, args, fragment):
    out = tmp_path / "out.wav"
    assert fragment in assert_one_line_error(run_cli("export", *args, "-o", out))
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize("fmt, bits", [("int16", 16), ("int24", 24)])
def test_integer_export_samples_match_the_float_export(tmp_path, fmt, bits):
    common = ("checkerboard-5mm", "--duration-s", "0.4", "--speed-mm-s", "150")
    run_cli("export", *common, "-o", tmp_path / "f.wav", check=True)
    run_cli("export", *common, "-o", tmp_path / "i.wav", "--format", fmt, check=True)
    reference, _ = soundfile.read(tmp_path / "f.wav", dtype="float64")
    integer, _ = soundfile.read(tmp_path / "i.wav", dtype="float64")  # libsndfile scales by 2**(bits-1)
    assert len(integer) == len(reference)
    assert np.max(np.abs(reference)) > 0.3  # a real signal, not silence that any scale would match
    step = 2.0 ** -(bits - 1)
    assert np.max(np.abs(integer - reference)) <= step  # rounding only: not half (or double) scale


def _export_envelope(tmp_path, *options):
    csv = tmp_path / "env.csv"
    run_cli("export", "grating-2mm", "-o", tmp_path / "out.wav", "--duration-s", "0.5", "--envelope-csv", csv,
            *options, check=True)
    return np.genfromtxt(csv, delimiter=",", names=True)


@pytest.mark.slow
def test_export_no_precompensation_drives_the_amplitude_itself(tmp_path):
    plain = _export_envelope(tmp_path, "--no-precompensation")
    np.testing.assert_allclose(plain["drive_um_pp"], plain["amplitude_um_pp"], atol=1e-5)
    compensated = _export_envelope(tmp_path)
    # pre-compensated, the drive leads the plate: it differs from the amplitude wherever the texture moves
    assert np.max(np.abs(compensated["drive_um_pp"] - compensated["amplitude_um_pp"])) > 0.1


@pytest.mark.slow
def test_export_swipe_geometry_options(tmp_path):
    down = _export_envelope(tmp_path, "--direction-deg", "90", "--start", "20,5", "--speed-mm-s", "60")
    touching = down["down"] > 0
    t = down["t_s"][touching] - down["t_s"][touching][0]
    np.testing.assert_allclose(down["x_mm"][touching], 20.0, atol=1e-6)  # 90°: straight down the screen
    np.testing.assert_allclose(down["y_mm"][touching], 5.0 + 60.0 * t, atol=0.02)

    circle = _export_envelope(tmp_path, "--path", "circle", "--radius-mm", "7", "--start", "30,25")
    touching = circle["down"] > 0
    radius = np.hypot(circle["x_mm"][touching] - 37.0, circle["y_mm"][touching] - 25.0)  # starts on its left
    np.testing.assert_allclose(radius, 7.0, atol=0.01)

    zigzag = _export_envelope(tmp_path, "--path", "zigzag", "--zigzag-width-mm", "12", "--start", "10,10",
                              "--speed-mm-s", "100")
    touching = zigzag["down"] > 0
    assert zigzag["x_mm"][touching].min() == pytest.approx(10.0, abs=0.01)
    assert zigzag["x_mm"][touching].max() == pytest.approx(22.0, abs=0.01)  # passes of 12 mm
