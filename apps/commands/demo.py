"""``ultraglide demo``: the touch-panel demo (its window and loop are :mod:`ultraglide.apps.demo`)."""

from __future__ import annotations

import argparse

from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.types import SCREEN_WIDTH_MM
from ultraglide.apps.commands.finger_options import add_finger_options
from ultraglide.apps.commands.plate_choice import add_plate_options
from ultraglide.render.physics.default_model import DEFAULT_MODEL


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide demo``: its options."""
    demo = commands.add_parser(
        "demo", help="feel textures on the plate: the touch-panel demo",
        description="A full-screen demo on the touch panel under the plate: a gallery of textures, each at "
                    "its physical size, and a widgets scene. Keys: G gallery, T texture, W widgets, arrows "
                    "switch texture and change the force, M model, space pause, H help, Esc quit.")
    demo.add_argument("textures", nargs="*", metavar="TEXTURE",
                      help="texture files or images to add to the library's (images are authored with defaults)")
    output_option(demo, "--device", kind="device", metavar="URL",
                  help="output device (default: the rig's device, else sim); audio and serial need --rig or --profile")
    add_plate_options(demo, demo, device_default="sim")
    demo.add_argument("--model", default=DEFAULT_MODEL,
                      help=f"friction model (default: {DEFAULT_MODEL}: stretched, force-aware, with the published "
                           "friction dynamics)")
    demo.add_argument("--screen-width-mm", type=SCREEN_WIDTH_MM, help="the display's width in mm, so textures show at "
                                                               "their physical size (default: a 96 dpi screen)")
    demo.add_argument("--windowed", action="store_true", help="a 1280×800 window instead of full screen")
    output_option(demo, "--record", kind="log", metavar="FILE.csv",
                      help="write the touches as a touch log (t_s,x_mm,y_mm,force_n) that export and play "
                           "--trajectory replay; flushed as it goes, renamed into place at exit")
    output_option(demo, "--stats", metavar="FILE.json",
                      help="at exit, write the engine's figures over the run: blocks, late blocks, underruns "
                           "(also as they were at the first touch), block time p50/p99, touches")
    demo.add_argument("--effects", metavar="EFFECTS",
                      help="play these temporal effects with the textures given, instead of their own: a .json "
                           "description (docs/effects.md), or an .ahap, .haptic, .hjif or .haps file (docs/formats.md)")
    demo.add_argument("--watch", action="store_true",
                      help="reload a texture given as a file when it (or the image it was authored from) changes, "
                           "checked every 200 ms: edit it in any image editor and feel the change")
    demo.add_argument("--report-frames", action="store_true",
                      help="print a line each time the whole screen is drawn (for scripts that drive the demo)")
    demo.add_argument("--closed-loop", action="store_true",
                      help="make the friction the plate's force sensors measure follow the texture (a plate driver "
                           "with force sensors; on sim, a simulated finger); the chart shows it beside the target")
    add_finger_options(demo, "--device sim")
    demo.set_defaults(run=run)


def run(args) -> int:
    """Start the demo (pygame and the engine load here, not when the parser is built)."""
    from ultraglide.apps.cli.errors import UsageError, require
    from ultraglide.apps.cli.files import model_file, profile_file, refuse_overlaps, texture_file

    require("pygame")  # the demo extra's: said in one line before anything starts
    from ultraglide.apps.demo.app import run as run_demo

    if args.effects and not args.textures:
        raise UsageError("--effects plays with the textures given on the command line: name one or more")
    read = {f"texture {number}": texture_file(spec) for number, spec in enumerate(args.textures, 1)}
    refuse_overlaps({"--record": args.record, "--stats": args.stats},
                    {**read, "--model": model_file(args.model), "--profile": profile_file(args.profile),
                     "--effects": args.effects})
    return run_demo(args)


