"""Regenerate the bundled texture library in textures/library/, its thumbnails in docs/textures/ and
the page docs/textures.md (run from the repository root).

    .venv/bin/python scripts/build_library.py

Source images for the authored textures are drawn here too (numpy only, seeded), so every file
in the library can be rebuilt from this script.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw
from ultraglide.textures import procedural
from ultraglide.textures.authoring import AuthoringOptions, author_image
from ultraglide.textures.fileformat import save_texture

LIBRARY = Path("textures/library")
SOURCES = LIBRARY / "sources"
DOCS = Path("docs/textures.md")
THUMBS = Path("docs/textures")
THUMB_PX = (160, 100)


def draw_sources() -> None:
    SOURCES.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    # wood: growth rings bent by smooth warps, as an RGB JPEG. Drawn as a tile: 11 rings down its height and
    # each warp a whole number of periods across its width, so it repeats without a seam and needs no
    # cross-fade (which blended unrelated rings into a smeared band, and a random-walk warp left kinks)
    y, x = np.mgrid[0:600, 0:900].astype(float)
    phases = rng.standard_normal(900)[:4]  # 900 drawn, as the random walk did: the sources after it are unchanged
    warp = sum(amplitude * np.sin(2 * np.pi * periods * x / 900 + phase)
               for (periods, amplitude), phase in zip(((1, 30.0), (2, 9.0), (5, 3.0), (11, 1.2)), phases, strict=True))
    spacing = 7.0 * np.sin(2 * np.pi * 3 * y / 600 + 0.7)  # rings closer and wider apart, as years differ
    rings = 0.5 + 0.5 * np.sin(2 * np.pi * 11 * (y + warp + spacing) / 600)
    grain = rings ** 3 * 0.7 + 0.3 * rng.random((600, 900)) * rings
    wood = np.stack([150 + 80 * grain, 95 + 60 * grain, 50 + 35 * grain], axis=-1)
    Image.fromarray(wood.clip(0, 255).astype(np.uint8)).save(SOURCES / "wood.jpg", quality=90)
    # fabric: a woven twill, 16-bit grayscale PNG
    y, x = np.mgrid[0:512, 0:768].astype(float)
    warp_threads = np.sin(2 * np.pi * x / 12) ** 2
    weft_threads = np.sin(2 * np.pi * y / 12) ** 2
    over = ((np.floor(x / 12) + np.floor(y / 12)) % 3) == 0
    fabric = np.where(over, warp_threads, weft_threads) * 0.8 + 0.2 * rng.random((512, 768))
    Image.fromarray((fabric / fabric.max() * 65535).astype(np.uint16)).save(SOURCES / "fabric.png")
    # icons: shapes with transparency, an RGBA PNG
    icons = Image.new("RGBA", (800, 500), (0, 0, 0, 0))
    draw = ImageDraw.Draw(icons)
    draw.ellipse((60, 80, 300, 320), fill=(30, 30, 30, 255))
    draw.rectangle((360, 100, 560, 300), outline=(0, 0, 0, 255), width=18)
    draw.polygon([(620, 320), (700, 90), (780, 320)], fill=(80, 80, 200, 255))
    draw.line((60, 420, 760, 420), fill=(0, 0, 0, 255), width=14)
    icons.save(SOURCES / "icons.png")


def library_textures() -> dict:
    """Every bundled texture by name, built from parameters or authored from the drawn sources."""
    textures = {
        "grating-0.5mm": procedural.grating(0.5),
        "grating-1mm": procedural.grating(1.0),
        "grating-2mm": procedural.grating(2.0),
        "grating-4mm": procedural.grating(4.0),
        "grating-diagonal-2mm": procedural.grating(2.0, angle_deg=45),
        "grating-square-1mm": procedural.grating(1.0, shape="square"),
        "grating-square-4mm": procedural.grating(4.0, shape="square"),
        "grating-square-2mm-duty25": procedural.grating(2.0, shape="square", duty=0.25),
        "grating-square-2mm-duty75": procedural.grating(2.0, shape="square", duty=0.75),
        "checkerboard-2mm": procedural.checkerboard(2.0, size_mm=(80, 48)),
        "checkerboard-5mm": procedural.checkerboard(5.0),
        "dots": procedural.dots(size_mm=(80, 48)),
        "dots-fine": procedural.dots(pitch_mm=1.5, diameter_mm=0.6, size_mm=(60, 30)),
        "bumps": procedural.bumps(),
        "noise-2mm": procedural.noise(2.0),
        "fractal-h0.3": procedural.fractal(0.3, px_per_mm=8, seed=1),
        "fractal-h0.8": procedural.fractal(0.8, px_per_mm=8, seed=1),
        "gabor-2mm": procedural.gabor(2.0),
        "bump": procedural.bump(),
        "edge": procedural.edge(),
        "lines": procedural.lines(px_per_mm=16),
        "chirp": procedural.chirp(),
        "button": procedural.button(),
        "slider": procedural.slider(),
        "toggle": procedural.toggle(),
        "keyboard": procedural.keyboard(),
    }
    wood = author_image(SOURCES / "wood.jpg", AuthoringOptions(width_mm=90, blur_mm=0.1, invert=True,
                                                                  auto_levels=1.0))
    textures["wood"] = wood.with_(description="wood grain from a photo-like JPEG drawn as a tile: dark rings "
                                              "sticky")
    fabric = author_image(SOURCES / "fabric.png", AuthoringOptions(width_mm=40, gamma=0.8, seamless="crossfade",
                                                                     auto_levels=1.0))
    textures["fabric"] = fabric.with_(description="woven twill from a 16-bit PNG, cross-faded into a seamless tile")
    icons = author_image(SOURCES / "icons.png",
                         AuthoringOptions(width_mm=80, mode="edges", blur_mm=0.3, outside="fixed"))
    textures["icons-edges"] = icons.with_(description="outlines of a circle, a frame, a triangle and a line")
    return dict(sorted(textures.items()))


def thumbnail(texture, path: Path) -> None:
    """A small grayscale picture for the docs: friction ratio (or height) 0 black to 1 white, at most
    THUMB_PX wide and tall, 16 gray levels so that it stays a few kB."""
    values = texture.values if texture.kind == "gradient" else texture.ratio_map()
    image = Image.fromarray(np.round(np.asarray(values) * 255).astype(np.uint8))
    scale = min(THUMB_PX[0] / image.width, THUMB_PX[1] / image.height)
    size = (max(1, round(image.width * scale)), max(1, round(image.height * scale)))
    small = image.resize(size, Image.Resampling.BOX if scale < 1 else Image.Resampling.NEAREST)
    indices = np.round(np.asarray(small) / 17.0).astype(np.uint8)  # 16 levels, 0 and 255 kept
    paletted = Image.fromarray(indices, mode="P")
    paletted.putpalette([17 * (i // 3) for i in range(48)])
    paletted.save(path, optimize=True, bits=4)


def write_docs(textures: dict) -> None:
    """docs/textures.md: a table of the library with thumbnails."""
    THUMBS.mkdir(parents=True, exist_ok=True)
    for stale in THUMBS.glob("*.png"):
        stale.unlink()
    lines = [
        "# The bundled textures",
        "",
        "Every texture that ships with ultraglide; use its name wherever a texture file is accepted",
        "(`ultraglide export grating-1mm ...`, `ultraglide texture show wood -o wood.pdf`). `ultraglide textures`",
        "lists them. Thumbnails show the friction ratio from 0 (black, slippery) to 1 (white, at rest);",
        "for gradient textures, the height (white high), felt through its slope. Textures that repeat are",
        "seamless tiles (see [design.md](design.md#seamless-tiles)). Regenerate the library, these",
        "thumbnails and this page with `.venv/bin/python scripts/build_library.py`.",
        "",
        "| | name | size (mm) | kind | beyond the edges | description |",
        "|---|---|---|---|---|---|",
    ]
    beyond = {"tile": "repeats", "clamp": "edges extend", "fixed": "its ground"}
    for name, texture in textures.items():
        thumbnail(texture, THUMBS / f"{name}.png")
        lines.append(f"| ![{name}](textures/{name}.png) | `{name}` | {texture.width_mm:g} × {texture.height_mm:g} "
                     f"| {texture.kind} | {beyond[texture.outside]} | {texture.description} |")
    DOCS.write_text("\n".join(lines) + "\n")


def main() -> None:
    LIBRARY.mkdir(exist_ok=True)
    draw_sources()
    textures = library_textures()
    for stale in LIBRARY.glob("*.png"):
        if stale.stem not in textures:
            stale.unlink()
    for name, texture in textures.items():
        texture = texture.with_(name=name, source=texture.source.replace(str(LIBRARY) + "/", ""))
        textures[name] = texture
        save_texture(texture, LIBRARY / f"{name}.png")
        print(f"{name:26} {texture.width_mm:6.1f} × {texture.height_mm:5.1f} mm  {texture.description}")
    write_docs(textures)
    print(f"wrote {DOCS} and {len(textures)} thumbnails in {THUMBS}")


if __name__ == "__main__":
    main()
