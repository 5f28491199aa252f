"""``ultraglide author``: a texture from an image."""

from __future__ import annotations

import argparse
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import refuse_overlaps
from ultraglide.apps.cli.options import add_range_option, output_option, refuse_ignored
from ultraglide.apps.cli.types import (
    BLUR_MM,
    CLIP_PERCENT,
    DPI,
    GAMMA,
    MAX_PIXELS,
    SEAM_BAND,
    TEXTURE_SIDE_MM,
    UNIT_INTERVAL,
    crop_box,
    texture_name,
)


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide author``: its options."""
    author = commands.add_parser(
        "author", help="make a texture from an image",
        description="Turn any image Pillow reads into a texture file (16-bit PNG with metadata). "
                    "By default white is sticky (at rest) and black slippery.")
    author.add_argument("image", metavar="IMAGE")
    output_option(author, "-o", "--output", required=True, metavar="TEXTURE.png")
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
    add_range_option(author)
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
    output_option(author, "--preview", metavar="PREVIEW.png",
                        help="also write a picture of the source, the friction map and a swipe")
    author.set_defaults(run=run)


def run(args) -> int:
    from ultraglide.textures.authoring import (
        AuthoringOptions,
        ImageTooLarge,
        read_image_luminance,
        texture_from_luminance,
    )
    from ultraglide.textures.fileformat import save_texture

    if not args.seamless:
        refuse_ignored(args, {"seam_method": "crossfade", "seam_band": 0.125},
                       "{option} says how --seamless joins the tile: add --seamless or leave it out")
    elif args.seam_method == "mirror":
        refuse_ignored(args, {"seam_band": 0.125}, "{option} is the band of --seam-method crossfade; mirror has none")
    if not args.auto_levels:  # (--levels with --auto-levels: the options refuse them)
        refuse_ignored(args, {"auto_levels_clip": 1.0}, "{option} tunes --auto-levels: add it, or leave this out")
    low, high = args.range
    black, white = args.levels
    options = AuthoringOptions(
        width_mm=args.width_mm, dpi=args.dpi, mode=args.mode, invert=args.invert, black=black, white=white,
        gamma=args.gamma, blur_mm=args.blur_mm, ratio_range=(low, high), crop=args.crop,
        background=(255, 255, 255) if args.background == "white" else (0, 0, 0),
        max_pixels=int(args.max_pixels), outside=args.outside,
        seamless=args.seam_method if args.seamless else None, seam_band=args.seam_band,
        auto_levels=args.auto_levels_clip if args.auto_levels else None,
    )
    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    refuse_overlaps({"-o": output, "--preview": args.preview}, {"the image": args.image})
    try:
        luminance, info = read_image_luminance(args.image, options)
    except ImageTooLarge as error:
        raise error.advising("raise the limit with --max-pixels (up to 100e6) or shrink the image") from None
    name = args.name or output.stem
    texture = texture_from_luminance(luminance, options, name, str(args.image), info)
    if args.preview:
        from ultraglide.apps.figures.preview import write_preview

        source = None if options.seamless else luminance  # a seamless tile no longer matches the source pixels
        write_preview(texture, Path(args.preview), source)
    save_texture(texture, output)
    print(f"wrote {output}: {texture.name}, {texture.width_mm:.1f} × {texture.height_mm:.1f} mm, "
          f"{texture.cols}×{texture.rows} px, {texture.kind}, ratio {low:g}..{high:g}")
    if args.preview:
        print(f"wrote {args.preview}")
    return 0
