"""The texture file: one PNG that any viewer opens.

The friction map is a 16-bit grayscale image (0 = ratio 0, 65535 = ratio 1; for gradient
textures, the height). The rest is JSON in an ``iTXt`` chunk named ``ultraglide``::

    {"format_version": 1, "kind": "friction", "width_mm": 80.0, "height_mm": 50.0,
     "outside": "tile", "outside_ratio": 1.0, "ratio_range": [0.4, 1.0], "full_slope_per_mm": 0.0,
     "name": "...", "description": "...", "source": "...", "authoring": {...}}

A PNG without that chunk (any image that is not ours) loads with documented defaults: brightness
is the friction ratio (white = 1, at rest), its DPI gives its size or else 10 pixels per
millimetre, and it tiles; a warning says so. Saving is atomic; a round trip is exact to 16 bits.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin, UnidentifiedImageError
from ultraglide.textures.errors import TextureError
from ultraglide.textures.texture import KINDS, OUTSIDE_RULES, Texture

FORMAT_VERSION = 1
CHUNK = "ultraglide"
FULL_SCALE = 65535
DEFAULT_PX_PER_MM = 10.0
MAX_PIXELS = 100_000_000


def quantise(values: np.ndarray) -> np.ndarray:
    """Values in 0..1 as the 16-bit integers the file stores."""
    return np.round(np.clip(values, 0.0, 1.0) * FULL_SCALE).astype(np.uint16)


def metadata_of(texture: Texture) -> dict:
    return {
        "format_version": FORMAT_VERSION,
        "kind": texture.kind,
        "width_mm": texture.width_mm,
        "height_mm": texture.height_mm,
        "outside": texture.outside,
        "outside_ratio": texture.outside_ratio,
        "ratio_range": list(texture.ratio_range),
        "full_slope_per_mm": texture.full_slope_per_mm,
        "name": texture.name,
        "description": texture.description,
        "source": texture.source,
        "authoring": texture.authoring,
    }


def save_texture(texture: Texture, path: str | Path) -> Path:
    """Write a texture file atomically; returns the path."""
    path = Path(path)
    image = Image.fromarray(quantise(texture.values))  # mode I;16: 16-bit grayscale PNG
    info = PngImagePlugin.PngInfo()
    info.add_itxt(CHUNK, json.dumps(metadata_of(texture), ensure_ascii=False))
    dpi = 25.4 * texture.cols / texture.width_mm
    directory = path.parent if str(path.parent) else Path(".")
    handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".png", dir=directory)
    try:
        with os.fdopen(handle, "wb") as stream:
            image.save(stream, format="PNG", pnginfo=info, dpi=(dpi, dpi))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, path)
    except OSError as error:  # a failed write names nothing: name the file asked for
        if error.filename is not None and error.filename != temporary:
            raise
        raise OSError(error.errno, error.strerror, str(path)) from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
    return path


def _sixteen_bit(image: Image.Image) -> np.ndarray:
    if image.mode in ("I;16", "I;16B", "I;16L", "I"):
        return np.clip(np.asarray(image, dtype=np.float64), 0, FULL_SCALE) / FULL_SCALE
    if image.mode == "L":
        return np.asarray(image, dtype=np.float64) / 255.0
    raise TextureError(f"a texture file must be grayscale, this one is {image.mode}; "
                       "make one with `ultraglide author`")


def _validated(meta: dict, where: str) -> dict:
    version = meta.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION or version < 1:
        raise TextureError(f"{where}: texture format version {version!r} is not one this ultraglide reads "
                           f"(up to {FORMAT_VERSION}); upgrade ultraglide")
    problems = []
    for key in ("width_mm", "height_mm"):
        if not isinstance(meta.get(key), int | float) or not meta[key] > 0:
            problems.append(f"{key} must be a positive number")
    if meta.get("kind", "friction") not in KINDS:
        problems.append(f"kind must be one of {', '.join(KINDS)}")
    if meta.get("outside", "tile") not in OUTSIDE_RULES:
        problems.append(f"outside must be one of {', '.join(OUTSIDE_RULES)}")
    if problems:
        raise TextureError(f"{where}: bad texture metadata: {'; '.join(problems)}")
    return meta


def load_texture(path: str | Path) -> Texture:
    """Read a texture file; :class:`TextureError` says what is wrong with a bad one."""
    path = Path(path)
    try:
        with Image.open(path) as image:
            if image.width * image.height > MAX_PIXELS:
                raise TextureError(f"{path}: {image.width}×{image.height} pixels is more than a texture may have")
            image.load()
            text = image.info.get(CHUNK)
            dpi = image.info.get("dpi")
            values = _sixteen_bit(image)
    except FileNotFoundError:
        raise TextureError(f"{path}: no such texture file") from None
    except UnidentifiedImageError:
        raise TextureError(f"{path}: not an image file") from None
    except OSError as error:
        raise TextureError(f"{path}: cannot read it ({error})") from None
    if text is None:
        rows, cols = values.shape
        px_per_mm = dpi[0] / 25.4 if dpi and dpi[0] > 1 else DEFAULT_PX_PER_MM
        warnings.warn(f"{path} has no ultraglide metadata: brightness is read as the friction ratio, "
                      f"{px_per_mm:g} pixels per mm, tiled", stacklevel=2)
        return Texture(values.astype(np.float32), cols / px_per_mm, rows / px_per_mm, name=path.stem,
                       source=str(path), authoring={"plain_image": True})
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as error:
        raise TextureError(f"{path}: its ultraglide metadata is not valid JSON ({error})") from None
    if not isinstance(meta, dict):
        raise TextureError(f"{path}: its ultraglide metadata must be a JSON object")
    meta = _validated(meta, str(path))
    try:
        return Texture(
            values.astype(np.float32), float(meta["width_mm"]), float(meta["height_mm"]),
            kind=meta.get("kind", "friction"), outside=meta.get("outside", "tile"),
            outside_ratio=float(meta.get("outside_ratio", 1.0)),
            ratio_range=tuple(meta.get("ratio_range", (0.0, 1.0))),
            full_slope_per_mm=float(meta.get("full_slope_per_mm", 0.0)),
            name=str(meta.get("name", path.stem)), description=str(meta.get("description", "")),
            source=str(meta.get("source", "")), authoring=dict(meta.get("authoring", {})),
        )
    except (TypeError, ValueError) as error:
        raise TextureError(f"{path}: bad texture metadata ({error})") from None
