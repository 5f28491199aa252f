"""The ``ultraglide`` command: argument parsing only, so that ``--help`` starts fast.

Each subcommand names a handler ``module:function`` that is imported when it runs; numpy, scipy,
pygame and the rest are loaded only by the subcommands that need them.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ultraglide.apps import errors
from ultraglide.apps.cli_types import crop_box, finite, positive, ratio, size_mm

from ultraglide import __version__


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line, as every error of ours is."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


MODEL_HELP = "friction model: paper, paper-uniform, exponential, table:FILE.csv or CAL.toml"


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
    model.add_argument("--force", type=positive, default=0.5, metavar="N",
                       help="normal force of the finger, N (default: 0.5)")
    _add_model(model)
    model.add_argument("--ratio", type=ratio, metavar="R",
                       help="also give the amplitude that yields friction ratio R")
    model.add_argument("--json", action="store_true", help="print one JSON object")
    model.add_argument("--plots", metavar="DIR", help="write the paper's figures 2-9 as PNGs here")
    model.add_argument("--data", metavar="CSV",
                       help="measured points for figure 9 (default: the bundled Monnoyer 2018 fit)")
    model.set_defaults(handler="ultraglide.apps.model_command:run")

    calibrate = commands.add_parser(
        "calibrate", help="fit a friction model to measured points",
        description="Fit a model's free parameters to a CSV of amplitude_um_pp,relative_friction"
                    "[,force_n] and write a calibration file usable as --model.")
    calibrate.add_argument("data", metavar="DATA.csv")
    calibrate.add_argument("--model", default="exponential",
                           choices=["exponential", "paper", "paper-uniform"])
    calibrate.add_argument("-o", "--output", required=True, metavar="CAL.toml")
    calibrate.set_defaults(handler="ultraglide.apps.calibrate_command:run")

    _add_texture_commands(commands)

    from ultraglide.apps.swipes import add_render_options

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
    export.set_defaults(handler="ultraglide.apps.export_command:run")

    play = commands.add_parser(
        "play", help="render a swipe or a touch log to a device in real time",
        description="Feed a swipe (as 120 Hz touch reports) or a touch log (at its own times) to the live "
                    "renderer and play it on a device.")
    add_render_options(play)
    play.add_argument("--device", default="sim", metavar="URL",
                      help="sim, serial:PORT[?baud=N], audio[:NAME_OR_INDEX][?rate=N&latency=S&blocksize=N], "
                           "wav:PATH or null "
                           "(default: sim)")
    play.add_argument("--json", action="store_true", help="print the final status as JSON")
    play.set_defaults(handler="ultraglide.apps.play_command:run")

    devices = commands.add_parser("devices", help="list outputs: audio, serial ports, the simulator",
                                  description="Audio outputs with the sample rates they accept, serial ports "
                                              "and the simulated plate.")
    devices.add_argument("--json", action="store_true", help="print one JSON object")
    devices.set_defaults(handler="ultraglide.apps.devices_command:list_all")

    sim = commands.add_parser("plate-sim", help="serve the simulated plate on a pseudo-terminal",
                              description="Run the simulated plate driver on a pty and print its path; "
                                          "connect with --device serial:PATH. Prints one line per event "
                                          "(connected, enabled, carrier, stream started/stopped, fault, "
                                          "watchdog, disabled, disconnected) with its time. Runs until stopped.")
    sim.add_argument("--profile", default="sim-plate", help="plate profile (default: sim-plate)")
    sim.add_argument("--link", metavar="PATH", help="serve at this path (default: a new temporary one)")
    sim.add_argument("--resonance-hz", type=positive, metavar="F",
                     help="the simulated plate's real resonance, Hz (default: the profile's)")
    sim.add_argument("--q", type=positive, metavar="Q", help="its real quality factor (default: the profile's)")
    sim.add_argument("--drift-hz-per-s", type=finite, default=0.0, metavar="D",
                     help="its resonance drifts by D Hz every second (default: 0)")
    sim.add_argument("--json", action="store_true", help="print each event as a line of JSON")
    sim.set_defaults(handler="ultraglide.apps.devices_command:plate_sim")

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
    demo.add_argument("--screen-width-mm", type=positive, help="the display's width in mm, so textures show at "
                                                               "their physical size (default: a 96 dpi screen)")
    demo.add_argument("--windowed", action="store_true", help="a 1280×800 window instead of full screen")
    demo.add_argument("--record", metavar="FILE.csv",
                      help="write the touches as a touch log (t_s,x_mm,y_mm,force_n) that export and play "
                           "--trajectory replay; flushed as it goes, renamed into place at exit")
    demo.add_argument("--stats", metavar="FILE.json",
                      help="at exit, write the renderer's figures: blocks, late blocks, underruns, block time "
                           "p50/p99 (over the last 50 000 blocks or more, 100 s at 2 ms a block)")
    demo.add_argument("--report-frames", action="store_true",
                      help="print a line each time the whole screen is drawn (for scripts that drive the demo)")
    demo.set_defaults(handler="ultraglide.apps.demo_app:run")
    return parser


def _add_range(parser: argparse.ArgumentParser, default=(0.4, 1.0)) -> None:
    parser.add_argument("--range", nargs=2, type=finite, default=list(default), metavar=("LOW", "HIGH"),
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
    size.add_argument("--width-mm", type=positive, help="physical width, mm (default: 80)")
    size.add_argument("--dpi", type=positive, help="physical size from the image's pixels per inch")
    author.add_argument("--mode", choices=["brightness", "edges", "gradient"], default="brightness",
                        help="brightness: luminance is friction; edges: edges are sticky; "
                             "gradient: luminance is height, felt through its slope")
    author.add_argument("--invert", action="store_true", help="swap sticky and slippery")
    author.add_argument("--levels", nargs=2, type=finite, default=[0.0, 1.0], metavar=("BLACK", "WHITE"),
                        help="input black and white points in 0..1 (default: 0 1)")
    author.add_argument("--gamma", type=finite, default=1.0, help="gamma > 0 applied after levels (default: 1)")
    author.add_argument("--blur-mm", type=finite, default=0.0, help="Gaussian blur sigma, mm (default: 0)")
    _add_range(author)
    author.add_argument("--crop", type=crop_box, metavar="X,Y,W,H", help="crop the source, in pixels")
    author.add_argument("--background", default="white", choices=["white", "black"],
                        help="what transparent parts are composited on (default: white = at rest)")
    author.add_argument("--outside", choices=["tile", "clamp", "fixed"], default="tile",
                        help="what lies beyond the edges (default: tile)")
    author.add_argument("--max-pixels", type=positive, default=40e6,
                        help="refuse larger images, a guard against decompression bombs (default: 40e6)")
    author.add_argument("--name", help="texture name (default: the image's file name)")
    author.add_argument("--preview", metavar="PREVIEW.png",
                        help="also write a picture of the source, the friction map and a swipe")
    author.set_defaults(handler="ultraglide.apps.author_command:run")

    listing = commands.add_parser("textures", help="list the bundled texture library",
                                  description="The textures that ship with ultraglide; use their names "
                                              "wherever a texture file is accepted.")
    listing.add_argument("--json", action="store_true", help="print a JSON list")
    listing.set_defaults(handler="ultraglide.apps.texture_command:list_library")

    texture = commands.add_parser("texture", help="make procedural textures",
                                  description="Make textures from parameters.")
    texture_commands = texture.add_subparsers(dest="texture_command", metavar="ACTION", required=True,
                                              parser_class=OneLineParser)
    new = texture_commands.add_parser("new", help="a new procedural texture",
                                      description="Make a procedural texture and save it as a texture file.")
    kinds = new.add_subparsers(dest="kind", metavar="KIND", required=True, parser_class=OneLineParser)
    specs = {
        "grating": ("parallel ridges", [("--wavelength-mm", positive, 1.0), ("--angle-deg", finite, 0.0),
                                        ("--shape", ["sine", "square"], "sine")]),
        "checkerboard": ("alternating squares", [("--square-mm", positive, 5.0)]),
        "dots": ("sticky dots", [("--pitch-mm", positive, 4.0), ("--diameter-mm", positive, 2.0)]),
        "bumps": ("round bumps, a gradient texture", [("--pitch-mm", positive, 10.0),
                                                      ("--diameter-mm", positive, 8.0)]),
        "noise": ("band-limited roughness", [("--cutoff-mm", positive, 2.0), ("--seed", int, 0)]),
        "chirp": ("wavelength sweeping across the width", [("--start-mm", positive, 4.0),
                                                           ("--end-mm", positive, 0.5)]),
        "button": ("a button with raised edges", [("--edge-mm", positive, 1.5)]),
        "slider": ("a slider with detents", [("--detents", int, 5), ("--detent-mm", positive, 1.0)]),
        "toggle": ("a toggle switch", []),
        "keyboard": ("a small keyboard with key edges", [("--edge-mm", positive, 0.8)]),
    }
    default_sizes = {"button": "60x40", "slider": "80x20", "toggle": "40x24", "keyboard": "90x30"}
    for kind, (summary, options) in specs.items():
        sub = kinds.add_parser(kind, help=summary, description=f"A procedural texture: {summary}.")
        for flag, kind_type, default in options:
            if isinstance(kind_type, list):
                sub.add_argument(flag, choices=kind_type, default=default, help=f"(default: {default})")
            else:
                sub.add_argument(flag, type=kind_type, default=default, help=f"(default: {default})")
        sub.add_argument("--size-mm", type=size_mm, default=size_mm(default_sizes.get(kind, "80x50")),
                         metavar="WxH", help=f"physical size in mm (default: {default_sizes.get(kind, '80x50')})")
        _add_range(sub)
        sub.add_argument("--px-per-mm", type=positive, help="resolution (default: 8 pixels on the finest feature)")
        sub.add_argument("--name", help="texture name (default: the output's file name)")
        sub.add_argument("-o", "--output", required=True, metavar="TEXTURE.png")
        sub.add_argument("--preview", metavar="PREVIEW.png", help="also write a picture of the texture")
        sub.set_defaults(handler="ultraglide.apps.texture_command:new")


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
    try:
        handler = getattr(importlib.import_module(module_name), function_name)
        return int(handler(args) or 0)
    except KeyboardInterrupt:
        print("ultraglide: stopped", file=sys.stderr)
        return 130
    except errors.user_errors() as error:
        print(f"ultraglide {args.command}: error: {errors.describe(error)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
