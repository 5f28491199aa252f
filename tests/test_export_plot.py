"""``export --plot``: what the recorder keeps of a run (checked against the signals fed to it) and the
figure read back."""

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from PIL import Image
from ultraglide.apps.figures.export_plot import BUCKETS, CANDIDATES, SEGMENT, ZOOMS, PlotRecorder

RATE = 12000.0


def _signals(n):
    t = np.arange(n) / RATE
    return SimpleNamespace(
        time_s=t, x_mm=100 * t, y_mm=np.full(n, 25.0), down=np.ones(n, bool),
        ratio=0.7 + 0.3 * np.cos(2 * np.pi * 100 * t),  # a 1 mm grating at 100 mm/s
        target_um_pp=3 + 2 * np.sin(2 * np.pi * 100 * t), amplitude_um_pp=np.zeros(n),
        drive_um_pp=3 + 2 * np.sin(2 * np.pi * 100 * t), plate_um_pp=np.full(n, 2.5),
        planned_ratio=0.7 + 0.3 * np.cos(2 * np.pi * 100 * t))


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
    drive = 2  # channel order: ratio, target, drive, plate, x, y, planned
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
        assert recorder.window_length == 1200 and recorder._hop_buffer.shape == (7, 600)
    n = int(RATE * 60)
    _feed(long, _signals(n), [4096] * (n // 4096))
    kept = [window for candidates in long.candidates.values() for _, _, window in candidates]
    assert len(kept) <= 3 * CANDIDATES and all(window.shape == (7, 1200) for window in kept)


def _events(n):
    """20 s at rest but for two events: at 4.2 s the target steps up to 4 µm and the drive overshoots to 7 µm
    for 5 ms (pre-compensation's overdrive, the limit being 6); at 13.3 s it steps back down and the plate
    takes 20 ms to follow."""
    t = np.arange(n) / RATE
    target = np.where((t >= 4.2) & (t < 13.3), 4.0, 0.0)
    drive = target + np.where((t >= 4.2) & (t < 4.205), 3.0, 0.0)
    plate = np.where((t >= 13.3) & (t < 13.32), 4.0, target)
    return SimpleNamespace(time_s=t, x_mm=50 * t, y_mm=np.full(n, 25.0), down=np.ones(n, bool),
                           ratio=np.where(target > 0, 0.3, 1.0), target_um_pp=target, amplitude_um_pp=target,
                           drive_um_pp=drive, plate_um_pp=plate, planned_ratio=np.where(target > 0, 0.3, 1.0))


def test_a_zoom_holds_its_event_in_its_middle_not_at_its_edge():
    """Windows overlap by half, so an event lies in two: the zoom is the one it is nearer the middle of. A
    step 8 ms before the end of the first window (as an edge texture's crossing at 80 ms was drawn, with
    nothing of the plate's answer to it) is shown in the next one, near its middle."""
    n = int(RATE * 2)
    t = np.arange(n) / RATE
    step = 1100  # the first window is samples 0-1199, the next 600-1799
    target = np.where(np.arange(n) >= step, 4.0, 1.0)
    signals = SimpleNamespace(time_s=t, x_mm=50 * t, y_mm=np.full(n, 25.0), down=np.ones(n, bool),
                              ratio=np.where(target > 1, 0.3, 0.9), target_um_pp=target, amplitude_um_pp=target,
                              drive_um_pp=target, plate_um_pp=target, planned_ratio=np.where(target > 1, 0.3, 0.9))
    recorder = PlotRecorder(n, RATE)
    _feed(recorder, signals, [500] * (n // 500))
    zooms = recorder.zooms(limit_um_pp=6.0)
    assert recorder.window_length == 1200 and [why for why, _, _ in zooms] == [ZOOMS["change"]]
    first = zooms[0][1]
    assert first + 300 <= step < first + 900, first


def _renderer():
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.renderer import Renderer
    from ultraglide.textures.library import resolve_texture

    return Renderer(resolve_texture("grating-1mm"), load_model("exponential"), load_profile("sim-plate"))


def test_zooms_land_where_something_happens_and_say_why():
    n = int(RATE * 20)
    recorder = PlotRecorder(n, RATE)
    _feed(recorder, _events(n), [1000] * (n // 1000))
    zooms = recorder.zooms(limit_um_pp=6.0)
    spans = [(first / RATE, (first + window.shape[1]) / RATE) for _, first, window in zooms]
    assert len(zooms) == 2  # two events, two windows: no third on a stretch where nothing happens
    assert spans[0][0] < 4.2 < spans[0][1] and spans[1][0] < 13.3 < 13.32 < spans[1][1], spans
    assert zooms[0][0] in (ZOOMS["change"], ZOOMS["overdrive"]) and zooms[1][0] in (ZOOMS["change"], ZOOMS["lag"])
    quiet = PlotRecorder(n, RATE)
    flat = _events(n)
    for name in ("target_um_pp", "drive_um_pp", "plate_um_pp", "amplitude_um_pp"):
        getattr(flat, name)[:] = 1.0
    _feed(quiet, flat, [1000] * (n // 1000))
    assert [(why, first) for why, first, _ in quiet.zooms(6.0)] == [("the start: nothing changes in this run", 0)]


def test_the_figure_draws_the_target_over_the_plate_and_explains_overdrive():
    import matplotlib.pyplot as plt

    n = int(RATE * 20)
    recorder = PlotRecorder(n, RATE)
    _feed(recorder, _events(n), [1000] * (n // 1000))
    figure = recorder.draw(_renderer())
    try:
        amplitude = next(axes for axes in figure.axes if axes.get_ylabel() == "amplitude (µm p-p)")
        target = [line for line in amplitude.lines if line.get_color() == "k"]
        assert target and all(line.get_zorder() > artist.get_zorder()
                              for line in target for artist in amplitude.collections)  # bands under the target
        labels = amplitude.get_legend_handles_labels()[1]
        assert any("overdrive" in label for label in labels), labels
        zooms = [axes for axes in figure.axes if axes.get_title().startswith("zoom")]
        assert len(zooms) == 2
        for zoom in zooms:
            black = [line for line in zoom.lines if line.get_color() == "k"]
            assert black and black[0].get_zorder() > max(line.get_zorder() for line in zoom.lines if line not in black)
            assert zoom.get_ylim() == zooms[0].get_ylim() and 7.0 < zoom.get_ylim()[1] <= 7.0 * 1.2  # one scale
        assert "overdrive" in " ".join(text.get_text() for text in zooms[0].texts)
        assert not zooms[1].texts  # no overdrive there
    finally:
        plt.close(figure)


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_export_plot_files(tmp_path, suffix):
    plot = tmp_path / f"run{suffix}"
    run_cli("export", "grating-1mm", "-o", tmp_path / "run.wav", "--duration-s", "2", "--plot", plot, check=True)
    data = plot.read_bytes()
    if suffix == ".png":
        with Image.open(plot) as image:
            assert image.info["dpi"][0] == pytest.approx(300, abs=0.5)
            assert 1000 <= image.size[0] <= 1050  # one IEEE column, 3.5 inches, at 300 dpi
    elif suffix == ".pdf":
        assert data.startswith(b"%PDF")
    else:
        assert b"<svg" in data[:2000] and b"spectrogram of the drive" in data


def test_the_figure_draws_the_ratio_commanded_where_the_renderer_plans(tmp_path):
    """Under the default model the renderer plans against the finger's lag: the top panel draws the ratio it
    commanded beside the texture's, each point the mean of the envelope record's planned_ratio over its stretch
    (read back from the CSV); under a static model it commands the texture's ratio and draws no second line."""
    import matplotlib.pyplot as plt
    from ultraglide.apps.figures import export_plot

    drawn = {}
    original = export_plot.PlotRecorder.draw

    def keep(self, renderer, width=None):
        figure = original(self, renderer, width)
        top = next(axes for axes in figure.axes if axes.get_ylabel() == "friction ratio")
        drawn[renderer.model.name] = ([(line.get_label(), line.get_xydata()) for line in top.lines], self.bucket)
        return figure

    for model in ("dynamic", "stretched"):
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(export_plot.PlotRecorder, "draw", keep)
            export_plot_in_process(tmp_path, model)
    lines, bucket = drawn["dynamic"]
    commanded = [xy for label, xy in lines if label.startswith("commanded")]
    assert len(commanded) == 1
    table = np.genfromtxt(tmp_path / "dynamic.csv", delimiter=",", names=True)
    planned = table["planned_ratio"]
    means = np.add.reduceat(planned, np.arange(0, len(planned), bucket)) / np.diff(
        np.r_[np.arange(0, len(planned), bucket), len(planned)])
    np.testing.assert_allclose(commanded[0][:, 1], means[:len(commanded[0])], atol=1e-5)
    assert np.ptp(planned - table["target_ratio"]) > 0.2  # it plans: the commanded ratio is not the texture's
    assert not [label for label, _ in drawn["stretched"][0] if label.startswith("commanded")]
    plt.close("all")


def export_plot_in_process(tmp_path, model):
    from ultraglide.apps.cli.main import main

    code = main(["export", "grating-1mm", "-o", str(tmp_path / f"{model}.wav"), "--duration-s", "0.5", "--model",
                 model, "--plot", str(tmp_path / f"{model}.png"), "--envelope-csv", str(tmp_path / f"{model}.csv")])
    assert code in (0, None)


def test_export_plot_bad_name_leaves_no_file(tmp_path):
    result = run_cli("export", "grating-1mm", "-o", tmp_path / "run.wav", "--duration-s", "1",
                     "--plot", tmp_path / "run.jpg")
    assert ".png, .pdf or .svg" in assert_one_line_error(result)
    assert not list(tmp_path.iterdir())
