"""``ultraglide export``: render a swipe or a touch log to a WAV file, faster than real time.

The WAV holds what a plate would get: the renderer's drive envelope through the same output stage
(limiter, then carrier) as every live device, with the temporal effects saved with the texture (or
given by ``--effects``) mixed into the friction before the model's inverse.

The writing itself is :func:`ultraglide.api.write_wav`, the library's path too: the envelope in order on
this thread, the carrier and the writes in a forked writer process on the other core (threads where
there is no fork), memory flat whatever the length."""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import THREADS
from ultraglide.apps.commands.render_options import add_render_options, model_words

if TYPE_CHECKING:
    import numpy as np
    from ultraglide.render.renderer import ControlBlock
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import atomic_path, refuse_overlaps, render_inputs
from ultraglide.apps.cli.options import add_figure_width_option, output_option, refuse_ignored

PLOT_POINTS = 200_000
ENVELOPE_COLUMNS = ("t_s", "x_mm", "y_mm", "down", "target_ratio", "target_um_pp", "amplitude_um_pp",
                    "drive_um_pp", "plate_um_pp", "sent_um_pp",  # sent: the drive after the limiter
                    "planned_ratio")  # the ratio the model's inverse was asked for (the planner's command, if any)
PLOT_COLUMNS = ENVELOPE_COLUMNS.index("sent_um_pp")  # the plot's columns come first


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide export``: its options."""
    export = commands.add_parser(
        "export", help="render a swipe or a touch log to a WAV file",
        description="Render the modulated carrier a plate would get for a swipe across a texture (or a "
                    "recorded touch log) to a WAV file, faster than real time, in bounded memory.")
    add_render_options(export)
    output_option(export, "-o", "--output", kind="wav", required=True, metavar="OUT.wav")
    export.add_argument("--format", choices=["float32", "int24", "int16"], default="float32")
    output_option(export, "--envelope-csv", metavar="FILE.csv",
                        help="also write target friction, amplitudes and position at the control rate")
    output_option(export, "--plot", metavar="FILE.png", help="also draw friction, amplitude and position")
    output_option(export, "--hjif", metavar="OUT.hjif",
                  help="also write the stroke as an MPEG-I haptics file (ISO/IEC 23090-31): a Friction perception "
                       "whose curve is the friction ratio over time, 1 ms a keyframe (docs/formats.md)")
    export.add_argument("--hjif-drive", action="store_true",
                        help="with --hjif: add a Vibrotactile perception, the drive's amplitude envelope")
    add_figure_width_option(export)
    export.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    export.add_argument("--threads", type=THREADS, metavar="N",
                        help="threads that put the envelope on the carrier, 1 to 256 (default: one per CPU available)")
    export.set_defaults(run=run)


class HjifRecorder:
    """Keeps the friction ratio under the finger (1, the plate at rest, while it is lifted) and the drive the
    output stage sent, at the control rate, for ``--hjif``; and where the finger was, for the texture's spatial
    signal. Observes the renderer's blocks, then the stage's."""

    def __init__(self):
        self.ratio: list[np.ndarray] = []
        self.drive: list[np.ndarray] = []
        self.path: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._block: ControlBlock | None = None

    def __call__(self, block: ControlBlock) -> None:
        import numpy as np

        self._block = block
        self.ratio.append(np.where(block.down, block.ratio, 1.0).astype(np.float32))
        self.path.append((block.x_mm.copy(), block.y_mm.copy(), np.asarray(block.down, dtype=bool).copy()))

    def sent(self, drive_um_pp: np.ndarray) -> None:
        import numpy as np

        self.drive.append(np.asarray(drive_um_pp, dtype=np.float32).copy())

    def document(self, rate_hz: float, description: str, with_drive: bool, texture=None) -> dict:
        import numpy as np
        from ultraglide.textures.formats.hjif import hjif_document, spatial_signal

        ratio = np.clip(np.concatenate(self.ratio), 0.0, 1.0) if self.ratio else np.ones(1)
        drive = np.concatenate(self.drive) if with_drive and self.drive else None
        spatial = None
        if texture is not None and self.path:
            spatial = spatial_signal(texture, *(np.concatenate(parts) for parts in zip(*self.path, strict=True)))
        return hjif_document(ratio, rate_hz, description, drive, spatial=spatial)


class EnvelopeLog:
    """Streams the control-rate envelope to CSV and keeps a bounded, decimated copy for a plot.
    Observes the renderer's blocks (``__call__``) and then the output stage's limited drive (``sent``)."""

    def __init__(self, stream, total_samples: int, keep_plot: bool, path: Path | None = None):
        self.stream = stream
        self.path = path  # named in write errors (the stream writes a hidden temporary file)
        if stream:
            stream.write(",".join(ENVELOPE_COLUMNS) + "\n")
        self.every = max(1, math.ceil(total_samples / PLOT_POINTS))
        self.keep_plot = keep_plot
        self.kept: list[np.ndarray] = []
        self._offset = 0
        self._block: ControlBlock | None = None

    def __call__(self, block: ControlBlock) -> None:
        self._block = block

    def sent(self, drive_um_pp: np.ndarray) -> None:
        import numpy as np

        block = self._block
        columns = np.column_stack([block.time_s, block.x_mm, block.y_mm, block.down.astype(float), block.ratio,
                                   block.target_um_pp, block.amplitude_um_pp, block.drive_um_pp, block.plate_um_pp,
                                   drive_um_pp, block.planned_ratio])
        if self.stream:
            try:
                np.savetxt(self.stream, columns, delimiter=",", fmt="%.6g")
            except OSError as error:
                raise OSError(error.errno, error.strerror, str(self.path)) from None
        if self.keep_plot:
            start = (-self._offset) % self.every
            self.kept.append(columns[start::self.every, :PLOT_COLUMNS])
        self._offset += len(columns)

    def plot_data(self) -> np.ndarray:
        import numpy as np

        return np.concatenate(self.kept) if self.kept else np.zeros((0, PLOT_COLUMNS))


@contextlib.contextmanager
def progress_bar(total: int):
    """A tqdm bar on stderr when it is a terminal; nothing (and no tqdm import) in a pipe or a file."""
    if not sys.stderr.isatty():
        yield _NoProgress()
        return
    from tqdm import tqdm

    with tqdm(total=total, unit="frame", unit_scale=True, desc="export", file=sys.stderr, leave=False) as bar:
        yield bar


class _NoProgress:
    def update(self, frames: int) -> None:
        pass


@contextlib.contextmanager
def no_collections():
    """No cyclic garbage collection while the export sets up: importing numba and scipy, loading numba's cache and
    the texture make some 10^5 objects and no garbage worth a collection, yet the collector ran through them over
    and over (0.05-0.1 s of CPU, out of a 10-minute export's 1.5 s). As it was after (for a caller in process)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


@contextlib.contextmanager
def frozen_set_up():
    """What is made so far left out of the collections while the blocks render (they walk only what the blocks
    make), and given back to the collector after, so that a caller in process keeps its own collections."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def run(args) -> int:
    with no_collections():
        import soundfile
        from ultraglide.apps.commands.output_report import clipped_fraction, clipping_warning, limiter_fields
        from ultraglide.apps.commands.render_setup import load_inputs, make_renderer
        from ultraglide.render.engine.sources import offline_stage
        from ultraglide.textures.effects import load_effects

        from ultraglide.api import WAV_SUBTYPES, available_cpus, export_duration_s, write_wav
        from ultraglide.atomic import write_failure

        if args.format not in WAV_SUBTYPES:
            raise UsageError(f"format must be one of {', '.join(WAV_SUBTYPES)}")
        output = Path(args.output)
        if output.suffix.lower() != ".wav":
            raise UsageError(f"the output must be a .wav file, got {output}")
        threads = available_cpus() if args.threads is None else int(args.threads)
        refuse_overlaps({"-o": output, "--envelope-csv": args.envelope_csv, "--plot": args.plot,
                         "--hjif": args.hjif}, render_inputs(args))
        if args.hjif and Path(args.hjif).suffix.lower() != ".hjif":
            raise UsageError(f"--hjif writes an .hjif file, got {args.hjif}")
        if args.hjif_drive and not args.hjif:
            raise UsageError("--hjif-drive adds to the --hjif file: give --hjif OUT.hjif too")
        if not args.plot:
            refuse_ignored(args, {"figure_width": "column"}, "{option} lays out --plot's figure: add --plot, or "
                                                             "leave it out")
        effects = load_effects(args.effects) if args.effects else None
        inputs = load_inputs(args)
        renderer, trajectory = make_renderer(inputs, args, args.rate), inputs.trajectory
        if effects is not None or args.no_effects:
            renderer.set_effects(effects or ())
        stage = offline_stage(renderer)
    rate = args.rate
    duration_s = export_duration_s(renderer)
    total = int(round(duration_s * rate))
    control_total = math.ceil(total / renderer.settings.upsampling)
    with contextlib.ExitStack() as stack:  # the outputs are renamed into place only once all are complete
        wav_path = stack.enter_context(atomic_path(output))
        csv_path = stack.enter_context(atomic_path(Path(args.envelope_csv))) if args.envelope_csv else None
        plot_path = stack.enter_context(atomic_path(Path(args.plot))) if args.plot else None
        hjif_path = stack.enter_context(atomic_path(Path(args.hjif))) if args.hjif else None
        if hjif_path:
            recorder = HjifRecorder()
            renderer.observers.append(recorder)
            stage.observers.append(recorder.sent)
        csv_stream = stack.enter_context(open(csv_path, "w", newline="")) if csv_path else None
        if csv_stream:
            log = EnvelopeLog(csv_stream, control_total, keep_plot=False, path=args.envelope_csv)
            renderer.observers.append(log)
            stage.observers.append(log.sent)
        if args.plot:
            from ultraglide.apps.figures.export_plot import PlotRecorder

            plot = PlotRecorder(control_total, renderer.settings.control_rate_hz, Path(args.plot))
            renderer.observers.append(plot)
        try:
            with progress_bar(total) as progress, frozen_set_up():
                write_wav(stage, wav_path, total, args.format, progress=progress.update, threads=threads)
        except soundfile.LibsndfileError as error:  # a full disk or a file too large; nothing is renamed
            raise write_failure(output, wav_path, error) from None
        if csv_stream:
            try:
                csv_stream.close()  # a write that fails on the last flush fails here, before anything is renamed
            except OSError as error:
                raise OSError(error.errno, error.strerror, str(args.envelope_csv)) from None
        if args.plot:
            plot.write(renderer, plot_path, width=args.figure_width)
        if hjif_path:
            import json

            what = f"{renderer.texture.name or 'texture'}, {duration_s:.3f} s stroke rendered by ultraglide export"
            document = recorder.document(renderer.settings.control_rate_hz, what, args.hjif_drive, renderer.texture)
            with open(hjif_path, "w", encoding="utf-8") as stream:
                json.dump(document, stream, separators=(",", ":"))
    counters = renderer.counters
    warning = clipping_warning(renderer, args.model, trajectory)
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        print_json({"output": str(output), "duration_s": round(duration_s, 6), "rate_hz": rate,
                          "format": args.format, "carrier_hz": renderer.carrier_hz,
                          "clipped_samples": counters.clipped_samples,
                          "clipped_fraction": round(clipped_fraction(renderer), 6), "ramps": counters.ramps,
                          "effects_started": 0 if renderer.effects is None else renderer.effects.started,
                          "model": args.model, "planned": renderer.planner is not None,
                          **limiter_fields(stage),
                          "extra_files": [str(extra) for extra in (args.envelope_csv, args.plot, args.hjif)
                                          if extra]})
        return 0
    started = 0 if renderer.effects is None else renderer.effects.started
    played = "" if renderer.effects is None else f", {started} effect{'s' if started != 1 else ''} played"
    print(f"wrote {output}: {duration_s:.2f} s at {rate} Hz, {args.format}, carrier {renderer.carrier_hz:g} Hz, "
          f"{counters.clipped_samples} clipped samples, {counters.ramps} ramps{played}; {stage.limiter.summary()}")
    print(model_words(args.model, renderer.model, renderer.planner is not None))
    for extra in (args.envelope_csv, args.plot, args.hjif):
        if extra:
            print(f"wrote {extra}")
    return 0
