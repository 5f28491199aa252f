"""``ultraglide firmware build``: cross-build the board images and say where they are and how big."""

from __future__ import annotations

import json

from ultraglide.devices.firmware.boards import build_images


def run_build(args) -> int:
    variants = args.variant or ["hardware", "qemu"]
    images = build_images(args.board, variants, out_dir=args.output, rebuild=args.rebuild)
    if args.json:
        print(json.dumps({"board": args.board, "images": [image.as_dict() for image in images]}))
        return 0
    for image in images:
        print(f"{image.variant:9} {image.elf_path}")
        print(f"{'':9} flash {image.flash_bytes} bytes ({image.flash_bytes / 1024:.1f} KiB of 1024), "
              f"RAM {image.ram_bytes} bytes ({image.ram_bytes / 1024:.1f} KiB of 128, stack "
              f"{image.stack_bytes / 1024:g} KiB included)")
        if image.bin_path:
            print(f"{'':9} {image.bin_path} (raw, for st-flash at 0x08000000)")
    return 0
