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

import numpy as np
from PIL import Image
from ultraglide.textures.authoring import AuthoringOptions, ImageTooLarge, author_image, check_image
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import CHUNK, has_texture_metadata, load_texture
from ultraglide.textures.texture import Texture

LIBRARY_DIR = Path(__file__).parent / "library"


@dataclass(frozen=True)
class LibraryEntry:
    """A bundled texture, described without loading its pixels.

    Attributes
    ----------
    name : str
        The texture's name (its file's stem).
    path : pathlib.Path
        Its file.
    width_mm, height_mm : float
        Its size, mm.
    kind : str
        ``friction`` or ``gradient``.
    description : str
        One line.

    Examples
    --------
    >>> entry = next(e for e in library_entries() if e.name == "grating-1mm")
    >>> entry.path.name, entry.width_mm, entry.height_mm
    ('grating-1mm.png', 80.0, 50.0)
    """

    name: str
    path: Path
    width_mm: float
    height_mm: float
    kind: str
    description: str


def library_entries(directory: Path = LIBRARY_DIR) -> list[LibraryEntry]:
    """Every texture in the library, sorted by name, described without loading its pixels.

    Parameters
    ----------
    directory : pathlib.Path
        The library's folder (the bundled one by default).

    Returns
    -------
    list of LibraryEntry
        Each texture's name, file, size (mm), kind and description.

    Examples
    --------
    >>> entry = next(entry for entry in library_entries() if entry.name == "grating-1mm")
    >>> entry.width_mm, entry.height_mm, entry.kind
    (80.0, 50.0, 'friction')
    """
    entries = []
    for path in sorted(directory.glob("*.png")):
        with Image.open(path) as image:
            meta = json.loads(image.info.get(CHUNK, "{}"))
        entries.append(LibraryEntry(path.stem, path, float(meta.get("width_mm", 0)), float(meta.get("height_mm", 0)),
                                    meta.get("kind", "friction"), meta.get("description", "")))
    return entries


def has_metadata(path: Path) -> bool:
    """Whether ``path`` is a PNG with an ultraglide metadata chunk (a damaged chunk counts: loading it then
    says what is wrong); False for anything that is not a regular file.

    Parameters
    ----------
    path : pathlib.Path

    Returns
    -------
    bool

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide.textures.fileformat import save_texture
    >>> from ultraglide.textures.procedural import grating
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "grating.png"
    >>> _ = save_texture(grating(wavelength_mm=2.0, size_mm=(20.0, 10.0)), path)
    >>> has_metadata(path), has_metadata(path.parent)
    (True, False)
    """
    return has_texture_metadata(path)  # a damaged chunk counts: loading it then says what is wrong


def resolve_texture(spec: str, options: AuthoringOptions | None = None) -> Texture:
    """A texture from a file path or a library name.

    A texture file loads as it is; a glTF scene (``.gltf``, ``.glb``) gives its first haptic material's
    friction map (:func:`ultraglide.textures.formats.gltf.load_friction_texture`); any other image is
    authored on the fly with ``options`` (the defaults of ``ultraglide author`` unless given), with a
    warning saying so. A path that exists but is not a regular file (a directory, a named pipe, a device)
    is refused in one line, unless a library texture has that name.

    Parameters
    ----------
    spec : str
        A library name (``ultraglide textures`` lists them), a texture or image file, or a glTF scene.
    options : AuthoringOptions, optional
        How a plain image is authored.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No such texture (with the closest library names), or a file that cannot be read.

    Examples
    --------
    >>> resolve_texture("grating-1mm")
    Texture('grating-1mm', 80 × 50 mm, 800 × 500 px)
    """
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


def as_texture(texture: Texture | str | os.PathLike | np.ndarray, *, width_mm: float | None = None,
               height_mm: float | None = None, options: AuthoringOptions | None = None) -> Texture:
    """Any of the ways the API accepts a texture, as a :class:`Texture`.

    Parameters
    ----------
    texture : Texture, str, os.PathLike or numpy.ndarray
        A texture; a library name or a file (a texture file, or an image authored with ``options``, see
        :func:`resolve_texture`); or a 2-D array of friction ratios (0..1, 1 = the plate at rest), rows
        top to bottom, which needs its physical size.
    width_mm : float, optional
        An array's width (mm across its columns). Only for an array.
    height_mm : float, optional
        An array's height (mm down its rows); by default its pixels are square.
    options : AuthoringOptions, optional
        How a plain image is authored (the defaults of ``ultraglide author`` unless given).

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        In one line, what to give instead: an array without ``width_mm``, a size given with a texture that
        has its own, a value of another type, or a texture that does not resolve.

    Examples
    --------
    >>> import numpy as np
    >>> bars = np.tile([0.2, 1.0], (4, 10))          # 4 rows, 20 columns of alternate ratios
    >>> as_texture(bars, width_mm=20.0)
    Texture('array', 20 × 4 mm, 20 × 4 px)
    """
    sized = width_mm is not None or height_mm is not None
    if isinstance(texture, Texture | str | os.PathLike):
        if sized:
            raise TextureError("width_mm and height_mm size a texture given as an array; this texture has its own "
                               "size (resize a Texture with texture.with_(width_mm=..., height_mm=...))")
        return texture if isinstance(texture, Texture) else resolve_texture(os.fspath(texture), options)
    if isinstance(texture, np.ndarray) or hasattr(texture, "__array__"):
        try:
            values = np.asarray(texture, dtype=np.float32)
        except (TypeError, ValueError):
            raise TextureError(f"a texture array holds friction ratios (numbers 0..1); this one holds "
                               f"{np.asarray(texture).dtype}") from None
        if values.ndim != 2 or min(values.shape) < 1:
            raise TextureError(f"a texture array is 2-D (rows × columns of friction ratios), got shape {values.shape}")
        if width_mm is None:
            raise TextureError("a texture given as an array needs its physical size: give width_mm= (mm across its "
                               "columns), and height_mm= unless its pixels are square")
        try:
            width = float(width_mm)
            height = float(height_mm) if height_mm is not None else width * values.shape[0] / values.shape[1]
        except (TypeError, ValueError):
            raise TextureError(f"width_mm and height_mm are sizes in mm (numbers), got {width_mm!r} and "
                               f"{height_mm!r}") from None
        return Texture(values, width, height, name="array")
    raise TextureError(f"a texture is a Texture, a library name, a texture or image file, or a 2-D array of friction "
                       f"ratios (0..1) with width_mm=; got {type(texture).__name__}")
