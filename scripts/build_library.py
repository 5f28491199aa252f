"""Regenerate the bundled texture library in textures/library/ (run from the repository root).

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


def draw_sources() -> None:
    SOURCES.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    # wood: growth rings bent by low-frequency noise, as an RGB JPEG
    y, x = np.mgrid[0:600, 0:900].astype(float)
    warp = np.cumsum(rng.standard_normal(900)) * 0.6
    rings = 0.5 + 0.5 * np.sin((y + warp[None, :] + 30 * np.sin(x / 170)) / 9.0)
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


def main() -> None:
    LIBRARY.mkdir(exist_ok=True)
    textures = {
        "grating-0.5mm": procedural.grating(0.5),
        "grating-1mm": procedural.grating(1.0),
        "grating-2mm": procedural.grating(2.0),
        "grating-square-4mm": procedural.grating(4.0, shape="square"),
        "grating-diagonal-2mm": procedural.grating(2.0, angle_deg=45),
        "checkerboard-5mm": procedural.checkerboard(5.0),
        "dots": procedural.dots(),
        "bumps": procedural.bumps(),
        "noise-2mm": procedural.noise(2.0),
        "chirp": procedural.chirp(),
        "button": procedural.button(),
        "slider": procedural.slider(),
        "toggle": procedural.toggle(),
        "keyboard": procedural.keyboard(),
    }
    draw_sources()
    wood = author_image(SOURCES / "wood.jpg", AuthoringOptions(width_mm=90, blur_mm=0.1, invert=True))
    textures["wood"] = wood.with_(description="wood grain from a photo-like JPEG: dark rings sticky")
    fabric = author_image(SOURCES / "fabric.png", AuthoringOptions(width_mm=40, gamma=0.8))
    textures["fabric"] = fabric.with_(description="woven twill from a 16-bit PNG")
    icons = author_image(SOURCES / "icons.png",
                         AuthoringOptions(width_mm=80, mode="edges", blur_mm=0.3, outside="fixed"))
    textures["icons-edges"] = icons.with_(description="outlines of a circle, a frame, a triangle and a line")
    for name, texture in textures.items():
        save_texture(texture.with_(name=name, source=texture.source.replace(str(LIBRARY) + "/", "")),
                     LIBRARY / f"{name}.png")
        print(f"{name:24} {texture.width_mm:6.1f} × {texture.height_mm:5.1f} mm  {texture.description}")


if __name__ == "__main__":
    main()
