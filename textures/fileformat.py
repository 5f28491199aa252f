"""The texture file: one PNG that any viewer opens.

The friction map is a 16-bit grayscale image (0 = ratio 0, 65535 = ratio 1; for gradient
textures, the height). The rest is JSON in an ``iTXt`` chunk named ``ultraglide``::

    {"format_version": 1, "kind": "friction", "width_mm": 80.0, "height_mm": 50.0,
     "outside": "tile", "outside_ratio": 1.0, "ratio_range": [0.4, 1.0], "full_slope_per_mm": 0.0,
     "name": "...", "description": "...", "source": "...", "authoring": {...},
     "effects": {"effects_version": 1, "bindings": [...]}}

``effects`` (present only when the texture has some) is the description of
:mod:`ultraglide.textures.effects`, validated on loading like the rest.

A PNG without that chunk (any image that is not ours) loads with documented defaults: brightness
is the friction ratio (white = 1, at rest), its DPI gives its size or else 10 pixels per
millimetre, and it tiles; a warning says so. Saving is atomic; a round trip is exact to 16 bits.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin, UnidentifiedImageError
from ultraglide.textures import effects as effects_format
from ultraglide.textures.errors import TextureError
from ultraglide.textures.texture import KINDS, OUTSIDE_RULES, Texture

FORMAT_VERSION = 1
CHUNK = "ultraglide"
FULL_SCALE = 65535
DEFAULT_PX_PER_MM = 10.0
MAX_PIXELS = 100_000_000  # textures.authoring.MAX_PIXELS_LIMIT says the same


def quantise(values: np.ndarray) -> np.ndarray:
    """Values in 0..1 as the 16-bit integers the file stores."""
    return np.round(np.clip(values, 0.0, 1.0) * FULL_SCALE).astype(np.uint16)


def metadata_of(texture: Texture) -> dict:
    meta = {
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
    if texture.effects:
        meta["effects"] = effects_format.to_json(texture.effects)
    return meta


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


MAX_SIDE_MM = 10_000.0  # no plate is 10 m across
MAX_TEXT = 10_000  # characters of a name, description or source
MAX_CHUNK_BYTES = 1 << 20  # the metadata is a few hundred bytes; Pillow refuses more than this too
TEXT_CHUNKS = (b"tEXt", b"zTXt", b"iTXt")


def _number(meta: dict, key: str, default, low: float, high: float, problems: list[str], low_open=False):
    """``meta[key]`` as a float in its range (``low`` excluded when ``low_open``), or a problem noted."""
    value = meta.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        problems.append(f"{key} must be a number, got {type(value).__name__}")
        return default
    value = float(value)
    above = value > low if low_open else value >= low
    if not (math.isfinite(value) and above and value <= high):
        bound = f"above {low:g} and at most {high:g}" if low_open else f"from {low:g} to {high:g}"
        problems.append(f"{key} must be {bound}, got {value:g}")
        return default
    return value


def _validated(meta: dict, where: str) -> dict:
    """The metadata's fields, typed and within their ranges; one :class:`TextureError` lists every problem."""
    version = meta.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or version > FORMAT_VERSION or version < 1:
        raise TextureError(f"{where}: texture format version {version!r} is not one this ultraglide reads "
                           f"(up to {FORMAT_VERSION}); upgrade ultraglide")
    problems: list[str] = []
    fields = {
        "width_mm": _number(meta, "width_mm", None, 0.0, MAX_SIDE_MM, problems, low_open=True),
        "height_mm": _number(meta, "height_mm", None, 0.0, MAX_SIDE_MM, problems, low_open=True),
        "outside_ratio": _number(meta, "outside_ratio", 1.0, 0.0, 1.0, problems),
        "full_slope_per_mm": _number(meta, "full_slope_per_mm", 0.0, 0.0, 1e9, problems),
    }
    for key, allowed, default in (("kind", KINDS, "friction"), ("outside", OUTSIDE_RULES, "tile")):
        value = meta.get(key, default)
        if not isinstance(value, str) or value not in allowed:
            problems.append(f"{key} must be one of {', '.join(allowed)}")
        fields[key] = value
    span = meta.get("ratio_range", [0.0, 1.0])
    if (isinstance(span, list) and len(span) == 2
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in span)
            and 0 <= span[0] <= span[1] <= 1):
        fields["ratio_range"] = (float(span[0]), float(span[1]))
    else:
        problems.append("ratio_range must be [low, high] with 0 <= low <= high <= 1")
    for key in ("name", "description", "source"):
        value = meta.get(key, "")
        if not isinstance(value, str) or len(value) > MAX_TEXT:
            problems.append(f"{key} must be text of {MAX_TEXT} characters at most")
        fields[key] = value
    authoring = meta.get("authoring", {})
    if not isinstance(authoring, dict):
        problems.append("authoring must be a JSON object")
    fields["authoring"] = authoring
    if problems:
        raise TextureError(f"{where}: bad texture metadata: {'; '.join(problems)}")
    return fields


def has_texture_metadata(path: str | Path) -> bool:
    """Whether a file is a PNG with an ultraglide metadata chunk, readable or not."""
    try:
        return _metadata_chunk_present(Path(path))
    except OSError:
        return False


def _metadata_chunk_present(path: Path) -> bool:
    """Whether the PNG has a text chunk with our keyword, read from the chunk headers (Pillow skips
    text chunks it cannot decode, which would turn a damaged texture file into a plain image)."""
    with open(path, "rb") as stream:
        if stream.read(8) != b"\x89PNG\r\n\x1a\n":
            return False
        while True:
            header = stream.read(8)
            if len(header) < 8:
                return False
            length, kind = int.from_bytes(header[:4], "big"), header[4:]
            if kind in TEXT_CHUNKS:
                if stream.read(min(length, len(CHUNK) + 1)) == CHUNK.encode() + b"\0":
                    return True
                stream.seek(-min(length, len(CHUNK) + 1), 1)
            if kind == b"IEND":
                return False
            stream.seek(length + 4, 1)


def load_texture(path: str | Path) -> Texture:
    """Read a texture file; :class:`TextureError` says what is wrong with a bad one."""
    path = Path(path)
    if path.is_dir():
        raise TextureError(f"{path}: is a directory, not a texture file")
    try:
        with Image.open(path) as image:
            if image.width * image.height > MAX_PIXELS:
                raise TextureError(f"{path}: {image.width}×{image.height} pixels is more than a texture may have "
                                   f"({MAX_PIXELS:,})")
            image.load()
            text = image.info.get(CHUNK)
            dpi = image.info.get("dpi")
            values = _sixteen_bit(image)
    except FileNotFoundError:
        raise TextureError(f"{path}: no such texture file") from None
    except UnidentifiedImageError:
        raise TextureError(f"{path}: not an image file") from None
    except Image.DecompressionBombError:
        raise TextureError(f"{path}: more pixels than a texture may have ({MAX_PIXELS:,})") from None
    except (OSError, SyntaxError, ValueError, EOFError) as error:  # Pillow's ways of saying "damaged"
        raise TextureError(f"{path}: cannot read it, the file is damaged or truncated ({error})") from None
    if text is None and _metadata_chunk_present(path):
        raise TextureError(f"{path}: its ultraglide metadata chunk is damaged (not readable text); "
                           "make the texture again with `ultraglide author` or `ultraglide texture new`")
    if text is None:
        rows, cols = values.shape
        px_per_mm = dpi[0] / 25.4 if dpi and math.isfinite(dpi[0]) and dpi[0] > 1 else DEFAULT_PX_PER_MM
        warnings.warn(f"{path} has no ultraglide metadata: brightness is read as the friction ratio, "
                      f"{px_per_mm:g} pixels per mm, tiled", stacklevel=2)
        return Texture(values.astype(np.float32), cols / px_per_mm, rows / px_per_mm, name=path.stem,
                       source=str(path), authoring={"plain_image": True})
    if len(text) > MAX_CHUNK_BYTES:
        raise TextureError(f"{path}: its ultraglide metadata is {len(text):,} characters, more than any texture has")
    try:
        meta = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as error:
        reason = "nested too deeply" if isinstance(error, RecursionError) else str(error)
        raise TextureError(f"{path}: its ultraglide metadata is not valid JSON ({reason})") from None
    if not isinstance(meta, dict):
        raise TextureError(f"{path}: its ultraglide metadata must be a JSON object")
    fields = _validated(meta, str(path))
    if fields["kind"] == "gradient" and min(values.shape) < 2:
        raise TextureError(f"{path}: a gradient texture needs 2×2 pixels or more, this one is "
                           f"{values.shape[1]}×{values.shape[0]}")
    fields["name"] = fields["name"] if "name" in meta else path.stem
    if meta.get("effects") is not None:
        fields["effects"] = effects_format.from_json(meta["effects"], where=f"{path}: effects")
    return Texture(values.astype(np.float32), **fields)
