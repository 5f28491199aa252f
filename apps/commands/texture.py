"""``ultraglide textures`` and ``ultraglide texture`` (new, compose, show, info; effects, import and export-gltf in
modules of their own)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import refuse_overlaps, texture_file
from ultraglide.apps.cli.options import (
    OneLineParser,
    add_figure_width_option,
    add_model_option,
    add_range_option,
    output_option,
)
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import (
    ANGLE_DEG,
    COORDINATE_MM,
    DETENTS,
    DUTY,
    FEATURE_MM,
    FORCE_N,
    HURST,
    LENGTH_MM,
    PRINT_DPI,
    PX_PER_MM,
    SEED,
    UNIT_INTERVAL,
    WEIGHT,
    size_mm,
    texture_name,
)
from ultraglide.render.physics.default_model import DEFAULT_MODEL

OPTION_NAMES = {  # CLI option → generator keyword
    "wavelength_mm": "wavelength_mm", "angle_deg": "angle_deg", "shape": "shape", "square_mm": "square_mm",
    "pitch_mm": "pitch_mm", "diameter_mm": "diameter_mm", "cutoff_mm": "cutoff_mm", "seed": "seed",
    "start_mm": "start_mm", "end_mm": "end_mm", "edge_mm": "edge_mm", "detents": "detents",
    "detent_mm": "detent_mm", "duty": "duty", "hurst": "hurst", "sigma_mm": "sigma_mm", "width_mm": "width_mm",
    "widths_mm": "widths_mm", "spacing_mm": "spacing_mm",
}


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide textures`` and ``ultraglide texture`` (new, compose, show, info): their options."""
    listing = commands.add_parser("textures", help="list the bundled texture library",
                                  description="The textures that ship with ultraglide; use their names "
                                              "wherever a texture file is accepted.")
    listing.add_argument("--json", action="store_true", help="print a JSON list")
    listing.set_defaults(run=list_library)

    texture = commands.add_parser("texture", help="make, combine, draw and describe textures",
                                  description="Make textures from parameters, combine them, draw them, "
                                              "describe them.")
    texture_commands = texture.add_subparsers(dest="texture_command", metavar="ACTION", required=True,
                                              parser_class=OneLineParser)
    new_parser = texture_commands.add_parser("new", help="a new procedural texture",
                                      description="Make a procedural texture and save it as a texture file.")
    kinds = new_parser.add_subparsers(dest="kind", metavar="KIND", required=True, parser_class=OneLineParser)
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
        add_range_option(sub)
        sub.add_argument("--px-per-mm", type=PX_PER_MM, help="resolution (default: 8 pixels on the finest feature)")
        sub.add_argument("--name", type=texture_name, help="texture name (default: the output's file name)")
        output_option(sub, "-o", "--output", required=True, metavar="TEXTURE.png")
        output_option(sub, "--preview", metavar="PREVIEW.png", help="also write a picture of the texture")
        sub.set_defaults(run=new)
    _add_compose(texture_commands)
    _add_show_and_info(texture_commands)
    from ultraglide.apps.commands import texture_effects, texture_formats

    texture_effects.add_parser(texture_commands)
    texture_formats.add_parser(texture_commands)


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
    compose_parser = texture_commands.add_parser(
        "compose", help="combine textures and images into a new texture",
        description="Combine textures (files, images or library names) into a new texture file. " + COMPOSE_SIZES)
    operations = compose_parser.add_subparsers(dest="operation", metavar="OPERATION", required=True,
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
            # two positionals into one list: argparse cannot show a positional's tuple metavar (a traceback in
            # --help and in the usage error for one input)
            sub.add_argument("inputs", action="append", metavar="INNER", help="the texture repeated inside the region")
            sub.add_argument("inputs", action="append", metavar="OUTER", help="the texture it is placed on")
            sub.add_argument("--region", type=region_mm, required=True, metavar="X,Y,W,H",
                             help="the rectangle of OUTER to fill, in mm from its top-left corner")
        else:
            sub.add_argument("--size-mm", type=size_mm, metavar="WxH", help="the result's size (default: the first "
                                                                            "input's)")
        sub.add_argument("--px-per-mm", type=PX_PER_MM, help="the result's resolution (default: the finest input's)")
        sub.add_argument("--outside", choices=["tile", "clamp", "fixed"],
                         help="what lies beyond the result's edges (default: the first input's rule)")
        sub.add_argument("--name", type=texture_name, help="texture name (default: the output's file name)")
        sub.add_argument("--no-effects", action="store_true",
                         help="leave out the inputs' temporal effects (by default the result keeps them all)")
        output_option(sub, "-o", "--output", required=True, metavar="TEXTURE.png")
        sub.set_defaults(run=compose)


def _add_show_and_info(texture_commands) -> None:
    show_parser = texture_commands.add_parser(
        "show", help="draw a texture: friction map, amplitude map, histogram",
        description="Draw a texture for print: the friction map at its physical size (printed at 100 %%, "
                    "1 mm on the axes is 1 mm on paper, when it fits the page) with mm axes and a colour bar, "
                    "the vibration amplitude it needs under a model, plate profile and force, and the "
                    "histogram of its friction. PNG at 300 dpi, or PDF/SVG by the output's extension.")
    show_parser.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, or a library name")
    where = show_parser.add_mutually_exclusive_group(required=True)
    output_option(where, "-o", "--output", metavar="FILE.png|pdf|svg")
    where.add_argument("--window", action="store_true", help="show it in a window instead (Esc or close to quit)")
    add_model_option(show_parser, default=DEFAULT_MODEL)
    show_parser.add_argument("--profile", default="sim-plate",
                             help="plate profile: its amplitude limit (default: sim-plate)")
    show_parser.add_argument("--force", type=FORCE_N, default=0.5, metavar="N",
                             help="normal force, N (default: 0.5)")
    show_parser.add_argument("--dpi", type=PRINT_DPI, default=300.0, help="PNG resolution (default: 300)")
    add_figure_width_option(show_parser, default="page")  # a page holds most textures at their physical size
    show_parser.set_defaults(run=show)

    info_parser = texture_commands.add_parser("info", help="a texture's metadata, in words or JSON",
                                              description="Print what a texture is: size, pixels, kind, what lies "
                                                          "beyond its edges, friction statistics, seams, how it "
                                                          "was made.")
    info_parser.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, a library name, or a glTF "
                                                                "scene (.gltf, .glb: its haptic materials)")
    info_parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_model_option(info_parser, default=DEFAULT_MODEL)
    info_parser.add_argument("--profile", default="sim-plate",
                             help="plate profile: its amplitude limit, which sets the lowest friction a swipe is "
                                  "felt at (default: sim-plate)")
    info_parser.add_argument("--force", type=FORCE_N, default=0.5, metavar="N",
                             help="normal force, N (default: 0.5)")
    info_parser.set_defaults(run=info)


def show(args) -> int:
    """``ultraglide texture show`` (matplotlib and pygame load here, not when the parser is built)."""
    from ultraglide.apps.figures.texture_show import run

    return run(args)


def new(args) -> int:
    from ultraglide.textures import procedural
    from ultraglide.textures.fileformat import save_texture

    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    refuse_overlaps({"-o": output, "--preview": args.preview})
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
    from ultraglide.textures.library import library_entries

    entries = library_entries()
    if args.json:
        print_json([{"name": e.name, "width_mm": _mm(e.width_mm), "height_mm": _mm(e.height_mm), "kind": e.kind,
                     "description": e.description} for e in entries])
        return 0
    sizes = [f"{e.width_mm:.1f} × {e.height_mm:.1f}" for e in entries]
    name_w = max([len("name")] + [len(e.name) for e in entries])
    size_w = max([len("size (mm)")] + [len(size) for size in sizes])
    kind_w = max([len("kind")] + [len(e.kind) for e in entries])
    print(f"{'name':{name_w}}  {'size (mm)':>{size_w}}  {'kind':{kind_w}}  description")
    for e, size in zip(entries, sizes, strict=True):
        print(f"{e.name:{name_w}}  {size:>{size_w}}  {e.kind:{kind_w}}  {e.description}")
    return 0


def _mm(value: float) -> float:
    """A length in mm as it means: to the micrometre (78.80000000000001 is 78.8)."""
    return round(float(value), 3)


def _ratio(value: float) -> float:
    """A friction ratio as it means: a 16-bit texture resolves 1/65535, so to 5 decimals."""
    return round(float(value), 5)


def _readable(value):
    """Recorded options (authoring) without float noise: 6 significant digits."""
    if isinstance(value, float):
        return float(f"{value:.6g}")
    if isinstance(value, list | tuple):
        return [_readable(item) for item in value]
    if isinstance(value, dict):
        return {key: _readable(item) for key, item in value.items()}
    return value


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
    from ultraglide.textures.fileformat import save_texture

    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    read = {f"input {number}": texture_file(spec) for number, spec in enumerate(args.inputs, 1)}
    read.update({"the mask": texture_file(getattr(args, "mask", None)),
                 "--else": texture_file(getattr(args, "other", None))})
    refuse_overlaps({"-o": output}, read)
    name = args.name or output.stem
    bare = (lambda texture: texture.with_(effects=())) if args.no_effects else (lambda texture: texture)
    inputs = [bare(_input(spec)) for spec in args.inputs]
    common = dict(px_per_mm=args.px_per_mm, name=name, outside=args.outside)
    operation = args.operation
    if operation == "mix":
        texture = combine.mix(inputs, args.weights, size_mm=args.size_mm, **common)
    elif operation in ("min", "max", "multiply"):
        function = {"min": combine.minimum, "max": combine.maximum, "multiply": combine.multiply}[operation]
        texture = function(inputs, size_mm=args.size_mm, **common)
    elif operation == "mask":
        other = bare(_input(args.other)) if args.other else None
        texture = combine.mask(inputs[0], _mask_weights(args.mask), other, args.else_ratio, size_mm=args.size_mm,
                               **common)
    else:
        texture = combine.tile_inside(inputs[0], inputs[1], args.region, **common)
    save_texture(texture, output)
    count = len(texture.effects)
    kept = f"; the inputs' {count} temporal effect{'s' if count != 1 else ''} kept" if count else ""
    print(f"wrote {output}: {texture.description}; {texture.width_mm:g} × {texture.height_mm:g} mm, "
          f"{texture.cols}×{texture.rows} px ({texture.authoring['px_per_mm']:g} px/mm), {texture.kind}{kept}")
    return 0


def describe(texture, spec: str, felt_under=None) -> dict:
    """What ``texture info`` prints: metadata, friction statistics and seams, JSON-ready; with ``felt_under`` (a
    model, the plate's limit in µm p-p and the force in N), what a swipe keeps of its contrast (:func:`_felt`)."""
    import numpy as np
    from ultraglide.textures.seams import measure_seams

    ratio = texture.ratio_map()
    seams = measure_seams(texture.values)
    pixel_x, pixel_y = texture.pixel_mm
    return {  # each number to what it means: lengths to the µm (pixels to the nm), ratios to 16 bits
        "texture": spec, "name": texture.name, "description": texture.description, "kind": texture.kind,
        "width_mm": _mm(texture.width_mm), "height_mm": _mm(texture.height_mm), "cols": texture.cols,
        "rows": texture.rows, "pixel_mm": [round(pixel_x, 6), round(pixel_y, 6)], "outside": texture.outside,
        "outside_ratio": _ratio(texture.outside_ratio), "ratio_range": [_ratio(v) for v in texture.ratio_range],
        "full_slope_per_mm": _readable(texture.full_slope_per_mm) if texture.kind == "gradient" else None,
        "friction": {"min": _ratio(ratio.min()), "mean": _ratio(ratio.mean()), "max": _ratio(ratio.max()),
                     "std": _ratio(np.std(ratio))},
        "seams": {"seam_max": _ratio(seams.seam_max), "interior_max": _ratio(seams.interior_max),
                  "ratio": round(float(seams.ratio), 3), "seamless": seams.seamless, "visible": seams.visible},
        "source": texture.source, "authoring": _readable(texture.authoring),
        "felt": _felt(texture, *felt_under) if felt_under is not None else None,
    }


FELT_SPEEDS_MM_S = (50.0, 100.0, 200.0)
FELT_MAX_PIXELS = 4_000_000


def _felt(texture, model, limit_um_pp: float, force_n: float) -> list[dict] | None:
    """What a finger keeps of a friction texture's contrast along a swipe at 50, 100 and 200 mm/s
    (render.planning.swipe_contrast): the model's friction dynamics (the published ones for a static model), and
    its floor within the plate's limit at that force and speed (under a speed law the floor rises with speed);
    None for a gradient texture (its friction depends on the direction of the swipe)."""
    if texture.kind != "friction" or texture.cols * texture.rows > FELT_MAX_PIXELS:
        return None  # a large map would be resampled for a lookup: not for an info line
    from ultraglide.render.physics.dynamics import FrictionDynamics
    from ultraglide.render.physics.speed_law import floor_at_speed
    from ultraglide.render.planning import swipe_contrast

    dynamics = getattr(model, "dynamics", None) or FrictionDynamics()
    felt = []
    for speed in FELT_SPEEDS_MM_S:
        floor = floor_at_speed(model, force_n, speed, limit_um_pp)
        kept = swipe_contrast(texture, dynamics, speed, floor, longest_s=0.5)
        felt.append({"speed_mm_s": speed, "floor": round(floor, 4),
                     "contrast_instantaneous": round(kept.instantaneous, 3), "contrast_planned": round(kept.planned, 3),
                     "rms_instantaneous": round(kept.instantaneous_rms, 3), "rms_planned": round(kept.planned_rms, 3)})
    return felt


def _own_dynamics(model) -> str | None:
    """Whose friction dynamics the felt figures use, where they are the model's own (fitted on the plate, or time
    constants it was given); None for the published ones (a static model, or ``dynamic`` as it comes)."""
    dynamics = getattr(model, "dynamics", None)
    if dynamics is None or (dynamics.published and not dynamics.source):
        return None
    return f"the model's own, {dynamics.source}" if dynamics.source else "the model's own, given time constants"


OUTSIDE_WORDS = {"tile": "it repeats (a tile)", "clamp": "its edges extend", "fixed": "a fixed friction ratio of {:g}"}


def info(args) -> int:
    from ultraglide.textures.fileformat import MAX_HELD_PIXELS, MAX_PX_PER_MM

    from ultraglide.inputs import shown

    if Path(args.texture).suffix.lower() in (".gltf", ".glb"):
        from ultraglide.apps.commands.texture_formats import scene_info

        return scene_info(args)
    from ultraglide.devices.profiles import load_profile
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.physics.speed_law import speed_law_of

    model = load_model(args.model)
    limit_um_pp = load_profile(args.profile).max_amplitude_um_pp
    texture = _input(args.texture)
    facts = describe(texture, args.texture, (model, limit_um_pp, args.force))
    own = _own_dynamics(model)
    if facts["felt"]:  # what the felt figures were worked out under, as the words below say it
        facts["felt_under"] = {"model": args.model, "dynamics": own or "published (Meyer et al. 2014)",
                               "profile": args.profile, "limit_um_pp": limit_um_pp, "force_n": args.force}
    if args.json:
        print_json(facts)
        return 0
    friction, seams = facts["friction"], facts["seams"]
    beyond = OUTSIDE_WORDS[texture.outside].format(texture.outside_ratio)
    lines = [
        f"{shown(texture.name)}: {shown(texture.description)}",  # the file's text: a line break would fake a line
        f"  size        {texture.width_mm:g} × {texture.height_mm:g} mm, {texture.cols} × {texture.rows} pixels "
        f"of {facts['pixel_mm'][0]:.3g} × {facts['pixel_mm'][1]:.3g} mm",
        f"  kind        {texture.kind}" + (" (friction follows the slope of a height map; figures below are for a "
                                           "left-to-right swipe)" if texture.kind == "gradient" else
                                           " (the values are friction ratios, 1 = plate at rest)"),
        f"  friction    {friction['min']:.3f} to {friction['max']:.3f}, mean {friction['mean']:.3f}, "
        f"standard deviation {friction['std']:.3f}",
        f"  beyond      {beyond}",
    ]
    if facts["felt"]:
        whose = "its own" if own else "the published"
        law = speed_law_of(model)  # the lowest friction reachable then rises with speed: said at each
        lines.append(f"  felt        of its contrast along a swipe, a finger with {whose} friction dynamics keeps "
                     f"(ours; {args.model} within {limit_um_pp:g} µm p-p at {args.force:g} N):")
        lines += [f"              {g['speed_mm_s']:5g} mm/s: {100 * g['contrast_instantaneous']:3.0f} % rendered "
                  f"instantly (error {g['rms_instantaneous']:.3f}), {100 * g['contrast_planned']:3.0f} % planned "
                  f"(error {g['rms_planned']:.3f})" + (f", lowest friction {g['floor']:.3f}" if law else "")
                  for g in facts["felt"]]
    if texture.outside == "tile":
        verdict = "seamless" if seams["seamless"] else ("a seam a finger would feel" if seams["visible"] else
                                                        "a slight seam")
        lines.append(f"  seams       {verdict}: largest step across the tile's edge {seams['seam_max']:.3f}, "
                     f"inside {seams['interior_max']:.3f}")
    if texture.source:
        lines.append(f"  source      {shown(texture.source)}")
    held_from = texture.authoring.get("held_from_pixels")
    if isinstance(held_from, list) and len(held_from) == 2:
        lines.append(f"  held as     {texture.cols} × {texture.rows} pixels, reduced from the file's {held_from[0]} × "
                     f"{held_from[1]}: at most {MAX_PX_PER_MM:g} per mm (a finger resolves about 0.05 mm) and "
                     f"{MAX_HELD_PIXELS / 1e6:g} million in all")
    made = ", ".join(f"{shown(key)} {shown(value)}" for key, value in facts["authoring"].items()
                     if key != "held_from_pixels")
    if made:
        lines.append(f"  made with   {made}")
    print("\n".join(lines))
    return 0
