"""``ultraglide texture import`` and ``ultraglide texture export-gltf``: haptic content in the field's formats.

``import`` reads a glTF scene's ``MPEG_haptic_material`` friction texture (or an Interhaptics ``.haps`` texture
block) into a texture file; ``export-gltf`` writes a texture as a glTF scene that any glTF tool opens.
docs/formats.md says what maps to what.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import refuse_overlaps, texture_file
from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.types import TEXTURE_SIDE_MM, UNIT_INTERVAL


def add_parser(texture_commands: argparse._SubParsersAction) -> None:
    """``ultraglide texture import`` and ``export-gltf``: their options."""
    importing = texture_commands.add_parser(
        "import", help="a texture from a glTF scene's haptic material or an Interhaptics .haps texture",
        description="Read the friction texture of a glTF 2.0 scene's MPEG_haptic_material (.gltf or .glb; its "
                    "images embedded or in files beside it) into a texture file. The texel's first channel "
                    "(0..1) is the friction ratio unless --texel-range or --invert say otherwise; the physical size "
                    "is the UV-mapped extent of the meshes wearing the material, else --width-mm. An Interhaptics "
                    ".haps file's texture block (an amplitude over distance) becomes a grating along x, its "
                    "amplitude (0..1) mapped as a texel is; its length from the file (unit 7: metres) or --width-mm.")
    importing.add_argument("scene", metavar="SCENE", help="a .gltf, .glb or .haps file")
    importing.add_argument("--material", metavar="NAME|INDEX",
                           help="the haptic material, by name or index (default: the first with a friction "
                                "texture; `ultraglide texture info SCENE` lists them)")
    importing.add_argument("--width-mm", type=TEXTURE_SIDE_MM, metavar="W",
                           help="the texture's width, mm (needed when the scene does not say; the height follows "
                                "the UV mapping's aspect, else the image's; a .haps texture's whole length spans W)")
    importing.add_argument("--texel-range", nargs=2, type=UNIT_INTERVAL, default=[0.0, 1.0], metavar=("LOW", "HIGH"),
                           help="friction ratios of a black and a white texel (default: 0 1, the texel is the ratio)")
    importing.add_argument("--invert", action="store_true",
                           help="black texels are at rest (the high ratio), white the slipperiest")
    importing.add_argument("--name", help="texture name (default: the material's)")
    output_option(importing, "-o", "--output", required=True, metavar="TEXTURE.png")
    importing.set_defaults(run=run_import)

    exporting = texture_commands.add_parser(
        "export-gltf", help="a texture as a glTF scene with a haptic material",
        description="Write TEXTURE as a glTF 2.0 scene: a quad at the texture's physical size whose "
                    "MPEG_haptic_material friction texture is the map (16-bit PNG) and whose base colour is a "
                    "preview of it. .glb (binary) or .gltf (JSON, everything embedded) by the output's extension.")
    exporting.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, a glTF scene, or a "
                                                              "library name")
    output_option(exporting, "-o", "--output", required=True, metavar="SCENE.glb|.gltf")
    exporting.set_defaults(run=run_export)


def run_import(args) -> int:
    from ultraglide.textures.fileformat import save_texture
    from ultraglide.textures.formats.gltf import is_gltf, load_friction_texture
    from ultraglide.textures.formats.mapping import TexelMapping

    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    low, high = args.texel_range
    if low > high:
        raise UsageError(f"--texel-range LOW HIGH needs LOW <= HIGH, got {low:g} {high:g}")
    refuse_overlaps({"-o": output}, {"SCENE": Path(args.scene)})
    mapping = TexelMapping(low, high, args.invert)
    if Path(args.scene).suffix.lower() == ".haps":
        return _import_haps(args, output, mapping)
    if not is_gltf(args.scene):
        raise UsageError(f"{args.scene}: texture import reads .gltf and .glb scenes and .haps files")
    texture = load_friction_texture(args.scene, args.material, args.width_mm, mapping)
    if args.name:
        texture = texture.with_(name=args.name)
    save_texture(texture, output)
    print(f"wrote {output}: {texture.name}, {texture.width_mm:g} × {texture.height_mm:g} mm, "
          f"{texture.cols}×{texture.rows} px; {mapping.describe()}")
    return 0


def _import_haps(args, output: Path, mapping) -> int:
    """``texture import FILE.haps``: the texture block as a grating along x (textures/formats/haps.py)."""
    import warnings

    from ultraglide.textures.fileformat import save_texture
    from ultraglide.textures.formats.haps import load_haps_texture

    if args.material is not None:
        raise UsageError("--material chooses a glTF scene's haptic material; a .haps file has one texture")
    texture, unrendered = load_haps_texture(args.scene, args.width_mm, mapping)
    if args.name:
        texture = texture.with_(name=args.name)
    save_texture(texture, output)
    rule = ("friction ratio = amplitude (1: the plate at rest; 0: the slipperiest)" if mapping.identity
            else mapping.describe().replace("texel", "amplitude"))
    print(f"wrote {output}: {texture.name}, a grating along x {texture.width_mm:g} mm long "
          f"({'repeating' if texture.outside == 'tile' else 'its end held beyond it'}), {texture.cols} columns; "
          f"{rule}")
    for text in unrendered:
        warnings.warn(f"{args.scene}: {text}", stacklevel=2)
    return 0


def run_export(args) -> int:
    from ultraglide.textures.formats.gltf import write_gltf
    from ultraglide.textures.library import resolve_texture

    output = Path(args.output)
    if output.suffix.lower() not in (".glb", ".gltf"):
        raise UsageError(f"the output must be a .glb or .gltf file, got {output}")
    refuse_overlaps({"-o": output}, {"TEXTURE": texture_file(args.texture)})
    texture = resolve_texture(args.texture)
    write_gltf(texture, output)
    print(f"wrote {output}: {texture.name}, a {texture.width_mm:g} × {texture.height_mm:g} mm quad whose "
          f"MPEG_haptic_material friction texture is the {texture.cols}×{texture.rows} map")
    return 0


def scene_info(args) -> int:
    """``texture info SCENE.glb``: the scene's haptic materials."""
    from ultraglide.apps.cli.output import print_json
    from ultraglide.textures.formats.gltf import describe_scene

    from ultraglide.inputs import shown

    materials = describe_scene(args.texture)
    if args.json:
        print_json({"scene": args.texture, "haptic_materials": materials})
        return 0
    lines = [f"{args.texture}: {len(materials)} haptic material{'s' if len(materials) != 1 else ''}"]
    for material in materials:
        size = material["size_mm"]
        where = f"{size[0]:g} × {size[1]:g} mm (its UV mapping)" if size else "size not known (give --width-mm)"
        friction = ("friction texture " + ", ".join(f"{t['texture']} ({t['type']})"
                                                    for t in material["friction_textures"])
                    if material["friction_textures"] else "no friction texture")
        lines.append(f"  {material['index']}. {shown(material['name']) or '(unnamed)'}: {friction}; {where}; "
                     f"properties {', '.join(material['properties']) or 'none'}")
    print("\n".join(lines))
    return 0
