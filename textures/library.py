"""The bundled texture library, and finding a texture by name or path.

The library is the PNG texture files in ``textures/library/``; ``scripts/build_library.py``
regenerates them (procedural ones from parameters, the rest from the source images there).
"""

from __future__ import annotations

import difflib
import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

from PIL import Image
from ultraglide.textures.authoring import AuthoringOptions, ImageTooLarge, author_image, check_image
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import CHUNK, has_texture_metadata, load_texture
from ultraglide.textures.texture import Texture

LIBRARY_DIR = Path(__file__).parent / "library"


@dataclass(frozen=True)
class LibraryEntry:
    """A bundled texture, described without loading its pixels."""

    name: str
    path: Path
    width_mm: float
    height_mm: float
    kind: str
    description: str


def library_entries(directory: Path = LIBRARY_DIR) -> list[LibraryEntry]:
    """Every texture in the library, sorted by name."""
    entries = []
    for path in sorted(directory.glob("*.png")):
        with Image.open(path) as image:
            meta = json.loads(image.info.get(CHUNK, "{}"))
        entries.append(LibraryEntry(path.stem, path, float(meta.get("width_mm", 0)), float(meta.get("height_mm", 0)),
                                    meta.get("kind", "friction"), meta.get("description", "")))
    return entries


def has_metadata(path: Path) -> bool:
    return has_texture_metadata(path)  # a damaged chunk counts: loading it then says what is wrong


def resolve_texture(spec: str, options: AuthoringOptions | None = None) -> Texture:
    """A texture from a file path or a library name.

    A texture file loads as it is; a glTF scene (``.gltf``, ``.glb``) gives its first haptic material's
    friction map (:func:`ultraglide.textures.formats.gltf.load_friction_texture`); any other image is
    authored on the fly with ``options`` (the defaults of ``ultraglide author`` unless given), with a
    warning saying so. A path that exists but is not a regular file (a directory, a named pipe, a device)
    is refused in one line, unless a library texture has that name."""
    spec = os.fspath(spec)
    path = Path(spec)
    bundled = LIBRARY_DIR / f"{spec}.png"
    library_name = "/" not in spec and bundled.is_file()
    if os.path.lexists(path) and (path.is_file() or not library_name):
        if path.suffix.lower() in (".gltf", ".glb"):
            from ultraglide.textures.formats.gltf import load_friction_texture

            return load_friction_texture(path)  # its first haptic material with a friction texture
        if has_metadata(path):
            return load_texture(path)
        check_image(path)
        warnings.warn(f"{path} is a plain image: authoring it with default options (choose them with "
                      "AuthoringOptions in Python, or make the texture with `ultraglide author`)", stacklevel=2)
        try:
            return author_image(path, options or AuthoringOptions())
        except ImageTooLarge as error:
            raise error.advising("shrink the image, or make a texture of it with `ultraglide author` and a "
                                 "larger --max-pixels") from None
    if library_name:
        return load_texture(bundled)
    names = [entry.name for entry in library_entries()]
    close = difflib.get_close_matches(spec, names, n=3, cutoff=0.6) if "/" not in spec else []
    if close:
        raise TextureError(f"no texture file or library texture named {spec!r}; did you mean "
                           + " or ".join(repr(name) for name in close) + "?")
    raise TextureError(f"no texture file or library texture named {spec!r}; library: {', '.join(names)}")
