"""``ultraglide texture new`` and ``ultraglide textures``."""

from __future__ import annotations

import json
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.textures import procedural
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.library import library_entries

OPTION_NAMES = {  # CLI option → generator keyword
    "wavelength_mm": "wavelength_mm", "angle_deg": "angle_deg", "shape": "shape", "square_mm": "square_mm",
    "pitch_mm": "pitch_mm", "diameter_mm": "diameter_mm", "cutoff_mm": "cutoff_mm", "seed": "seed",
    "start_mm": "start_mm", "end_mm": "end_mm", "edge_mm": "edge_mm", "detents": "detents",
    "detent_mm": "detent_mm", "duty": "duty", "hurst": "hurst", "sigma_mm": "sigma_mm", "width_mm": "width_mm",
    "widths_mm": "widths_mm", "spacing_mm": "spacing_mm",
}


def new(args) -> int:
    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    options = {key: getattr(args, key) for key in OPTION_NAMES if hasattr(args, key)}
    if getattr(args, "exact", False):
        options["tile"] = False
    texture = procedural.GENERATORS[args.kind](size_mm=args.size_mm, ratio_range=tuple(args.range),
                                               px_per_mm=args.px_per_mm, **options)
    texture = texture.with_(name=args.name or output.stem)
    save_texture(texture, output)
    print(f"wrote {output}: {texture.description}, {texture.width_mm:g} × {texture.height_mm:g} mm, "
          f"{texture.cols}×{texture.rows} px")
    if args.preview:
        from ultraglide.apps.figures.preview import write_preview

        write_preview(texture, Path(args.preview))
        print(f"wrote {args.preview}")
    return 0


def list_library(args) -> int:
    entries = library_entries()
    if args.json:
        print(json.dumps([{"name": e.name, "width_mm": e.width_mm, "height_mm": e.height_mm, "kind": e.kind,
                           "description": e.description} for e in entries], ensure_ascii=False))
        return 0
    print(f"{'name':24} {'size (mm)':>13}  {'kind':9} description")
    for e in entries:
        print(f"{e.name:24} {e.width_mm:6.1f} × {e.height_mm:<5.1f} {e.kind:9} {e.description}")
    return 0


def _input(spec: str):
    """A texture from a file, an image (authored with defaults, with a warning) or a library name."""
    from ultraglide.textures.library import resolve_texture

    return resolve_texture(spec)


def _mask_weights(spec: str):
    """A mask: a texture file or library name gives its values; any other image its luminance."""
    from ultraglide.textures.authoring import read_image_luminance
    from ultraglide.textures.library import has_metadata

    path = Path(spec)
    if path.is_file() and not has_metadata(path):
        luminance, _ = read_image_luminance(path)
        return luminance
    return _input(spec)


def compose(args) -> int:
    from ultraglide.textures import compose as combine

    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    name = args.name or output.stem
    inputs = [_input(spec) for spec in args.inputs]
    common = dict(px_per_mm=args.px_per_mm, name=name, outside=args.outside)
    operation = args.operation
    if operation == "mix":
        texture = combine.mix(inputs, args.weights, size_mm=args.size_mm, **common)
    elif operation in ("min", "max", "multiply"):
        function = {"min": combine.minimum, "max": combine.maximum, "multiply": combine.multiply}[operation]
        texture = function(inputs, size_mm=args.size_mm, **common)
    elif operation == "mask":
        other = _input(args.other) if args.other else None
        texture = combine.mask(inputs[0], _mask_weights(args.mask), other, args.else_ratio, size_mm=args.size_mm,
                               **common)
    else:
        texture = combine.tile_inside(inputs[0], inputs[1], args.region, **common)
    save_texture(texture, output)
    print(f"wrote {output}: {texture.description}; {texture.width_mm:g} × {texture.height_mm:g} mm, "
          f"{texture.cols}×{texture.rows} px ({texture.authoring['px_per_mm']:g} px/mm), {texture.kind}")
    return 0


def describe(texture, spec: str) -> dict:
    """What ``texture info`` prints: metadata, friction statistics and seams, JSON-ready."""
    import numpy as np
    from ultraglide.textures.seams import measure_seams

    ratio = texture.ratio_map()
    seams = measure_seams(texture.values)
    pixel_x, pixel_y = texture.pixel_mm
    return {
        "texture": spec, "name": texture.name, "description": texture.description, "kind": texture.kind,
        "width_mm": texture.width_mm, "height_mm": texture.height_mm, "cols": texture.cols, "rows": texture.rows,
        "pixel_mm": [pixel_x, pixel_y], "outside": texture.outside, "outside_ratio": texture.outside_ratio,
        "ratio_range": list(texture.ratio_range),
        "full_slope_per_mm": texture.full_slope_per_mm if texture.kind == "gradient" else None,
        "friction": {"min": float(ratio.min()), "mean": float(ratio.mean()), "max": float(ratio.max()),
                     "std": float(np.std(ratio))},
        "seams": {"seam_max": seams.seam_max, "interior_max": seams.interior_max, "ratio": seams.ratio,
                  "seamless": seams.seamless, "visible": seams.visible},
        "source": texture.source, "authoring": texture.authoring,
    }


OUTSIDE_WORDS = {"tile": "it repeats (a tile)", "clamp": "its edges extend", "fixed": "a fixed friction ratio of {:g}"}


def info(args) -> int:
    texture = _input(args.texture)
    facts = describe(texture, args.texture)
    if args.json:
        print(json.dumps(facts, ensure_ascii=False))
        return 0
    friction, seams = facts["friction"], facts["seams"]
    beyond = OUTSIDE_WORDS[texture.outside].format(texture.outside_ratio)
    lines = [
        f"{texture.name}: {texture.description}",
        f"  size        {texture.width_mm:g} × {texture.height_mm:g} mm, {texture.cols} × {texture.rows} pixels "
        f"of {facts['pixel_mm'][0]:.3g} × {facts['pixel_mm'][1]:.3g} mm",
        f"  kind        {texture.kind}" + (" (friction follows the slope of a height map; figures below are for a "
                                           "left-to-right swipe)" if texture.kind == "gradient" else
                                           " (the values are friction ratios, 1 = plate at rest)"),
        f"  friction    {friction['min']:.3f} to {friction['max']:.3f}, mean {friction['mean']:.3f}, "
        f"standard deviation {friction['std']:.3f}",
        f"  beyond      {beyond}",
    ]
    if texture.outside == "tile":
        verdict = "seamless" if seams["seamless"] else ("a seam a finger would feel" if seams["visible"] else
                                                        "a slight seam")
        lines.append(f"  seams       {verdict}: largest step across the tile's edge {seams['seam_max']:.3f}, "
                     f"inside {seams['interior_max']:.3f}")
    if texture.source:
        lines.append(f"  source      {texture.source}")
    if texture.authoring:
        made = ", ".join(f"{key} {value}" for key, value in texture.authoring.items())
        lines.append(f"  made with   {made}")
    print("\n".join(lines))
    return 0
