"""``export --plot``: what the recorder keeps of a run (checked against the signals fed to it) and the
figure read back."""

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from PIL import Image
from ultraglide.apps.figures.export_plot import BUCKETS, SEGMENT, PlotRecorder

RATE = 12000.0


def _signals(n):
    t = np.arange(n) / RATE
    return SimpleNamespace(
        time_s=t, x_mm=100 * t, y_mm=np.full(n, 25.0), down=np.ones(n, bool),
        ratio=0.7 + 0.3 * np.cos(2 * np.pi * 100 * t),  # a 1 mm grating at 100 mm/s
        target_um_pp=3 + 2 * np.sin(2 * np.pi * 100 * t), amplitude_um_pp=np.zeros(n),
        drive_um_pp=3 + 2 * np.sin(2 * np.pi * 100 * t), plate_um_pp=np.full(n, 2.5))


def _feed(recorder, signals, sizes):
    start = 0
    for size in sizes:
        recorder(SimpleNamespace(**{k: v[start:start + size] for k, v in vars(signals).items()}))
        start += size


def test_recorder_overview_windows_and_spectrum_match_the_signals():
    n = int(RATE * 30)  # 30 s
    signals = _signals(n)
    recorder = PlotRecorder(n, RATE)
    sizes = [97, 12000, 5, 33333] * 8
    sizes.append(n - sum(sizes))
    _feed(recorder, signals, sizes)  # odd block sizes: buckets and segments straddle blocks
    times, low, mean, high = recorder.overview()
    assert len(times) == pytest.approx(BUCKETS, abs=1) and recorder.bucket == 180  # 15 ms stretches
    drive = 2  # channel order: ratio, target, drive, plate, x, y
    # each 15 ms stretch holds 1.5 cycles of the 100 Hz drive: its full swing, 1 to 5 µm
    assert low[drive] == pytest.approx(1.0, abs=1e-3) and high[drive] == pytest.approx(5.0, abs=1e-3)
    assert np.all(np.abs(mean[drive] - 3) < 2 / (1.5 * np.pi) + 1e-9)  # a part cycle's mean strays little
    assert mean[4] == pytest.approx(100 * times, abs=1e-6)  # x: the mean of a line is its middle
    # the zoomed windows hold the samples themselves, at full rate
    for k, first in enumerate(recorder.window_starts):
        assert recorder.windows[k, drive] == pytest.approx(signals.drive_um_pp[first:first + recorder.window_length])
    assert recorder.window_length == 1200 and len(recorder.window_starts) == 3
    # the drive's spectrum peaks at 100 Hz in every column
    freqs = np.fft.rfftfreq(SEGMENT, 1 / RATE)
    used = recorder.power_count > 0
    peaks = freqs[np.argmax(recorder.power[used], axis=1)]
    assert np.all(np.abs(peaks - 100) <= freqs[1])


def test_recorder_memory_does_not_grow_with_the_run():
    short, long = PlotRecorder(int(RATE * 10), RATE), PlotRecorder(int(RATE * 3600), RATE)
    for recorder in (short, long):
        assert recorder.low.shape[1] <= BUCKETS and recorder.power.shape[0] <= 602
        assert recorder.windows.shape == (3, 6, 1200)


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_export_plot_files(tmp_path, suffix):
    plot = tmp_path / f"run{suffix}"
    run_cli("export", "grating-1mm", "-o", tmp_path / "run.wav", "--duration-s", "2", "--plot", plot, check=True)
    data = plot.read_bytes()
    if suffix == ".png":
        with Image.open(plot) as image:
            assert image.info["dpi"][0] == pytest.approx(300, abs=0.5)
            assert image.size == (3300, 3750)  # 11 × 12.5 inches at 300 dpi
    elif suffix == ".pdf":
        assert data.startswith(b"%PDF")
    else:
        assert b"<svg" in data[:2000] and b"spectrogram of the drive" in data


def test_export_plot_bad_name_leaves_no_file(tmp_path):
    result = run_cli("export", "grating-1mm", "-o", tmp_path / "run.wav", "--duration-s", "1",
                     "--plot", tmp_path / "run.jpg")
    assert ".png, .pdf or .svg" in assert_one_line_error(result)
    assert not list(tmp_path.iterdir())
