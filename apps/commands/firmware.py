"""``ultraglide firmware build``: cross-build the board images and say where they are and how big."""

from __future__ import annotations

import argparse

from ultraglide.apps.cli.options import OneLineParser, output_option
from ultraglide.apps.cli.output import print_json


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide firmware``: its actions and their options."""
    firmware = commands.add_parser("firmware", help="the plate-driver firmware: build the board images",
                                   description="The reference firmware's board ports.")
    firmware_actions = firmware.add_subparsers(dest="firmware_command", metavar="ACTION", required=True,
                                               parser_class=OneLineParser)
    build = firmware_actions.add_parser(
        "build", help="cross-build the board images; print their paths and sizes",
        description="Build the board's images with arm-none-eabi-gcc (Debian's gcc-arm-none-eabi and "
                    "libnewlib-arm-none-eabi): netduinoplus2's hardware (the real DAC, DMA and ADC) and qemu "
                    "(what `plate-sim --board qemu` runs) images, or mps2-an386's qemu image (what "
                    "`plate-sim --board mps2-an386` runs). Prints each image's path and its flash and RAM "
                    "from the linker map. Without -o the images go to a cache reused while the sources stay "
                    "the same.")
    build.add_argument("--board", default="netduinoplus2", choices=["netduinoplus2", "mps2-an386"],
                       help="the board port (default: netduinoplus2)")
    build.add_argument("--variant", action="append", choices=["hardware", "qemu", "bench"],
                       help="build only this variant (repeatable; default: netduinoplus2's hardware and qemu, "
                            "mps2-an386's qemu, its only one)")
    output_option(build, "-o", "--output", kind="folder", metavar="DIR", help="build into DIR (default: the cache)")
    build.add_argument("--rebuild", action="store_true", help="build even if the cache has the images")
    build.add_argument("--json", action="store_true", help="print one JSON object")
    build.set_defaults(run=run_build)


def run_build(args) -> int:
    from ultraglide.apps.cli.errors import UsageError
    from ultraglide.devices.firmware.boards import BOARD_INFO, build_images

    board = BOARD_INFO[args.board]
    variants = args.variant or list(board.default_variants)
    for variant in variants:
        if variant not in board.variants:
            raise UsageError(f"--variant {variant}: {board.name} has only {', '.join(board.variants)}")
    images = build_images(args.board, variants, out_dir=args.output, rebuild=args.rebuild)
    flash_kib = (board.flash[1] - board.flash[0]) // 1024
    ram_kib = (board.ram[1] - board.ram[0]) // 1024
    if args.json:
        print_json({"board": args.board, "images": [image.as_dict() for image in images]})
        return 0
    for image in images:
        print(f"{image.variant:9} {image.elf_path}")
        print(f"{'':9} flash {image.flash_bytes} bytes ({image.flash_bytes / 1024:.1f} KiB of {flash_kib}), "
              f"RAM {image.ram_bytes} bytes ({image.ram_bytes / 1024:.1f} KiB of {ram_kib}, stack "
              f"{image.stack_bytes / 1024:g} KiB included)")
        if image.bin_path and image.board == "netduinoplus2":
            print(f"{'':9} {image.bin_path} (raw, for st-flash at 0x08000000)")
    return 0
