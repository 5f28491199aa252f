"""``ultraglide texture effects``: list the temporal effects a texture file keeps, or attach, add or remove them.

Effects are a versioned JSON description (``docs/effects.md``, :mod:`ultraglide.textures.effects`); the texture
file keeps them in its metadata, and ``export``, ``play`` and the demo play them with it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import refuse_overlaps
from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.output import print_json


def add_parser(texture_commands: argparse._SubParsersAction) -> None:
    """``ultraglide texture effects``: its options."""
    parser = texture_commands.add_parser(
        "effects", help="list a texture's temporal effects, or attach, add or remove them",
        description="Without --set, --add or --clear: list the temporal effects TEXTURE keeps. With one of them: "
                    "write the texture with those effects to -o (the same file may be given: it is replaced "
                    "whole, atomically). Effects are a JSON description (docs/effects.md).")
    parser.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, or a library name")
    change = parser.add_mutually_exclusive_group()
    change.add_argument("--set", metavar="EFFECTS", help="these effects instead of the texture's own: a .json "
                                                         "description, or an .ahap, .haptic, .hjif or .haps file")
    change.add_argument("--add", metavar="EFFECTS", help="these effects after the texture's own (the same files)")
    change.add_argument("--clear", action="store_true", help="no effects")
    output_option(parser, "-o", "--output", metavar="TEXTURE.png", help="the texture with its new effects")
    parser.add_argument("--json", action="store_true", help="print the effects' JSON description (to list them)")
    parser.set_defaults(run=run, output_may_replace="texture")  # -o TEXTURE: in place, as documented


def run(args) -> int:
    from ultraglide.textures import effects as format_
    from ultraglide.textures.library import resolve_texture

    changing = bool(args.set or args.add or args.clear)
    if changing and not args.output:
        raise UsageError("give -o TEXTURE.png: the texture with its new effects is written there")
    if not changing and args.output:
        raise UsageError("-o writes the texture with new effects: give --set, --add or --clear")
    output = Path(args.output) if args.output else None
    if output is not None and output.suffix.lower() != ".png":
        raise UsageError(f"the output must be a .png texture file, got {output}")
    # -o may be TEXTURE itself (loaded whole before it is replaced, atomically), never the effects file read
    refuse_overlaps({"-o": output}, {"--set" if args.set else "--add": args.set or args.add})
    given = format_.load_effects(args.set or args.add) if (args.set or args.add) else ()
    texture = resolve_texture(args.texture)
    if not changing:
        if args.json:
            print_json(format_.to_json(texture.effects))
        else:
            print(effects_words(texture.name, texture.effects))
        return 0
    from ultraglide.textures.fileformat import save_texture

    bindings = format_.combined(texture.effects, given) if args.add else given
    save_texture(texture.with_(effects=bindings), output)
    print(f"wrote {output}: " + effects_words(texture.name, bindings).splitlines()[0])
    return 0


def effects_words(name: str, bindings) -> str:
    """``name``'s effects for people: how many, then one line each (its label, what starts it, where)."""
    if not bindings:
        return f"{name}: no temporal effects"
    lines = [f"{name}: {len(bindings)} temporal effect{'s' if len(bindings) != 1 else ''}"]
    for k, binding in enumerate(bindings, 1):
        lines.append(f"  {k}. {binding.label or type(binding.effect).__name__.lower()}: {trigger_words(binding)}")
    return "\n".join(lines)


def trigger_words(binding) -> str:
    t = binding.trigger
    when = {"start": "when the finger lands or slides in", "end": "when the finger lifts or leaves",
            "while": "while the finger is down" + (f" and moving at {t.min_speed_mm_s:g} mm/s or more"
                                                    if t.min_speed_mm_s else ""),
            "cross": f"each time the finger crosses {t.axis} = " + ", ".join(f"{v:g}" for v in t.lines_mm) + " mm",
            "event": f"on the app's event {t.name!r}"}[t.on]
    if t.region_mm is None:
        return when + " anywhere"
    x, y, w, h = t.region_mm
    return when + f" in {w:g} × {h:g} mm at ({x:g}, {y:g})"
