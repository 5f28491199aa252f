"""``ultraglide author``: a texture from an image."""

from __future__ import annotations

from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.textures.authoring import AuthoringOptions, read_image_luminance, texture_from_luminance
from ultraglide.textures.fileformat import save_texture


def run(args) -> int:
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
    luminance, info = read_image_luminance(args.image, options)
    name = args.name or output.stem
    texture = texture_from_luminance(luminance, options, name, str(args.image), info)
    if args.preview:
        from ultraglide.apps.figures.preview import write_preview

        crop = options.crop
        source = luminance if crop is None else luminance[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]]
        if options.seamless:  # the tile no longer matches the source pixel for pixel
            source = None
        write_preview(texture, Path(args.preview), source)
    save_texture(texture, output)
    print(f"wrote {output}: {texture.name}, {texture.width_mm:.1f} × {texture.height_mm:.1f} mm, "
          f"{texture.cols}×{texture.rows} px, {texture.kind}, ratio {low:g}..{high:g}")
    if args.preview:
        print(f"wrote {args.preview}")
    return 0
