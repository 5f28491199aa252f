"""``ultraglide rig check RIG.toml``: what a rig file resolves to, and what loading it could not verify.

The rig is read by :func:`ultraglide.devices.rig.load_rig` (a bad file is one line, exit 2); this command prints
the plate, the drive chain's arithmetic (``full_scale_um_pp``: what a sample of 1.0 moves the plate), every
limit declared and the one that binds, the device, the touch panel and the display, then what was taken as
written. ``--json`` gives the same as one strict JSON object.
"""

from __future__ import annotations

import argparse
import sys

from ultraglide.apps.cli.options import OneLineParser
from ultraglide.apps.cli.output import print_json


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide rig``: its actions and their options."""
    rig = commands.add_parser("rig", help="a lab's rig file: check what it resolves to",
                              description="A rig file names a lab's parts: the plate, the drive chain, the output "
                                          "device, the touch panel and the display (see examples/rig.toml). "
                                          "Commands that drive the plate take it as --rig RIG.toml.")
    actions = rig.add_subparsers(dest="rig_command", metavar="ACTION", required=True, parser_class=OneLineParser)
    check = actions.add_parser(
        "check", help="print what a rig file resolves to and what could not be verified",
        description="Load a rig file and print what it resolves to: the plate's profile, the drive chain's "
                    "full_scale_um_pp (the plate's amplitude at a sample of 1.0), every limit declared and the "
                    "smallest, which binds, the output device, the touch panel and the display; then what was "
                    "taken as written and must be measured. Exit status 2 for a file that cannot be used.")
    check.add_argument("rig_file", metavar="RIG.toml", help="the rig file")
    check.add_argument("--json", action="store_true", help="print one JSON object")
    check.set_defaults(run=run_check)


def run_check(args) -> int:
    from ultraglide.apps.cli.output import one_line
    from ultraglide.devices.rig import RigError, load_rig

    try:
        rig = load_rig(args.rig_file)
    except RigError as error:  # a file a person wrote: usage, as a bad option is
        print(f"ultraglide rig: error: {one_line(str(error))}", file=sys.stderr)
        return 2
    if args.json:
        print_json(rig.as_dict())
        return 0
    for line in describe(rig):
        print(line)
    return 0


def describe(rig) -> list[str]:
    """The rig in words, one fact a line."""
    plate = rig.plate
    lines = [f"rig {rig.name} ({rig.path})" + (f": {rig.description}" if rig.description else "")]
    source = "given inline" if rig.plate_source == "inline" else f"from profile {rig.plate_source}"
    lines.append(f"plate: {plate.shown_name}, {source}: resonance {plate.resonance_hz:g} Hz, Q {plate.q:g}, "
                 f"carrier {plate.carrier_min_hz:g}-{plate.carrier_max_hz:g} Hz")
    if rig.drive is not None:
        lines.append(f"drive chain: {rig.drive.words()}")
    else:
        lines.append(f"drive chain: none given; full_scale_um_pp = {plate.full_scale_um_pp:g} µm p-p as the plate "
                     "says")
    declared = ", ".join(f"{who} {value:g}" for who, value in rig.limits_um_pp.items())
    lines.append(f"limit: {plate.max_amplitude_um_pp:g} µm p-p ({rig.limit_from}; declared, µm p-p: {declared}); "
                 f"a sample never asks for more than {plate.max_amplitude_um_pp / plate.full_scale_um_pp:.3g} of full "
                 "scale" + (f", {plate.max_drive_um_pp:g} µm p-p for a moment of overdrive"
                            if plate.max_drive_um_pp > plate.max_amplitude_um_pp else ""))
    lines.append(f"output device: {rig.device}" if rig.device else
                 "output device: none (commands take --device, or drive the simulated plate)")
    touch = rig.touch
    if touch is None:
        lines.append("touch panel: none given (the demo maps touches onto the whole display, first finger drives)")
    else:
        area = ("the whole display" if touch.area_mm is None else
                "{:g},{:g} mm, {:g} × {:g} mm".format(*touch.area_mm))
        flips = " ".join(word for word, on in (("flipped in x", touch.flip_x), ("flipped in y", touch.flip_y)) if on)
        pressure = (f"pressure 1.0 = {touch.pressure_full_scale_n:g} N" if touch.pressure_full_scale_n is not None
                    else "no pressure (the demo's force applies)")
        ranges = ", ".join(f"{axis} {low}..{high}" for axis, (low, high) in touch.axis_ranges.items())
        lines.append(f"touch panel: active area {area}, turned {touch.rotation_deg}°{' ' + flips if flips else ''}; "
                     f"{pressure}; with two down, {DRIVES_WORDS[touch.drives]}"
                     f"{'; axis ranges ' + ranges + ' (panel units)' if ranges else ''}")
    lines.append(f"display: {rig.display_width_mm:g} mm wide" if rig.display_width_mm is not None else
                 "display: width not given (the demo assumes 96 dpi unless --screen-width-mm)")
    lines.append(f"full_scale_um_pp = {plate.full_scale_um_pp:g}, max_amplitude_um_pp = {plate.max_amplitude_um_pp:g}")
    lines.append("not verified:")
    lines.extend(f"  - {sentence}" for sentence in rig.unverified())
    return lines


DRIVES_WORDS = {"first": "the first touch drives until it lifts", "latest": "the newest touch drives",
                "none": "none drives (the plate rests until one lifts)"}
