"""The ``ultraglide`` command: argument parsing only, so that ``--help`` starts fast.

Each subcommand names a handler ``module:function`` that is imported when it runs; numpy, scipy,
pygame and the rest are loaded only by the subcommands that need them.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import re
import signal
import sys

from ultraglide.apps.cli import errors
from ultraglide.apps.cli.signals import StopSignals
from ultraglide.apps.cli.types import (
    ANGLE_DEG,
    BLUR_MM,
    BOOTSTRAP_SAMPLES,
    CARRIER_HZ,
    CLIP_PERCENT,
    COORDINATE_MM,
    DETENTS,
    DPI,
    DRIFT_HZ_PER_S,
    DUTY,
    FEATURE_MM,
    FORCE_N,
    GAMMA,
    HURST,
    LENGTH_MM,
    LEVEL,
    MAX_PIXELS,
    PARTICIPANT,
    PRINT_DPI,
    PX_PER_MM,
    Q_FACTOR,
    REPEATS,
    SCREEN_WIDTH_MM,
    SEAM_BAND,
    SEED,
    SENSITIVITY,
    SPEED_MM_S,
    STEPS,
    SWEEP_STEPS,
    TEXTURE_SIDE_MM,
    THREADS,
    TRIALS,
    TRIALS_BETWEEN_BREAKS,
    UNIT_INTERVAL,
    WEIGHT,
    ZONES,
    crop_box,
    ratio,
    size_mm,
    texture_name,
)

from ultraglide import __version__

_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line, as every error of ours is, and which reads any
    negative number (``-1e+16``, ``-inf`` too, not only ``-3`` and ``-.5``) as a value, so that an option's
    own range check names the option instead of argparse calling the number an unknown option."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


MODEL_HELP = "friction model: paper, paper-uniform, exponential, stretched, table:FILE.csv or CAL.toml"


def _add_model(parser: argparse.ArgumentParser, default: str = "paper") -> None:
    parser.add_argument("--model", default=default, metavar="MODEL",
                        help=f"{MODEL_HELP} (default: {default})")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="ultraglide",
        description="Tactile texture rendering for ultrasonic friction displays.",
    )
    parser.add_argument("--version", action="version",
                        version=f"ultraglide {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)

    model = commands.add_parser(
        "model", help="the fingerprint physics at one normal force",
        description="Contact area, ridge stiffness, detachment amplitude, glide threshold and "
                    "relative friction against amplitude, from the paper's model.")
    model.add_argument("--force", type=FORCE_N, default=None, metavar="N",
                       help="normal force of the finger, N (default: 0.5; figures: the paper's force for each)")
    _add_model(model)
    model.add_argument("--ratio", type=ratio, metavar="R",
                       help="also give the amplitude that yields friction ratio R")
    model.add_argument("--json", action="store_true", help="print one JSON object")
    model.add_argument("--plots", metavar="DIR",
                       help="write the paper's figures 2-9 here, each as a 300 dpi PNG and a PDF")
    model.add_argument("--report", metavar="FILE.pdf",
                       help="write one page on the model at this force: parameters, curve, inverse, contact")
    model.add_argument("--data", metavar="CSV",
                       help="measured points for figure 9 (default: the bundled Monnoyer 2018 fit)")
    model.set_defaults(handler="ultraglide.apps.commands.model:run")

    calibrate = commands.add_parser(
        "calibrate", help="fit a friction model to measured points",
        description="Fit a model's free parameters to a CSV of amplitude_um_pp,relative_friction"
                    "[,force_n][,participant] by least squares; report each parameter with its standard "
                    "error and the cross-validated error (k-fold, leave-one-force-out); write a calibration "
                    "file usable as --model and a figure beside it (CAL.png at 300 dpi and CAL.pdf).")
    calibrate.add_argument("data", metavar="DATA.csv")
    calibrate.add_argument("--model", default="stretched",
                           choices=["stretched", "exponential", "paper", "paper-uniform", "table"],
                           help="the model to fit (default: stretched)")
    calibrate.add_argument("--compare", action="store_true",
                           help="fit every model and rank them by cross-validated error; -o keeps the best")
    calibrate.add_argument("--participant", type=PARTICIPANT, metavar="ID",
                           help="use only this participant's points (the participant column)")
    calibrate.add_argument("--json", action="store_true", help="print one JSON object")
    calibrate.add_argument("-o", "--output", metavar="CAL.toml",
                           help="write the calibration here, and its figure as CAL.png and CAL.pdf")
    calibrate.set_defaults(handler="ultraglide.apps.commands.calibrate:run")

    _add_texture_commands(commands)

    from ultraglide.apps.commands.render_options import add_render_options

    export = commands.add_parser(
        "export", help="render a swipe or a touch log to a WAV file",
        description="Render the modulated carrier a plate would get for a swipe across a texture (or a "
                    "recorded touch log) to a WAV file, faster than real time, in bounded memory.")
    add_render_options(export)
    export.add_argument("-o", "--output", required=True, metavar="OUT.wav")
    export.add_argument("--format", choices=["float32", "int24", "int16"], default="float32")
    export.add_argument("--envelope-csv", metavar="FILE.csv",
                        help="also write target friction, amplitudes and position at the control rate")
    export.add_argument("--plot", metavar="FILE.png", help="also draw friction, amplitude and position")
    effects = export.add_mutually_exclusive_group()
    effects.add_argument("--effects", metavar="EFFECTS.json",
                         help="play these temporal effects (a versioned JSON description, see docs/effects.md) "
                              "instead of those saved with the texture")
    effects.add_argument("--no-effects", action="store_true",
                         help="leave out the temporal effects saved with the texture")
    export.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    export.add_argument("--threads", type=THREADS, metavar="N",
                        help="threads that put the envelope on the carrier, 1 to 256 (default: one per CPU available)")
    export.set_defaults(handler="ultraglide.apps.commands.export:run")

    play = commands.add_parser(
        "play", help="render a swipe or a touch log to a device in real time",
        description="Feed a swipe (as 120 Hz touch reports) or a touch log (at its own times) to the live "
                    "renderer and play it on a device.")
    add_render_options(play)
    play.add_argument("--device", default="sim", metavar="URL",
                      help="sim, serial:PORT[?baud=N], audio[:NAME_OR_INDEX][?rate=N&latency=S&blocksize=N], "
                           "wav:PATH or null "
                           "(default: sim)")
    play.add_argument("--track-resonance", action="store_true",
                      help="follow the plate's drifting resonance from its telemetry (a small dither of the "
                           "carrier, stepping toward more amplitude per unit drive); plate drivers only")
    play.add_argument("--json", action="store_true", help="print the final status as JSON")
    play.set_defaults(handler="ultraglide.apps.commands.play:run")

    latency = commands.add_parser(
        "latency", help="time from a touch to the first output sample that reflects it",
        description="Step a finger from a sticky to a slippery region many times and report the time from "
                    "each touch entering the real-time engine to the first output sample that reflects it: "
                    "the engine's part and the device's buffering part (end to end on the simulated plate).")
    latency.add_argument("--device", default="sim", metavar="URL",
                         help="sim, serial:PORT, audio[:NAME][?...], wav:PATH or null (default: sim)")
    latency.add_argument("--steps", type=STEPS, default=40, help="how many steps to time, 1 to 10000 (default: 40)")
    latency.add_argument("--profile", default="sim-plate", metavar="PROFILE", help="plate profile (default: sim-plate)")
    latency.add_argument("--json", action="store_true", help="print one JSON object")
    latency.set_defaults(handler="ultraglide.apps.commands.latency:run")

    devices = commands.add_parser("devices", help="list outputs: audio, serial ports, the simulator",
                                  description="Audio outputs with the sample rates they accept, serial ports "
                                              "and the simulated plate.")
    devices.add_argument("--json", action="store_true", help="print one JSON object")
    devices.set_defaults(handler="ultraglide.apps.commands.devices:list_all")

    sim = commands.add_parser("plate-sim", help="serve the simulated plate on a pseudo-terminal",
                              description="Run the simulated plate driver on a pty and print its path; "
                                          "connect with --device serial:PATH. Prints one line per event "
                                          "(connected, enabled, carrier, stream started/stopped, fault, "
                                          "watchdog, disabled, disconnected) with its time. Runs until stopped.")
    sim.add_argument("--profile", default="sim-plate", help="plate profile (default: sim-plate)")
    sim.add_argument("--link", metavar="PATH", help="serve at this path (default: a new temporary one)")
    sim.add_argument("--resonance-hz", type=CARRIER_HZ, metavar="F",
                     help="the simulated plate's real resonance, Hz (default: the profile's)")
    sim.add_argument("--q", type=Q_FACTOR, metavar="Q", help="its real quality factor (default: the profile's)")
    sim.add_argument("--drift-hz-per-s", type=DRIFT_HZ_PER_S, default=0.0, metavar="D",
                     help="its resonance drifts by D Hz every second (default: 0)")
    sim.add_argument("--json", action="store_true", help="print each event as a line of JSON")
    sim.add_argument("--board", choices=["sim", "qemu"], default="sim",
                     help="sim: the firmware's core on this machine; qemu: the netduinoplus2 board image under "
                          "QEMU (built first if needed), its UART on the pty (default: sim)")
    sim.set_defaults(handler="ultraglide.apps.commands.devices:plate_sim")

    firmware = commands.add_parser("firmware", help="the plate-driver firmware: build the board images",
                                   description="The reference firmware's board ports.")
    firmware_actions = firmware.add_subparsers(dest="firmware_command", metavar="ACTION", required=True,
                                               parser_class=OneLineParser)
    build = firmware_actions.add_parser(
        "build", help="cross-build the board images; print their paths and sizes",
        description="Build the board's images with arm-none-eabi-gcc (Debian's gcc-arm-none-eabi and "
                    "libnewlib-arm-none-eabi): hardware (the real DAC, DMA and ADC) and qemu (what "
                    "`plate-sim --board qemu` runs). Prints each image's path and its flash and RAM "
                    "from the linker map. Without -o the images go to a cache reused while the sources stay "
                    "the same.")
    build.add_argument("--board", default="netduinoplus2", choices=["netduinoplus2"],
                       help="the board port (default: netduinoplus2)")
    build.add_argument("--variant", action="append", choices=["hardware", "qemu", "bench"],
                       help="build only this variant (repeatable; default: hardware and qemu)")
    build.add_argument("-o", "--output", metavar="DIR", help="build into DIR (default: the cache)")
    build.add_argument("--rebuild", action="store_true", help="build even if the cache has the images")
    build.add_argument("--json", action="store_true", help="print one JSON object")
    build.set_defaults(handler="ultraglide.apps.commands.firmware:run_build")

    _add_plate_commands(commands)

    demo = commands.add_parser(
        "demo", help="feel textures on the plate: the touch-panel demo",
        description="A full-screen demo on the touch panel under the plate: a gallery of textures, each at "
                    "its physical size, and a widgets scene. Keys: G gallery, T texture, W widgets, arrows "
                    "switch texture and change the force, M model, space pause, H help, Esc quit.")
    demo.add_argument("textures", nargs="*", metavar="TEXTURE",
                      help="texture files or images to add to the library's (images are authored with defaults)")
    demo.add_argument("--device", default="sim", metavar="URL", help="output device (default: sim)")
    demo.add_argument("--profile", default="sim-plate", help="plate profile (default: sim-plate)")
    demo.add_argument("--model", default="exponential", help="friction model (default: exponential)")
    demo.add_argument("--screen-width-mm", type=SCREEN_WIDTH_MM, help="the display's width in mm, so textures show at "
                                                               "their physical size (default: a 96 dpi screen)")
    demo.add_argument("--windowed", action="store_true", help="a 1280×800 window instead of full screen")
    demo.add_argument("--record", metavar="FILE.csv",
                      help="write the touches as a touch log (t_s,x_mm,y_mm,force_n) that export and play "
                           "--trajectory replay; flushed as it goes, renamed into place at exit")
    demo.add_argument("--stats", metavar="FILE.json",
                      help="at exit, write the engine's figures over the run: blocks, late blocks, underruns "
                           "(also as they were at the first touch), block time p50/p99, touches")
    demo.add_argument("--watch", action="store_true",
                      help="reload a texture given as a file when it (or the image it was authored from) changes, "
                           "checked every 200 ms: edit it in any image editor and feel the change")
    demo.add_argument("--report-frames", action="store_true",
                      help="print a line each time the whole screen is drawn (for scripts that drive the demo)")
    demo.set_defaults(handler="ultraglide.apps.demo.app:run")
    _add_experiment_commands(commands)
    return parser


def _add_plate_commands(commands) -> None:
    plate = commands.add_parser("plate", help="characterise a plate: resonance sweep",
                                description="Measure a plate before trusting its profile.")
    actions = plate.add_subparsers(dest="plate_command", metavar="ACTION", required=True, parser_class=OneLineParser)
    sweep = actions.add_parser(
        "sweep", help="find the resonance, Q and gain; write a profile",
        description="Step the carrier across the profile's range (or --from-hz..--to-hz) driving 15 % of the "
                    "plate's limit, read the settled amplitude from telemetry at each step, fit "
                    "A(f) = A0 / sqrt(1 + (2Q(f - f0)/f0)^2), refine around the peak, and write a profile with "
                    "the measured resonance, Q and full scale (the limit is kept, never raised). The plate is "
                    "rested (zero, disable) on every way out.")
    sweep.add_argument("--device", default="sim", metavar="URL",
                       help="sim or serial:PORT[?baud=N]; audio[:NAME] needs --sensor (default: sim)")
    sweep.add_argument("--sensor", metavar="audio:NAME",
                       help="for an audio output: the input wired to a vibration sensor (one pass over the "
                            "grid, 0.1 s a carrier, amplitude by a single-bin DFT)")
    sweep.add_argument("--sensor-um-per-unit", type=SENSITIVITY, metavar="K",
                       help="the sensor's sensitivity: µm p-p of vibration per unit of input amplitude (peak, "
                            "full scale 1); without it an audio sweep keeps the profile's full scale")
    sweep.add_argument("--profile", default="sim-plate",
                       help="the plate's present profile: its range, limit and gain (default: sim-plate)")
    sweep.add_argument("--from-hz", type=CARRIER_HZ, metavar="A", help="lowest carrier, Hz (default: the profile's)")
    sweep.add_argument("--to-hz", type=CARRIER_HZ, metavar="B", help="highest carrier, Hz (default: the profile's)")
    sweep.add_argument("--steps", type=SWEEP_STEPS, default=41, metavar="N", help="coarse steps (default: 41)")
    sweep.add_argument("-o", "--output", required=True, metavar="PROFILE.toml", help="the measured profile")
    sweep.add_argument("--plot", metavar="FILE.png|pdf|svg", help="also draw the response and the fit")
    sweep.add_argument("--json", action="store_true", help="print one JSON object")
    sweep.set_defaults(handler="ultraglide.apps.commands.plate:run_sweep")
def _add_experiment_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--vary", choices=["contrast", "wavelength", "amplitude"],
                        help="the parameter the procedure varies: the friction contrast of TEXTURE (default), "
                             "the wavelength of a grating (discrimination, mm), or a uniform vibration "
                             "amplitude (µm p-p)")
    parser.add_argument("--observer", metavar="sim:threshold=T,slope=S,lapse=L",
                        help="a simulated observer (dry run, offline through the renderer; default: a person "
                             "at the window)")
    parser.add_argument("--device", metavar="URL",
                        help="output device: sim, serial:PORT, audio[...], wav:PATH or null "
                             "(default: sim; null with a simulated observer)")
    parser.add_argument("--seed", type=SEED, default=0, help="seed of every random choice (default: 0)")
    parser.add_argument("--out", metavar="DIR", help="where trials.csv, session.json, result.json and the "
                                                     "figures go (a new directory)")
    parser.add_argument("--resume", metavar="DIR", help="continue the session in DIR (its options are kept)")
    parser.add_argument("--break-every", type=TRIALS_BETWEEN_BREAKS, default=0, metavar="N",
                        help="a pause screen every N trials (default: none)")
    parser.add_argument("--participant", default="P01", help="participant code for the log (default: P01)")
    parser.add_argument("--session", default="1", help="session label for the log (default: 1)")
    parser.add_argument("--function", choices=["weibull", "logistic"], default="weibull",
                        help="psychometric function fitted (default: weibull)")
    parser.add_argument("--interval", choices=["posterior", "bootstrap"], default="posterior",
                        help="the threshold's 95 %% interval for staircases and constant stimuli: the grid "
                             "posterior's credible interval, or a parametric bootstrap of the ML fit "
                             "(default: posterior; QUEST+ always gives its posterior)")
    parser.add_argument("--bootstrap", type=BOOTSTRAP_SAMPLES, default=200, metavar="N",
                        help="bootstrap samples with --interval bootstrap (default: 200)")
    parser.add_argument("--model", default="exponential", metavar="MODEL", help=f"{MODEL_HELP} (default: exponential)")
    parser.add_argument("--profile", default="sim-plate", help="plate profile (default: sim-plate)")
    parser.add_argument("--force", type=FORCE_N, metavar="N", help="the finger's normal force, N (default: 0.5)")
    parser.add_argument("--speed-mm-s", type=SPEED_MM_S, default=100.0,
                        help="swipe speed of the simulated observer's finger (default: 100)")
    parser.add_argument("--screen-width-mm", type=SCREEN_WIDTH_MM, help="the display's width in mm (window)")
    parser.add_argument("--windowed", action="store_true", help="a window instead of full screen")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")


def _add_experiment_commands(commands) -> None:
    experiment = commands.add_parser(
        "experiment", help="threshold experiments: staircases, QUEST+, constant stimuli",
        description="Psychophysics on the plate: adaptive thresholds and the method of constant stimuli, "
                    "with a person at the touch panel or a simulated observer (dry run).")
    kinds = experiment.add_subparsers(dest="experiment", metavar="KIND", required=True, parser_class=OneLineParser)
    threshold = kinds.add_parser(
        "threshold", help="an adaptive threshold: staircase or QUEST+, 2 or 3 zones (forced choice)",
        description="Find the level of one parameter a finger detects: zones side by side, one holds the "
                    "stimulus; the participant swipes each and taps the odd one.")
    threshold.add_argument("texture", nargs="?", metavar="TEXTURE", help="a texture file or a library name")
    threshold.add_argument("--method", choices=["staircase", "quest"], default="staircase")
    threshold.add_argument("--afc", type=ZONES, help="zones (forced-choice intervals) (default: 2)")
    threshold.add_argument("--rule", choices=["1u2d", "1u3d", "weighted"], default="1u2d",
                           help="staircase rule (default: 1u2d; weighted targets 75 %% correct)")
    threshold.add_argument("--trials", type=TRIALS, metavar="N", help="number of trials")
    threshold.add_argument("--range", nargs=2, type=LEVEL, metavar=("LOW", "HIGH"),
                           help="levels the procedure may use (default: by parameter)")
    threshold.add_argument("--start-level", type=LEVEL, metavar="LEVEL", help="staircase start level")
    threshold.add_argument("--reference", metavar="TEXTURE",
                           help="what the other zones show (default: plain glass)")
    threshold.add_argument("--preset", choices=["grating-contrast", "grating-period"],
                           help="a common question: grating-contrast, the detection threshold of a 1 mm grating's "
                                "friction contrast; grating-period, the discrimination threshold of its period "
                                "(Δλ in mm against 1 mm); both 3 zones")
    _add_experiment_options(threshold)
    threshold.set_defaults(handler="ultraglide.apps.commands.experiment:run")
    constant = kinds.add_parser(
        "constant", help="the method of constant stimuli (preset: the paper's own assessment)",
        description="Fixed levels, each presented a set number of times in random order, a yes/no answer; "
                    "a psychometric function fitted by maximum likelihood. --preset vezzoli2015: 0, 2 and "
                    "4 µm p-p at the plate's resonance, 10 times each, \"more slippery?\".")
    constant.add_argument("texture", nargs="?", metavar="TEXTURE", help="a texture (not needed by the preset)")
    constant.add_argument("--preset", choices=["vezzoli2015"])
    constant.add_argument("--levels", nargs="+", type=LEVEL, metavar="L", help="the fixed levels")
    constant.add_argument("--repeats", type=REPEATS, metavar="N", help="presentations of each level")
    constant.add_argument("--afc", type=ZONES, help="forced choice instead of yes/no")
    _add_experiment_options(constant)
    constant.set_defaults(handler="ultraglide.apps.commands.experiment:run")


def _add_range(parser: argparse.ArgumentParser, default=(0.4, 1.0)) -> None:
    parser.add_argument("--range", nargs=2, type=UNIT_INTERVAL, default=list(default), metavar=("LOW", "HIGH"),
                        help="friction ratio where the pattern is off (slippery) and on (sticky), each in 0..1 "
                             f"(default: {default[0]} {default[1]})")


def _add_texture_commands(commands) -> None:
    author = commands.add_parser(
        "author", help="make a texture from an image",
        description="Turn any image Pillow reads into a texture file (16-bit PNG with metadata). "
                    "By default white is sticky (at rest) and black slippery.")
    author.add_argument("image", metavar="IMAGE")
    author.add_argument("-o", "--output", required=True, metavar="TEXTURE.png")
    size = author.add_mutually_exclusive_group()
    size.add_argument("--width-mm", type=TEXTURE_SIDE_MM, help="physical width, 0.1 to 10000 mm (default: 80)")
    size.add_argument("--dpi", type=DPI, help="physical size from the image's pixels per inch")
    author.add_argument("--mode", choices=["brightness", "edges", "gradient"], default="brightness",
                        help="brightness: luminance is friction; edges: edges are sticky; "
                             "gradient: luminance is height, felt through its slope")
    author.add_argument("--invert", action="store_true", help="swap sticky and slippery")
    author.add_argument("--levels", nargs=2, type=UNIT_INTERVAL, default=[0.0, 1.0], metavar=("BLACK", "WHITE"),
                        help="input black and white points in 0..1 (default: 0 1)")
    author.add_argument("--gamma", type=GAMMA, default=1.0,
                        help="gamma, 0.01 to 100, applied after levels (default: 1)")
    author.add_argument("--blur-mm", type=BLUR_MM, default=0.0,
                        help="Gaussian blur sigma, mm, at most the texture's width (default: 0)")
    _add_range(author)
    author.add_argument("--crop", type=crop_box, metavar="X,Y,W,H", help="crop the source, in pixels")
    author.add_argument("--background", default="white", choices=["white", "black"],
                        help="what transparent parts are composited on (default: white = at rest)")
    author.add_argument("--outside", choices=["tile", "clamp", "fixed"], default="tile",
                        help="what lies beyond the edges (default: tile)")
    author.add_argument("--max-pixels", type=MAX_PIXELS, default=40_000_000,
                        help="refuse larger images, a guard against decompression bombs; at most 100e6, "
                             "the texture file's own limit (default: 40e6)")
    author.add_argument("--seamless", action="store_true",
                        help="make the image tile without a seam (a finger would feel the jump where the tile "
                             "repeats), by --seam-method; features keep their size: --width-mm/--dpi give the "
                             "scale of the image as read")
    author.add_argument("--seam-method", choices=["crossfade", "mirror"], default="crossfade",
                        help="crossfade: a band at each end is blended into the opposite end, the tile is shorter "
                             "by the band and keeps its look; mirror: the image with mirror images right and "
                             "below, a tile twice as wide and high (default: crossfade)")
    author.add_argument("--seam-band", type=SEAM_BAND, default=0.125, metavar="FRACTION",
                        help="crossfade band, a fraction of each side in (0, 0.5] (default: 0.125)")
    author.add_argument("--auto-levels", action="store_true",
                        help="stretch the range (a percentile stretch) for images that use part of it; "
                             "replaces --levels")
    author.add_argument("--auto-levels-clip", type=CLIP_PERCENT, default=1.0, metavar="PERCENT",
                        help="with --auto-levels, the percentage of pixels clipped at each end (default: 1)")
    author.add_argument("--name", type=texture_name, help="texture name (default: the image's file name)")
    author.add_argument("--preview", metavar="PREVIEW.png",
                        help="also write a picture of the source, the friction map and a swipe")
    author.set_defaults(handler="ultraglide.apps.commands.author:run")

    listing = commands.add_parser("textures", help="list the bundled texture library",
                                  description="The textures that ship with ultraglide; use their names "
                                              "wherever a texture file is accepted.")
    listing.add_argument("--json", action="store_true", help="print a JSON list")
    listing.set_defaults(handler="ultraglide.apps.commands.texture:list_library")

    texture = commands.add_parser("texture", help="make, combine, draw and describe textures",
                                  description="Make textures from parameters, combine them, draw them, "
                                              "describe them.")
    texture_commands = texture.add_subparsers(dest="texture_command", metavar="ACTION", required=True,
                                              parser_class=OneLineParser)
    new = texture_commands.add_parser("new", help="a new procedural texture",
                                      description="Make a procedural texture and save it as a texture file.")
    kinds = new.add_subparsers(dest="kind", metavar="KIND", required=True, parser_class=OneLineParser)
    specs = {
        "grating": ("parallel ridges; the wavelength and angle snap to whole cycles across the tile",
                    [("--wavelength-mm", FEATURE_MM, 1.0), ("--angle-deg", ANGLE_DEG, 0.0),
                     ("--shape", ["sine", "square"], "sine"), ("--duty", DUTY, 0.5)]),
        "checkerboard": ("alternating squares", [("--square-mm", FEATURE_MM, 5.0)]),
        "dots": ("sticky dots", [("--pitch-mm", FEATURE_MM, 4.0), ("--diameter-mm", FEATURE_MM, 2.0)]),
        "bumps": ("round bumps, a gradient texture", [("--pitch-mm", FEATURE_MM, 10.0),
                                                      ("--diameter-mm", FEATURE_MM, 8.0)]),
        "noise": ("band-limited roughness", [("--cutoff-mm", FEATURE_MM, 2.0), ("--seed", SEED, 0)]),
        "fractal": ("fractal roughness of a Hurst exponent (spectral synthesis, seeded)",
                    [("--hurst", HURST, 0.5), ("--cutoff-mm", FEATURE_MM, 0.5), ("--seed", SEED, 0)]),
        "gabor": ("a Gabor patch: a grating under a Gaussian window", [("--wavelength-mm", FEATURE_MM, 2.0),
                                                                      ("--sigma-mm", FEATURE_MM, 4.0),
                                                                      ("--angle-deg", ANGLE_DEG, 0.0)]),
        "bump": ("one smooth bump, a gradient texture", [("--diameter-mm", FEATURE_MM, 10.0)]),
        "edge": ("one edge, slippery to sticky", [("--width-mm", FEATURE_MM, 0.5)]),
        "lines": ("single lines of several widths", [("--widths-mm", FEATURE_MM, [0.25, 0.5, 1.0, 2.0, 4.0]),
                                                     ("--spacing-mm", FEATURE_MM, 10.0)]),
        "chirp": ("wavelength sweeping across the width", [("--start-mm", FEATURE_MM, 4.0),
                                                           ("--end-mm", FEATURE_MM, 0.5)]),
        "button": ("a button with raised edges", [("--edge-mm", FEATURE_MM, 1.5)]),
        "slider": ("a slider with detents", [("--detents", DETENTS, 5), ("--detent-mm", FEATURE_MM, 1.0)]),
        "toggle": ("a toggle switch", []),
        "keyboard": ("a small keyboard with key edges", [("--edge-mm", FEATURE_MM, 0.8)]),
    }
    default_sizes = {"button": "60x40", "slider": "80x20", "toggle": "40x24", "keyboard": "90x30", "fractal": "40x40",
                     "gabor": "30x30", "bump": "30x30", "edge": "40x30", "lines": "80x40"}
    for kind, (summary, options) in specs.items():
        sub = kinds.add_parser(kind, help=summary, description=f"A procedural texture: {summary}.")
        for flag, kind_type, default in options:
            if isinstance(kind_type, list):
                sub.add_argument(flag, choices=kind_type, default=default, help=f"(default: {default})")
            elif isinstance(default, list):
                sub.add_argument(flag, type=kind_type, nargs="+", default=default,
                                 help=f"each {kind_type.describe()} (default: {' '.join(map(str, default))})")
            else:
                sub.add_argument(flag, type=kind_type, default=default,
                                 help=f"{kind_type.describe()} (default: {default})")
        if kind == "grating":
            sub.add_argument("--exact", action="store_true",
                             help="keep the wavelength and angle exactly as given; the texture then does not tile "
                                  "(its edges extend) instead of snapping to whole cycles across the tile")
        sub.add_argument("--size-mm", type=size_mm, default=size_mm(default_sizes.get(kind, "80x50")),
                         metavar="WxH", help=f"physical size in mm (default: {default_sizes.get(kind, '80x50')})")
        _add_range(sub)
        sub.add_argument("--px-per-mm", type=PX_PER_MM, help="resolution (default: 8 pixels on the finest feature)")
        sub.add_argument("--name", type=texture_name, help="texture name (default: the output's file name)")
        sub.add_argument("-o", "--output", required=True, metavar="TEXTURE.png")
        sub.add_argument("--preview", metavar="PREVIEW.png", help="also write a picture of the texture")
        sub.set_defaults(handler="ultraglide.apps.commands.texture:new")
    _add_compose(texture_commands)
    _add_show_and_info(texture_commands)


COMPOSE_SIZES = ("Sizes are reconciled on a common grid: the result covers the first input's area (or --size-mm) "
                 "at the finest pixel pitch of the inputs (or --px-per-mm); each input lies from the top-left "
                 "corner at its own physical size, read by bilinear interpolation, and beyond its edges its own "
                 "rule holds (a tile repeats, a clamped texture extends its edge, a fixed one gives its ratio).")


def region_mm(text: str) -> tuple[float, float, float, float]:
    """X,Y,WIDTH,HEIGHT in millimetres: X and Y within ±10 000, the size positive up to 10 000."""
    parts = text.split(",")
    if len(parts) != 4:
        raise argparse.ArgumentTypeError(f"a region is X,Y,WIDTH,HEIGHT in mm, e.g. 10,10,30,20, got {text!r}")
    return COORDINATE_MM(parts[0]), COORDINATE_MM(parts[1]), LENGTH_MM(parts[2]), LENGTH_MM(parts[3])


def _add_compose(texture_commands) -> None:
    compose = texture_commands.add_parser(
        "compose", help="combine textures and images into a new texture",
        description="Combine textures (files, images or library names) into a new texture file. " + COMPOSE_SIZES)
    operations = compose.add_subparsers(dest="operation", metavar="OPERATION", required=True,
                                        parser_class=OneLineParser)
    specs = {
        "mix": "the weighted mean of the inputs (equal weights unless --weights)",
        "min": "the lowest friction of the inputs at each point",
        "max": "the highest friction of the inputs at each point",
        "multiply": "the product of the inputs' friction ratios (reductions compound: 0.5 × 0.8 = 0.4)",
        "mask": "TEXTURE where MASK is white, --else (a texture, or the ratio --else-ratio) where it is black",
        "tile": "INNER repeated inside --region of OUTER; elsewhere OUTER",
    }
    for operation, summary in specs.items():
        sub = operations.add_parser(operation, help=summary, description=f"{summary[0].upper()}{summary[1:]}. "
                                    + ("" if operation == "tile" else COMPOSE_SIZES))
        if operation in ("mix", "min", "max", "multiply"):
            sub.add_argument("inputs", nargs="+", metavar="TEXTURE", help="two textures or more")
        if operation == "mix":
            sub.add_argument("--weights", nargs="+", type=WEIGHT, metavar="W",
                             help="one weight (0 or more) per texture, normalised to sum to 1")
        if operation == "mask":
            sub.add_argument("inputs", nargs=1, metavar="TEXTURE")
            sub.add_argument("mask", metavar="MASK",
                             help="an image (its luminance, white = TEXTURE, stretched over the result) or a "
                                  "texture file or name (its values, at its physical size)")
            other = sub.add_mutually_exclusive_group()
            other.add_argument("--else", dest="other", metavar="TEXTURE", help="what shows where the mask is black")
            other.add_argument("--else-ratio", type=UNIT_INTERVAL, default=1.0, metavar="R",
                               help="the friction ratio where the mask is black (default: 1, at rest)")
        if operation == "tile":
            sub.add_argument("inputs", nargs=2, metavar=("INNER", "OUTER"))
            sub.add_argument("--region", type=region_mm, required=True, metavar="X,Y,W,H",
                             help="the rectangle of OUTER to fill, in mm from its top-left corner")
        else:
            sub.add_argument("--size-mm", type=size_mm, metavar="WxH", help="the result's size (default: the first "
                                                                            "input's)")
        sub.add_argument("--px-per-mm", type=PX_PER_MM, help="the result's resolution (default: the finest input's)")
        sub.add_argument("--outside", choices=["tile", "clamp", "fixed"],
                         help="what lies beyond the result's edges (default: the first input's rule)")
        sub.add_argument("--name", type=texture_name, help="texture name (default: the output's file name)")
        sub.add_argument("-o", "--output", required=True, metavar="TEXTURE.png")
        sub.set_defaults(handler="ultraglide.apps.commands.texture:compose")


def _add_show_and_info(texture_commands) -> None:
    show = texture_commands.add_parser(
        "show", help="draw a texture: friction map, amplitude map, histogram",
        description="Draw a texture for print: the friction map at its physical size (printed at 100 %%, "
                    "1 mm on the axes is 1 mm on paper, when it fits the page) with mm axes and a colour bar, "
                    "the vibration amplitude it needs under a model, plate profile and force, and the "
                    "histogram of its friction. PNG at 300 dpi, or PDF/SVG by the output's extension.")
    show.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, or a library name")
    where = show.add_mutually_exclusive_group(required=True)
    where.add_argument("-o", "--output", metavar="FILE.png|pdf|svg")
    where.add_argument("--window", action="store_true", help="show it in a window instead (Esc or close to quit)")
    _add_model(show, default="exponential")
    show.add_argument("--profile", default="sim-plate", help="plate profile: its amplitude limit (default: sim-plate)")
    show.add_argument("--force", type=FORCE_N, default=0.5, metavar="N", help="normal force, N (default: 0.5)")
    show.add_argument("--dpi", type=PRINT_DPI, default=300.0, help="PNG resolution (default: 300)")
    show.set_defaults(handler="ultraglide.apps.figures.texture_show:run")

    info = texture_commands.add_parser("info", help="a texture's metadata, in words or JSON",
                                       description="Print what a texture is: size, pixels, kind, what lies "
                                                   "beyond its edges, friction statistics, seams, how it was made.")
    info.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, or a library name")
    info.add_argument("--json", action="store_true", help="print one JSON object")
    info.set_defaults(handler="ultraglide.apps.commands.texture:info")


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"ultraglide: warning: {message}", file=file or sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return 0
    import warnings

    warnings.showwarning = _show_warning
    module_name, function_name = args.handler.split(":")
    stop = StopSignals()  # SIGTERM and SIGHUP stop a command as Ctrl-C does, through every finally
    stop.install()
    try:
        handler = getattr(importlib.import_module(module_name), function_name)
        status = int(handler(args) or 0)
    except KeyboardInterrupt as interrupt:
        stop.restore()  # from here on the stop signals are ignored: the command has stopped
        return _stopped(stop.received or getattr(interrupt, "signum", signal.SIGINT))
    except BrokenPipeError:  # the reader left (``ultraglide textures | head``): stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at interpreter exit
        return 128 + signal.SIGPIPE
    except errors.user_errors() as error:
        print(f"ultraglide {args.command}: error: {errors.describe(error)}", file=sys.stderr)
        return 1
    finally:
        stop.restore()
    return _stopped(stop.received) if stop.received is not None else status


def console() -> int:
    """The ``ultraglide`` command (and ``python -m ultraglide``): :func:`main`, then a quick exit."""
    status = main()
    # the finished command's objects need no cycle collection at exit, which otherwise walks every object numba,
    # scipy and the texture made: about 0.15 s of a short command's time
    gc.freeze()
    return status


def _stopped(signum: int) -> int:
    """One line and the shell's status for a command stopped by a signal: 130 for Ctrl-C, 143 for SIGTERM."""
    print(f"ultraglide: stopped ({signal.Signals(signum).name})", file=sys.stderr)
    return 128 + signum


if __name__ == "__main__":
    sys.exit(console())
