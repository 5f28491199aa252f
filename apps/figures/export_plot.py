"""The picture ``ultraglide export --plot`` draws, readable for a run of any length.

A :class:`PlotRecorder` watches the renderer's control blocks and keeps, in memory that does not
grow with the run: an overview (the minimum, maximum and mean of each signal over about 2000
stretches of time, drawn as a band with its mean, so that no peak is lost however long the run),
three zoomed windows at full control rate where something happens (:data:`ZOOMS`: where the target
changes most, where the drive goes furthest above the plate's limit, where the plate lags the target
most; 100 ms windows looked at every 50 ms, the best few of each kind kept), and a spectrogram of the
drive (Hann-windowed segments whose power is averaged over about 600 columns).

The target is drawn over the plate and the drive (black), so it is never hidden under them. Where the renderer
plans against the finger's friction dynamics (the default model), the ratio it commanded (orange) is drawn beside
the texture's: the model target is the amplitude for the commanded ratio, not for the texture's. The drive
may rise above the plate's limit: that is pre-compensation's overdrive (up to the profile's
``max_drive_um_pp``), which speeds the plate's slow response while its own amplitude stays within the
limit; the figure says so where it happens.
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

CHANNELS = ("ratio", "target_um_pp", "drive_um_pp", "plate_um_pp", "x_mm", "y_mm", "planned_ratio")
RATIO, TARGET, DRIVE, PLATE, X, Y, PLANNED = range(len(CHANNELS))
BUCKETS = 2000
WINDOW_S = 0.1
ZOOMS = {  # what a zoomed window shows, and how a window scores for it (the highest wins)
    "change": "where the target changes most",
    "overdrive": "where the drive goes furthest above the plate's limit",
    "lag": "where the plate lags the target most",
}
CANDIDATES = 3  # windows kept for each kind, so that three distinct ones can be chosen
NOTHING_UM_PP = 0.05  # a window whose target changes less, and whose plate lags less, shows nothing
TARGET_STYLE = {"color": "k", "lw": 0.8, "zorder": 5}  # over the plate and the drive
SEGMENT = 1024  # spectrogram segment, control samples (85 ms at 12 kHz)
COLUMNS = 600
SPECTRUM_TOP_HZ = 1000.0
FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}


def _checked(path) -> Path:
    if path is None or Path(path).suffix.lower() not in FORMATS:
        raise UsageError(f"the plot must end in .png, .pdf or .svg, got {path}")
    return Path(path)


def _off_centre(kind: str, window: np.ndarray) -> float:
    """How far (samples) the moment that makes ``window`` a zoom of ``kind`` lies from its middle: the
    target's largest step, the drive's peak, the plate's largest lag behind the target."""
    if kind == "change":
        where = int(np.argmax(np.abs(np.diff(window[TARGET])))) + 0.5 if window.shape[1] > 1 else 0.0
    elif kind == "overdrive":
        where = int(np.argmax(window[DRIVE]))
    else:
        where = int(np.argmax(np.abs(window[PLATE] - window[TARGET])))
    return abs(where - (window.shape[1] - 1) / 2)


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
        self.hop = max(1, min(round(WINDOW_S * self.rate), self.total // 4 or 2) // 2)
        self.window_length = 2 * self.hop  # a window is two hops: looked at every hop, half overlapping
        self.candidates: dict[str, list[tuple[float, int, np.ndarray]]] = {kind: [] for kind in ZOOMS}
        self._hop_buffer = np.zeros((len(CHANNELS), self.hop))
        self._hop_fill = 0
        self._last_hop: np.ndarray | None = None
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
        """Collect hops; each window of two hops is scored for every kind of zoom."""
        done = 0
        while done < columns.shape[1]:
            take = min(self.hop - self._hop_fill, columns.shape[1] - done)
            self._hop_buffer[:, self._hop_fill:self._hop_fill + take] = columns[:, done:done + take]
            self._hop_fill += take
            done += take
            if self._hop_fill == self.hop:
                hop_start = start + done - self.hop
                if self._last_hop is not None:
                    self._consider(np.concatenate([self._last_hop, self._hop_buffer], axis=1), hop_start - self.hop)
                self._last_hop = self._hop_buffer.copy()
                self._hop_fill = 0

    def _consider(self, window: np.ndarray, first: int) -> None:
        target, drive, plate = window[TARGET], window[DRIVE], window[PLATE]
        scores = {"change": float(np.ptp(target)), "overdrive": float(drive.max()),
                  "lag": float(np.sqrt(np.mean((plate - target) ** 2)))}
        for kind, score in scores.items():
            kept = self.candidates[kind]
            rival = next((c for c in kept if abs(c[1] - first) < self.window_length), None)  # overlapping
            if rival is not None:
                if math.isclose(score, rival[0], rel_tol=1e-6, abs_tol=1e-12):  # the same event in both: the
                    if _off_centre(kind, window) >= _off_centre(kind, rival[2]):  # window it is nearer the
                        continue  # middle of (at a window's edge, half of what happens is cut off)
                elif score < rival[0]:
                    continue
                kept.remove(rival)
            if len(kept) < CANDIDATES or score > kept[-1][0]:
                kept.append((score, first, window))
                kept.sort(key=lambda c: -c[0])
                del kept[CANDIDATES:]

    def zooms(self, limit_um_pp: float | None = None) -> list[tuple[str, int, np.ndarray]]:
        """Up to three windows that do not overlap, in time order: (why, first sample, channels × samples).
        One of each kind where it can; overdrive only where the drive went above ``limit_um_pp``."""
        chosen: list[tuple[str, int, np.ndarray]] = []

        def free(first):
            return all(abs(first - other) >= self.window_length for _, other, _ in chosen)

        least = {"change": NOTHING_UM_PP, "lag": NOTHING_UM_PP,
                 "overdrive": math.inf if limit_um_pp is None else limit_um_pp + 1e-9}
        for kind in ZOOMS:
            for score, first, window in self.candidates[kind]:
                if score <= least[kind]:
                    break
                if free(first):
                    chosen.append((ZOOMS[kind], first, window))
                    break
        rest = sorted(((score, kind, first, window) for kind in ("change", "lag")
                       for score, first, window in self.candidates[kind]), key=lambda c: -c[0])
        for score, kind, first, window in rest:  # fewer kinds than three: more of what happens most
            if len(chosen) == len(ZOOMS) or score <= least[kind]:
                break
            if free(first):
                chosen.append((ZOOMS[kind], first, window))
        if not chosen:  # nothing happens: the start, to show that
            window = next((c[2] for c in self.candidates["change"] if c[1] == 0), None)
            if window is None and self._last_hop is not None:  # a run shorter than a window
                window = self._last_hop
            if window is not None:
                chosen.append(("the start: nothing changes in this run", 0, window))
        return sorted(chosen, key=lambda zoom: zoom[1])

    @property
    def window_starts(self) -> list[int]:
        return [first for _, first, _ in self.zooms()]

    @property
    def windows(self) -> np.ndarray:
        return np.array([window for _, _, window in self.zooms()])

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

    def write(self, renderer, path: Path | None = None, dpi: float = 300.0, width=None) -> Path:
        """Draw at the print ``width`` ("column", "page") and save to ``path`` (or the one given at
        construction): PNG at ``dpi``, PDF or SVG by the extension, atomically."""
        from ultraglide.apps.figures.style import before_saving, print_layout

        path = _checked(path or self.path)
        fmt = FORMATS[path.suffix.lower()]
        figure = self.draw(renderer, width)
        try:
            options = print_layout(figure, dpi)
            before_saving(fmt)
            with atomic_path(path) as temporary:
                figure.savefig(temporary, dpi=dpi, format=fmt, **options)
        finally:
            plt.close(figure)
        return path

    def draw(self, renderer, width=None):
        """The figure at a print width: one IEEE column (3.5 in, the zooms stacked) or two (7.16 in, the zooms
        side by side), text of 8 pt or more at that size."""
        import textwrap

        from ultraglide.apps.figures.style import PAGE_IN, STYLE, width_of

        width_in = width_of(width)
        page = width_in >= PAGE_IN
        times, low, mean, high = self.overview()
        limit = renderer.limit_um_pp
        max_drive = renderer.profile.max_drive_um_pp
        duration_s = self.total / self.rate
        zooms = self.zooms(limit)
        zoom_rows = 1 if page else max(len(zooms), 1)
        planned = renderer.planner is not None
        heights = [1.0 if page or not planned else 1.7, 1.2, 0.8] + [1.0] * zoom_rows + [1.3]  # room for the words
        with plt.rc_context(STYLE):
            figure = plt.figure(figsize=(width_in, (2.0 if page else 1.55) * sum(heights) + 1.2), layout="constrained")
        figure.print_width_in = width_in
        grid = figure.add_gridspec(len(heights), 3 if page else 1, height_ratios=heights)
        overdriven = bool(len(high[DRIVE])) and float(high[DRIVE].max()) > limit + 1e-9
        drive_label = ("drive (pre-compensated; above the limit: overdrive, which speeds the plate up)" if overdriven
                       else "drive (pre-compensated)")
        characters = int(width_in * 11)

        def band(axes, channel, label, colour, line=True, alpha=0.3):
            axes.fill_between(times, low[channel], high[channel], color=colour, alpha=alpha, lw=0,
                              label=None if line else label)
            if line:
                axes.plot(times, mean[channel], color=colour, lw=0.8, label=label)

        top = figure.add_subplot(grid[0, :])
        band(top, RATIO, "texture (target)", "C0")
        if planned:  # the ratio the inverse was asked for: the target's amplitudes follow it, not the texture
            top.plot(times, mean[PLANNED], color="C1", lw=0.8, label="commanded (planned for the finger's lag)")
        top.set(ylabel="friction ratio", ylim=(0, 1.05), xlim=(0, duration_s))
        words = (f"{renderer.texture.name}, {renderer.model.describe()}. Overview of {duration_s:.3g} s: shaded, the "
                 f"range within each {self.bucket / self.rate * 1000:.3g} ms; line, its mean"
                 + (". Ratios: the texture's (blue), the one commanded (orange: planned for the finger's lag, "
                    "the model target's)" if planned else ""))
        top.set_title(textwrap.fill(words, characters), loc="left")
        amplitude = figure.add_subplot(grid[1, :], sharex=top)
        band(amplitude, DRIVE, drive_label, "C2", line=False, alpha=0.35)  # ranges: a mean of a fast swing
        band(amplitude, PLATE, "plate (modelled)", "C3", line=False, alpha=0.5)  # would only scribble over them
        amplitude.plot(times, high[TARGET], **TARGET_STYLE, label="model target (its range: the lines)")
        amplitude.plot(times, low[TARGET], **TARGET_STYLE)
        amplitude.axhline(limit, color="r", ls="--", lw=0.8, label="plate limit (the plate's own amplitude)")
        if overdriven and max_drive:
            amplitude.axhline(max_drive, color="C2", ls=":", lw=0.8, label="max drive (the profile's overdrive)")
        amplitude.set(ylabel="amplitude (µm p-p)", ylim=(0, 1.3 * max(limit, (max_drive or 0.0) if overdriven else 0.0,
                                                                       float(high[TARGET:PLATE + 1].max(initial=0.0)))))
        handles, labels = amplitude.get_legend_handles_labels()
        column = (characters // 2 if page else characters) - 6  # two columns of labels on a page's width
        amplitude.legend(handles, [textwrap.fill(label, column) for label in labels], loc="upper left",
                         bbox_to_anchor=(0.0, -0.12 if not page else -0.08), ncol=2 if page else 1)
        position = figure.add_subplot(grid[2, :], sharex=top)
        band(position, X, "x", "C0")
        band(position, Y, "y", "C4")
        position.set(ylabel="position (mm)", xlabel="time (s)")
        position.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
        shown = max([limit] + [float(np.nanmax(w[[TARGET, DRIVE, PLATE]])) for _, _, w in zooms]) * 1.15
        for k, (why, first, window) in enumerate(zooms):
            start_s, stop_s = first / self.rate, (first + window.shape[1]) / self.rate
            for axes in (top, amplitude, position):
                axes.axvspan(start_s, stop_s, color="k", alpha=0.12, lw=0)
            zoom = figure.add_subplot(grid[3, k] if page else grid[3 + k, 0])
            t = np.arange(window.shape[1]) / self.rate * 1000  # ms from the window's start
            zoom.plot(t, window[DRIVE], color="C2", lw=0.8)
            zoom.plot(t, window[PLATE], color="C3", lw=0.8)
            zoom.plot(t, window[TARGET], **TARGET_STYLE)
            zoom.axhline(limit, color="r", ls="--", lw=0.8)
            zoom.set_ylim(0, shown)  # one scale for the three, the limit on it
            if float(np.nanmax(window[DRIVE])) > limit + 1e-9:
                note = "drive above the limit: overdrive; the plate itself stays below it"  # wrapped to the panel
                zoom.text(0.02, 0.97, textwrap.fill(note, int(characters / (3 if page else 1)) - 4),
                          transform=zoom.transAxes, fontsize=8, va="top", color="C2")
            zoom.set_title(textwrap.fill(f"zoom {k + 1}, {start_s:.3f}–{stop_s:.3f} s: {why}",
                                         int(characters / (3 if page else 1))))
            zoom.set_xlabel(f"ms from {start_s:.3f} s")
            if k == 0 or not page:
                zoom.set_ylabel("µm p-p")
            twin = zoom.twinx()
            twin.plot(t, window[RATIO], color="C0", lw=0.6, alpha=0.7)
            if planned:
                twin.plot(t, window[PLANNED], color="C1", lw=0.6, alpha=0.8)
            twin.set_ylim(0, 1.05)
            twin.grid(False)
            if k == len(zooms) - 1 or not page:
                twin.set_ylabel("ratio" if planned else "ratio (blue)")
        spectrum = figure.add_subplot(grid[3 + zoom_rows, :])
        self._draw_spectrogram(figure, spectrum, characters)
        return figure

    def _draw_spectrogram(self, figure, axes, characters: int = 80) -> None:
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
        import textwrap

        axes.set_title(textwrap.fill(f"spectrogram of the drive: {SEGMENT / self.rate * 1000:.0f} ms Hann segments, "
                                     f"{freqs[1]:.1f} Hz resolution, mean removed", characters), loc="left")
        bar = figure.colorbar(mesh, ax=axes, pad=0.01, fraction=0.04)
        bar.set_label("dB re 1 µm²/Hz")


def plot_envelope(data: np.ndarray, path: Path, renderer, width=None) -> Path:
    """Draw from a table of control samples (columns t, x, y, down, ratio, target, amplitude, drive,
    plate, as ``export --envelope-csv`` writes them; evenly spaced in time, at any rate)."""
    data = np.asarray(data, dtype=float).reshape(-1, 9)
    rate = 1.0 / np.median(np.diff(data[:, 0])) if len(data) > 1 else 12000.0
    recorder = PlotRecorder(len(data), rate, path)
    names = ("time_s", "x_mm", "y_mm", "down", "ratio", "target_um_pp", "amplitude_um_pp", "drive_um_pp",
             "plate_um_pp")
    recorder(SimpleNamespace(**dict(zip(names, data.T, strict=True))))
    return recorder.write(renderer, width=width)
