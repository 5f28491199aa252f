"""The picture ``ultraglide export --plot`` draws, readable for a run of any length.

A :class:`PlotRecorder` watches the renderer's control blocks and keeps, in memory that does not
grow with the run: an overview (the minimum, maximum and mean of each signal over about 2000
stretches of time, drawn as a band with its mean, so that no peak is lost however long the run),
three zoomed windows at full control rate (near the start, the middle and the end), and a
spectrogram of the drive (Hann-windowed segments whose power is averaged over about 600 columns).
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from ultraglide.apps.cli.errors import UsageError  # noqa: E402
from ultraglide.apps.cli.files import atomic_path  # noqa: E402

CHANNELS = ("ratio", "target_um_pp", "drive_um_pp", "plate_um_pp", "x_mm", "y_mm")
BUCKETS = 2000
WINDOWS = (0.1, 0.5, 0.9)  # where the zoomed windows are centred, as fractions of the run
WINDOW_S = 0.1
SEGMENT = 1024  # spectrogram segment, control samples (85 ms at 12 kHz)
COLUMNS = 600
SPECTRUM_TOP_HZ = 1000.0
FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}


def _checked(path) -> Path:
    if path is None or Path(path).suffix.lower() not in FORMATS:
        raise UsageError(f"the plot must end in .png, .pdf or .svg, got {path}")
    return Path(path)


class PlotRecorder:
    """A renderer observer that keeps what the plot needs; see the module docstring."""

    def __init__(self, total_samples: int, control_rate_hz: float, path: Path | None = None):
        self.path = None if path is None else _checked(path)  # refuse a bad name before a long run, not after
        self.rate = float(control_rate_hz)
        self.total = max(1, int(total_samples))
        self.bucket = max(1, math.ceil(self.total / BUCKETS))
        buckets = math.ceil(self.total / self.bucket)
        self.low = np.full((len(CHANNELS), buckets), np.inf)
        self.high = np.full((len(CHANNELS), buckets), -np.inf)
        self.sum = np.zeros((len(CHANNELS), buckets))
        self.count = np.zeros(buckets)
        window = max(2, min(round(WINDOW_S * self.rate), self.total // 4 or 2))
        starts = [min(max(0, round(f * self.total) - window // 2), max(0, self.total - window)) for f in WINDOWS]
        self.window_starts = sorted(set(starts))
        self.windows = np.full((len(self.window_starts), len(CHANNELS), window), np.nan)
        self.window_length = window
        segments = max(1, self.total // SEGMENT)
        self.per_column = max(1, math.ceil(segments / COLUMNS))
        self.power = np.zeros((math.ceil(segments / self.per_column) + 1, SEGMENT // 2 + 1))
        self.power_count = np.zeros(len(self.power))
        self._taper = np.hanning(SEGMENT)
        self._pending = np.zeros(0)
        self._segments_done = 0
        self._offset = 0

    def __call__(self, block) -> None:
        columns = np.stack([np.asarray(getattr(block, name), dtype=float) for name in CHANNELS])
        n = columns.shape[1]
        if n == 0:
            return
        start = self._offset
        self._overview(columns, start)
        self._zoom(columns, start)
        self._spectrum(columns[CHANNELS.index("drive_um_pp")])
        self._offset += n

    def _overview(self, columns: np.ndarray, start: int) -> None:
        index = np.arange(start, start + columns.shape[1]) // self.bucket
        keep = index < self.low.shape[1]
        if not keep.all():
            columns, index = columns[:, keep], index[keep]
            if not len(index):
                return
        edges = np.flatnonzero(np.diff(index)) + 1
        cuts = np.concatenate([[0], edges])
        ids = index[cuts]
        self.low[:, ids] = np.minimum(self.low[:, ids], np.minimum.reduceat(columns, cuts, axis=1))
        self.high[:, ids] = np.maximum(self.high[:, ids], np.maximum.reduceat(columns, cuts, axis=1))
        self.sum[:, ids] += np.add.reduceat(columns, cuts, axis=1)
        self.count[ids] += np.diff(np.concatenate([cuts, [len(index)]]))

    def _zoom(self, columns: np.ndarray, start: int) -> None:
        stop = start + columns.shape[1]
        for k, first in enumerate(self.window_starts):
            a, b = max(start, first), min(stop, first + self.window_length)
            if a < b:
                self.windows[k, :, a - first:b - first] = columns[:, a - start:b - start]

    def _spectrum(self, drive: np.ndarray) -> None:
        samples = np.concatenate([self._pending, drive])
        whole = len(samples) // SEGMENT
        if whole:
            segments = samples[:whole * SEGMENT].reshape(whole, SEGMENT)
            segments = segments - segments.mean(axis=1, keepdims=True)  # the envelope's mean is not a tone
            power = np.abs(np.fft.rfft(segments * self._taper, axis=1)) ** 2
            column = np.minimum((self._segments_done + np.arange(whole)) // self.per_column, len(self.power) - 1)
            np.add.at(self.power, column, power)
            np.add.at(self.power_count, column, 1)
            self._segments_done += whole
        self._pending = samples[whole * SEGMENT:]

    # ---- drawing --------------------------------------------------------------------------------------
    def overview(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Each bucket's mean sample time (s) and each channel's minimum, mean and maximum over it."""
        seen = self.count > 0
        times = (np.arange(len(self.count)) * self.bucket + (self.bucket - 1) / 2) / self.rate  # mean sample time
        mean = self.sum[:, seen] / self.count[seen]
        return times[seen], self.low[:, seen], mean, self.high[:, seen]

    def write(self, renderer, path: Path | None = None, dpi: float = 300.0) -> Path:
        """Draw and save to ``path`` (or the one given at construction): PNG at ``dpi``, PDF or SVG by the
        extension, atomically."""
        path = _checked(path or self.path)
        fmt = FORMATS[path.suffix.lower()]
        figure = self.draw(renderer)
        try:
            with atomic_path(path) as temporary:
                figure.savefig(temporary, dpi=dpi, format=fmt)
        finally:
            plt.close(figure)
        return path

    def draw(self, renderer):
        times, low, mean, high = self.overview()
        figure = plt.figure(figsize=(11, 12.5))
        grid = figure.add_gridspec(5, 3, height_ratios=[1, 1.2, 0.8, 1.2, 1.4], hspace=0.6, wspace=0.3, top=0.94,
                                   bottom=0.05, left=0.08, right=0.92)
        ratio, target, drive, plate, x, y = range(len(CHANNELS))
        limit = renderer.limit_um_pp
        duration_s = self.total / self.rate

        def band(axes, channel, label, colour):
            axes.fill_between(times, low[channel], high[channel], color=colour, alpha=0.3, lw=0)
            axes.plot(times, mean[channel], color=colour, lw=0.8, label=label)

        top = figure.add_subplot(grid[0, :])
        band(top, ratio, "target friction ratio", "C0")
        top.set(ylabel="friction ratio", ylim=(0, 1.05), xlim=(0, duration_s))
        top.set_title(f"{renderer.texture.name}, {renderer.model.describe()}\noverview of {duration_s:.3g} s: "
                      f"shaded, the range within each {self.bucket / self.rate * 1000:.3g} ms; line, its mean",
                      fontsize=9, loc="left")
        amplitude = figure.add_subplot(grid[1, :], sharex=top)
        for channel, label, colour in ((target, "model target", "C1"), (drive, "drive (pre-compensated)", "C2"),
                                       (plate, "plate (modelled)", "C3")):
            band(amplitude, channel, label, colour)
        amplitude.axhline(limit, color="r", ls="--", lw=0.8, label="plate limit")
        amplitude.set(ylabel="amplitude (µm p-p)")
        amplitude.legend(fontsize=7, loc="upper right", ncol=4)
        position = figure.add_subplot(grid[2, :], sharex=top)
        band(position, x, "x", "C0")
        band(position, y, "y", "C4")
        position.set(ylabel="position (mm)", xlabel="time (s)")
        position.legend(fontsize=7, loc="upper right")
        for k, first in enumerate(self.window_starts):
            start_s, stop_s = first / self.rate, (first + self.window_length) / self.rate
            for axes in (top, amplitude, position):
                axes.axvspan(start_s, stop_s, color="k", alpha=0.12, lw=0)
            zoom = figure.add_subplot(grid[3, k])
            t = np.arange(self.window_length) / self.rate * 1000  # ms from the window's start
            for channel, colour in ((target, "C1"), (drive, "C2"), (plate, "C3")):
                zoom.plot(t, self.windows[k, channel], color=colour, lw=0.8)
            zoom.axhline(limit, color="r", ls="--", lw=0.8)
            zoom.set_title(f"zoom {k + 1}: {start_s:.3f}–{stop_s:.3f} s (shaded above)", fontsize=8)
            zoom.set_xlabel(f"time from {start_s:.3f} s (ms)", fontsize=8)
            if k == 0:
                zoom.set_ylabel("amplitude (µm p-p)", fontsize=8)
            twin = zoom.twinx()
            twin.plot(t, self.windows[k, ratio], color="C0", lw=0.6, alpha=0.7)
            twin.set_ylim(0, 1.05)
            if k == len(self.window_starts) - 1:
                twin.set_ylabel("friction ratio (blue)", fontsize=8)
            for axes in (zoom, twin):
                axes.tick_params(labelsize=7)
        spectrum = figure.add_subplot(grid[4, :])
        self._draw_spectrogram(figure, spectrum)
        for axes in (top, amplitude, position):
            axes.grid(alpha=0.3)
            axes.tick_params(labelsize=7)
        return figure

    def _draw_spectrogram(self, figure, axes) -> None:
        used = self.power_count > 0
        axes.set(xlabel="time (s)", ylabel="frequency (Hz)")
        if not used.any():
            axes.text(0.5, 0.5, f"run shorter than one {SEGMENT / self.rate * 1000:.0f} ms segment: no spectrogram",
                      ha="center", va="center", transform=axes.transAxes)
            return
        power = self.power[used] / self.power_count[used, None]
        freqs = np.fft.rfftfreq(SEGMENT, 1 / self.rate)
        shown = freqs <= min(SPECTRUM_TOP_HZ, self.rate / 2)
        column_s = self.per_column * SEGMENT / self.rate
        starts = np.flatnonzero(used) * column_s
        density = power[:, shown] / (self.rate * np.sum(self._taper ** 2))  # µm² per Hz
        level = 10 * np.log10(np.maximum(density, 1e-12))
        top = level.max()
        mesh = axes.pcolormesh(np.append(starts, starts[-1] + column_s), np.append(freqs[shown], freqs[shown][-1]
                               + freqs[1]) - freqs[1] / 2, level.T, cmap="magma", vmin=top - 60, vmax=top,
                               shading="flat")
        axes.set_title(f"spectrogram of the drive: {SEGMENT / self.rate * 1000:.0f} ms Hann segments, "
                       f"{freqs[1]:.1f} Hz resolution, mean removed", fontsize=9, loc="left")
        bar = figure.colorbar(mesh, cax=axes.inset_axes((1.01, 0.0, 0.012, 1.0)))  # keeps the time axis aligned
        bar.set_label("dB re 1 µm²/Hz", fontsize=8)
        bar.ax.tick_params(labelsize=7)
        axes.tick_params(labelsize=7)


def plot_envelope(data: np.ndarray, path: Path, renderer) -> Path:
    """Draw from a table of control samples (columns t, x, y, down, ratio, target, amplitude, drive,
    plate, as ``export --envelope-csv`` writes them; evenly spaced in time, at any rate)."""
    data = np.asarray(data, dtype=float).reshape(-1, 9)
    rate = 1.0 / np.median(np.diff(data[:, 0])) if len(data) > 1 else 12000.0
    recorder = PlotRecorder(len(data), rate, path)
    names = ("time_s", "x_mm", "y_mm", "down", "ratio", "target_um_pp", "amplitude_um_pp", "drive_um_pp",
             "plate_um_pp")
    recorder(SimpleNamespace(**dict(zip(names, data.T, strict=True))))
    return recorder.write(renderer)
