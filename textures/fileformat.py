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

import json
import math
import struct
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin, UnidentifiedImageError
from ultraglide.textures import effects as effects_format
from ultraglide.textures.errors import TextureError
from ultraglide.textures.limits import MAX_PIXELS
from ultraglide.textures.texture import KINDS, OUTSIDE_RULES, Texture

from ultraglide.atomic import AtomicFile
from ultraglide.inputs import open_input, parse_json

FORMAT_VERSION = 1
CHUNK = "ultraglide"
FULL_SCALE = 65535
DEFAULT_PX_PER_MM = 10.0
# Pillow's decompression-bomb warning never reaches the terminal: our own pixel limits say what to do (a filter
# set inside catch_warnings is undone by another thread's catch_warnings; this one holds in every thread)
warnings.filterwarnings("ignore", category=Image.DecompressionBombWarning)


def quantise(values: np.ndarray) -> np.ndarray:
    """Values in 0..1 as the 16-bit integers the file stores (clipped, rounded to the nearest of 65535 steps).

    Parameters
    ----------
    values : numpy.ndarray

    Returns
    -------
    numpy.ndarray of uint16

    Examples
    --------
    >>> quantise(np.array([0.0, 0.5, 1.0, 1.2]))
    array([    0, 32768, 65535, 65535], dtype=uint16)
    """
    return np.round(np.clip(values, 0.0, 1.0) * FULL_SCALE).astype(np.uint16)


def metadata_of(texture: Texture) -> dict:
    """The texture's metadata as the file's JSON chunk holds it: the format version, kind, size (mm), outside
    rule, ratio range, slope, words and authoring (not the pixels, not the effects).

    Parameters
    ----------
    texture : Texture

    Returns
    -------
    dict

    Examples
    --------
    >>> from ultraglide.textures.procedural import grating
    >>> meta = metadata_of(grating(wavelength_mm=2.0, size_mm=(20.0, 10.0)))
    >>> meta["format_version"], meta["kind"], meta["width_mm"], meta["height_mm"]
    (1, 'friction', 20.0, 10.0)
    """
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
    """Write a texture file: a PNG of its values with its size and metadata, whole or not at all.

    Written atomically (:class:`ultraglide.atomic.AtomicFile`): a temporary file renamed into place.

    Parameters
    ----------
    texture : Texture
        The texture to write.
    path : str or pathlib.Path
        The ``.png`` file to write.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    TextureError
        A path that is not a PNG, or a texture the format cannot hold; ``OSError`` for a file that cannot be
        written (nothing is left behind).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide.textures.procedural import dots
    >>> path = save_texture(dots(size_mm=(16.0, 8.0)), pathlib.Path(tempfile.mkdtemp()) / "dots.png")
    >>> path.name, load_texture(path).height_mm
    ('dots.png', 8.0)
    """
    path = Path(path)
    image = Image.fromarray(quantise(texture.values))  # mode I;16: 16-bit grayscale PNG
    info = PngImagePlugin.PngInfo()
    info.add_itxt(CHUNK, json.dumps(metadata_of(texture), ensure_ascii=False))
    dpi = 25.4 * texture.cols / texture.width_mm
    with AtomicFile(path) as target, open(target.temporary, "wb") as stream:
        image.save(stream, format="PNG", pnginfo=info, dpi=(dpi, dpi))
    return path


GRAY_MODES = ("I;16", "I;16L", "I;16B", "I;16N", "I", "L")
READ_AS_GRAY_MODES = ("P", "PA", "1", "LA", "La")


def pillow_failure(error: BaseException) -> str:
    """What Pillow's failure to read an image means, in words (after the file's name).

    Parameters
    ----------
    error : BaseException
        What Pillow raised.

    Returns
    -------
    str

    Examples
    --------
    >>> pillow_failure(OSError("image file is truncated"))
    'cannot read it, the file is damaged or truncated (image file is truncated)'
    """
    if isinstance(error, ValueError) and "too large" in str(error).lower():  # a text chunk's limit (MAX_TEXT_CHUNK)
        return ("a text chunk in it decompresses to more than Pillow reads (a decompression bomb?); it was not "
                "read")
    return f"cannot read it, the file is damaged or truncated ({error})"


def _check_gray(image: Image.Image, path) -> None:
    """Colour is refused from the file's header, before its pixels are decoded."""
    if image.mode not in GRAY_MODES + READ_AS_GRAY_MODES:
        raise TextureError(f"{path}: a texture file must be grayscale, this one is {image.mode}; "
                           "make one with `ultraglide author`")


def _grayscale(image: Image.Image) -> Image.Image:
    """The decoded image in a grayscale mode (16-bit, 8-bit or 32-bit integers); a palette or 1-bit image is
    read through its gray levels, an alpha channel dropped; colour is refused (:func:`_check_gray`)."""
    if image.mode in READ_AS_GRAY_MODES:
        return image.convert("L")
    return image


MAX_PX_PER_MM = 20.0  # a finger resolves about 0.05 mm: a texture is held no finer than this
MAX_HELD_PIXELS = 16_000_000  # and in at most this many pixels (200 × 200 mm at 20 px/mm; 64 MB of float32)


def held_size(cols: int, rows: int, width_mm: float, height_mm: float) -> tuple[int, int]:
    """The pixels a texture of ``cols`` × ``rows`` pixels over ``width_mm`` × ``height_mm`` is held in: at most
    :data:`MAX_PX_PER_MM` per millimetre along each side, at most :data:`MAX_HELD_PIXELS` in all, at least one.

    Parameters
    ----------
    cols, rows : int
        The source's pixels.
    width_mm, height_mm : float
        The texture's size (mm).

    Returns
    -------
    (int, int)
        cols, rows.

    Examples
    --------
    >>> held_size(4000, 3000, 80.0, 60.0)                              # 20 px/mm at most
    (1600, 1200)
    >>> held_size(100, 50, 80.0, 40.0)                                 # coarser: kept as it is
    (100, 50)
    """
    held_cols = min(cols, max(1, math.ceil(width_mm * MAX_PX_PER_MM)))
    held_rows = min(rows, max(1, math.ceil(height_mm * MAX_PX_PER_MM)))
    if held_cols * held_rows > MAX_HELD_PIXELS:
        shrink = math.sqrt(MAX_HELD_PIXELS / (held_cols * held_rows))
        held_cols, held_rows = max(1, int(held_cols * shrink)), max(1, int(held_rows * shrink))
    return held_cols, held_rows


def _held_values(image: Image.Image, width_mm: float, height_mm: float, authoring: dict) -> tuple[np.ndarray, dict]:
    """The map's values (float32, 0..1) at the resolution it is held at (:func:`held_size`), averaging the
    file's pixels over each held pixel (an exact box filter); ``authoring`` notes the file's own size."""
    cols, rows = image.size
    size = held_size(cols, rows, width_mm, height_mm)
    if size != (cols, rows):
        if image.mode not in ("I;16", "L", "I"):
            image = image.convert("I")
        image = image.resize(size, Image.Resampling.BOX)
        authoring = {**authoring, "held_from_pixels": [cols, rows]}
    top = 255.0 if image.mode == "L" else float(FULL_SCALE)
    values = np.asarray(image).astype(np.float32)
    np.clip(values, 0.0, top, out=values)
    values *= np.float32(1.0 / top)
    return values, authoring


MAX_SIDE_MM = 10_000.0  # no plate is 10 m across
MIN_SIDE_MM = 0.01  # 10 µm: a fifth of what a finger resolves; smaller would make pixels vanish
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
        "width_mm": _number(meta, "width_mm", None, MIN_SIDE_MM, MAX_SIDE_MM, problems),
        "height_mm": _number(meta, "height_mm", None, MIN_SIDE_MM, MAX_SIDE_MM, problems),
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
    """Whether a file is a PNG with an ultraglide metadata chunk, readable or not (False for anything that is
    not a regular file: it is never opened).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    bool

    Examples
    --------
    >>> import os, tempfile
    >>> from ultraglide.textures.procedural import grating
    >>> path = os.path.join(tempfile.mkdtemp(), "grating.png")
    >>> _ = save_texture(grating(wavelength_mm=2.0, size_mm=(20.0, 10.0)), path)
    >>> has_texture_metadata(path), has_texture_metadata(os.path.dirname(path))
    (True, False)
    """
    try:
        with open_input(path, "texture file", TextureError) as stream:
            return _metadata_chunk_present(stream)
    except (OSError, TextureError):
        return False


def _metadata_chunk_present(stream) -> bool:
    """Whether the PNG has a text chunk with our keyword, read from the chunk headers (Pillow skips
    text chunks it cannot decode, which would turn a damaged texture file into a plain image)."""
    stream.seek(0)
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
    """Read a texture file (a PNG with the texture's metadata, as :func:`save_texture` writes it).

    A file finer than :data:`MAX_PX_PER_MM` is held at that resolution (see :func:`_held_size`); the
    texture's ``authoring`` then says so under ``held_from_pixels``.

    Parameters
    ----------
    path : str or pathlib.Path
        The texture file.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        In one line, what is wrong with the file: missing, not a texture, damaged metadata, too large.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide.textures.procedural import grating
    >>> path = save_texture(grating(2.0, size_mm=(20.0, 10.0)), pathlib.Path(tempfile.mkdtemp()) / "g.png")
    >>> load_texture(path).width_mm, load_texture(path).height_mm
    (20.0, 10.0)
    """
    path = Path(path)
    with open_input(path, "texture file", TextureError) as stream:
        image, text, dpi = _read_png(stream, path)
        chunk_present = text is not None or _metadata_chunk_present(stream)
    if text is None and chunk_present:
        raise TextureError(f"{path}: its ultraglide metadata chunk is damaged (not readable text); "
                           "make the texture again with `ultraglide author` or `ultraglide texture new`")
    if text is None:
        cols, rows = image.size
        px_per_mm = dpi[0] / 25.4 if dpi and math.isfinite(dpi[0]) and dpi[0] > 1 else DEFAULT_PX_PER_MM
        width_mm, height_mm = cols / px_per_mm, rows / px_per_mm
        if max(width_mm, height_mm) > MAX_SIDE_MM:
            raise TextureError(f"{path}: at {px_per_mm:g} pixels per mm it would be {width_mm:.6g} × "
                               f"{height_mm:.6g} mm, more than {MAX_SIDE_MM:g} mm; give it a higher DPI")
        values, authoring = _held_values(image, width_mm, height_mm, {"plain_image": True})
        warnings.warn(f"{path} has no ultraglide metadata: brightness is read as the friction ratio, "
                      f"{px_per_mm:g} pixels per mm, tiled", stacklevel=2)
        return Texture(values, width_mm, height_mm, name=path.stem, source=str(path), authoring=authoring)
    if len(text) > MAX_CHUNK_BYTES:
        raise TextureError(f"{path}: its ultraglide metadata is {len(text):,} characters, more than any texture has")
    meta = parse_json(text, f"{path}: its ultraglide metadata", TextureError, what="texture's metadata")
    if not isinstance(meta, dict):
        raise TextureError(f"{path}: its ultraglide metadata must be a JSON object")
    fields = _validated(meta, str(path))
    if fields["kind"] == "gradient" and min(image.size) < 2:
        raise TextureError(f"{path}: a gradient texture needs 2×2 pixels or more, this one is "
                           f"{image.size[0]}×{image.size[1]}")
    fields["name"] = fields["name"] if "name" in meta else path.stem
    if meta.get("effects") is not None:
        fields["effects"] = effects_format.from_json(meta["effects"], where=f"{path}: effects")
    values, fields["authoring"] = _held_values(image, fields["width_mm"], fields["height_mm"], fields["authoring"])
    return Texture(values, **fields)


def _read_png(stream, path: Path):
    """The decoded image (grayscale), its ultraglide text chunk (or None) and its DPI, from an open file."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our own limit speaks instead
            image = Image.open(stream)
        with image:
            if image.width * image.height > MAX_PIXELS:
                raise TextureError(f"{path}: {image.width}×{image.height} is {image.width * image.height:,} pixels, "
                                   f"more than a texture file may have ({MAX_PIXELS:,}); shrink the image")
            _check_gray(image, path)
            image.load()
            text = image.info.get(CHUNK)
            dpi = image.info.get("dpi")
            return _grayscale(image), text, dpi
    except TextureError:
        raise
    except UnidentifiedImageError:
        raise TextureError(f"{path}: not an image (no image format Pillow knows)") from None
    except Image.DecompressionBombError:
        raise TextureError(f"{path}: more pixels than a texture file may have ({MAX_PIXELS:,}); "
                           "shrink the image") from None
    except MemoryError:
        raise TextureError(f"{path}: too large to decode in the memory available") from None
    except (OSError, SyntaxError, ValueError, EOFError, struct.error) as error:  # Pillow's ways of saying "damaged"
        raise TextureError(f"{path}: {pillow_failure(error)}") from None
