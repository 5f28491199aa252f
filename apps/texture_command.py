"""``ultraglide texture new`` and ``ultraglide textures``."""

from __future__ import annotations

import json
from pathlib import Path

from ultraglide.apps.errors import UsageError
from ultraglide.textures import procedural
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.library import library_entries

OPTION_NAMES = {  # CLI option → generator keyword
    "wavelength_mm": "wavelength_mm", "angle_deg": "angle_deg", "shape": "shape", "square_mm": "square_mm",
    "pitch_mm": "pitch_mm", "diameter_mm": "diameter_mm", "cutoff_mm": "cutoff_mm", "seed": "seed",
    "start_mm": "start_mm", "end_mm": "end_mm", "edge_mm": "edge_mm", "detents": "detents",
    "detent_mm": "detent_mm",
}


def new(args) -> int:
    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    options = {key: getattr(args, key) for key in OPTION_NAMES if hasattr(args, key)}
    texture = procedural.GENERATORS[args.kind](size_mm=args.size_mm, ratio_range=tuple(args.range),
                                               px_per_mm=args.px_per_mm, **options)
    texture = texture.with_(name=args.name or output.stem)
    save_texture(texture, output)
    print(f"wrote {output}: {texture.description}, {texture.width_mm:g} × {texture.height_mm:g} mm, "
          f"{texture.cols}×{texture.rows} px")
    if args.preview:
        from ultraglide.apps.preview import write_preview

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
