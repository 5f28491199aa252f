"""Textures from images: any image Pillow reads becomes a friction map.

The pipeline, in order: read (first frame; EXIF rotation applied; alpha composited on
``background``, white by default, so transparent parts read as "at rest"), luminance
(ITU-R 601: 0.299 R + 0.587 G + 0.114 B, 16-bit kept at 16 bits), crop (pixels), seamless
(optional: cross-fade or mirror into a tile, :mod:`textures.seams`), blur (Gaussian, ``blur_mm``
is its sigma; across the seam for a seamless tile), mapping (``brightness``: the luminance;
``edges``: the Sobel edge strength, normalised; ``gradient``: the luminance as a height map, felt
through its slope), levels (black and white points, or ``auto_levels``: the percentiles that clip
that percentage at each end), gamma (v ** (1/gamma)), invert, and finally the friction
range: v = 0 gives ``ratio_range[0]`` (slippery), v = 1 gives ``ratio_range[1]`` (sticky).
So by default white is sticky (at rest) and black is slippery. A texture that tiles but has a
seam a finger would feel gets a warning.

Its size is ``width_mm`` (default 80 mm, a typical plate) or follows from ``dpi``.
"""

from __future__ import annotations

import contextlib
import struct
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import held_size, pillow_failure
from ultraglide.textures.limits import MAX_PIXELS
from ultraglide.textures.seams import DEFAULT_BAND, METHODS, make_seamless, measure_seams
from ultraglide.textures.texture import Texture

from ultraglide.inputs import open_input

MODES = ("brightness", "edges", "gradient")
DEFAULT_WIDTH_MM = 80.0
DEFAULT_MAX_PIXELS = 40_000_000
MAX_SIDE_MM = 10_000.0  # what a texture file may measure


@dataclass(frozen=True)
class AuthoringOptions:
    """How an image becomes a texture; see the module docstring for the order of the steps.

    Parameters
    ----------
    width_mm : float, optional
        The texture's width (mm); 80 mm when neither it nor ``dpi`` is given.
    dpi : float, optional
        The image's dots per inch, which set its width instead (not with ``width_mm``).
    mode : {"brightness", "edges", "gradient"}
        What of the image becomes friction: its luminance, its edges, or its luminance as heights.
    invert : bool
        Swap sticky and slippery.
    black, white : float
        Levels: the luminances (0..1) taken as 0 and 1, 0 <= black < white <= 1.
    gamma : float
        v ** (1 / gamma), > 0.
    blur_mm : float
        A Gaussian blur's sigma (mm), >= 0.
    ratio_range : (float, float)
        The friction ratios v = 0 and v = 1 become, low to high, in 0..1.
    crop : (int, int, int, int), optional
        x, y, width, height in the source's pixels.
    background : (int, int, int)
        The RGB a transparent part is composited on.
    max_pixels : int
        The most pixels an image may have.
    outside : {"tile", "clamp", "fixed"}
        The texture's rule beyond its edges.
    seamless : {"crossfade", "mirror"}, optional
        Make the image tile without a seam.
    seam_band : float
        The cross-fade band, a fraction of each side.
    auto_levels : float, optional
        Percent of pixels clipped at each end by a percentile stretch (instead of ``black`` and ``white``).

    Raises
    ------
    TextureError
        An option out of range, or both ``width_mm`` and ``dpi``, in one line.

    Examples
    --------
    >>> AuthoringOptions(width_mm=40.0).ratio_range                       # black slippery, white at rest
    (0.4, 1.0)
    >>> AuthoringOptions(width_mm=40.0, dpi=300.0)
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: give --width-mm or --dpi, not both
    """

    width_mm: float | None = None
    dpi: float | None = None
    mode: str = "brightness"
    invert: bool = False
    black: float = 0.0
    white: float = 1.0
    gamma: float = 1.0
    blur_mm: float = 0.0
    ratio_range: tuple[float, float] = (0.4, 1.0)
    crop: tuple[int, int, int, int] | None = None  # x, y, width, height in source pixels
    background: tuple[int, int, int] = (255, 255, 255)
    max_pixels: int = DEFAULT_MAX_PIXELS
    outside: str = "tile"
    seamless: str | None = None  # "crossfade" or "mirror": make the image tile (textures.seams)
    seam_band: float = DEFAULT_BAND  # crossfade: the blended band, a fraction of each side
    auto_levels: float | None = None  # percent of pixels clipped at each end by a percentile stretch

    def __post_init__(self) -> None:
        if self.width_mm is not None and self.dpi is not None:
            raise TextureError("give --width-mm or --dpi, not both")
        for name in ("width_mm", "dpi"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise TextureError(f"{name.replace('_', '-')} must be a positive number, got {value}")
        if self.mode not in MODES:
            raise TextureError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        low, high = self.ratio_range
        if not (0 <= low <= 1 and 0 <= high <= 1):
            raise TextureError(f"the friction range must lie within 0..1, got {low} {high}")
        if low > high:
            raise TextureError(f"the friction range must go from low to high, got {low} {high}")
        if not 0 <= self.black < self.white <= 1:
            raise TextureError(f"levels need 0 <= black < white <= 1, got {self.black} {self.white}")
        if not (np.isfinite(self.gamma) and self.gamma > 0):
            raise TextureError(f"gamma must be greater than 0, got {self.gamma}")
        if not (np.isfinite(self.blur_mm) and self.blur_mm >= 0):
            raise TextureError(f"blur must be 0 mm or more, got {self.blur_mm}")
        if self.crop is not None and (len(self.crop) != 4 or min(self.crop[2:]) <= 0 or min(self.crop[:2]) < 0):
            raise TextureError("crop is X,Y,WIDTH,HEIGHT in pixels, with a positive width and height")
        if not 0 < self.max_pixels <= MAX_PIXELS:
            raise TextureError(f"the pixel limit must be 1 to {MAX_PIXELS:,} (the texture file's own limit), "
                               f"got {self.max_pixels}")
        self._check_seamless_and_auto_levels()

    def _check_seamless_and_auto_levels(self) -> None:
        if self.seamless is not None and self.seamless not in METHODS:
            raise TextureError(f"--seamless must be one of {', '.join(METHODS)}, got {self.seamless!r}")
        if not (np.isfinite(self.seam_band) and 0 < self.seam_band <= 0.5):
            raise TextureError(f"--seam-band is a fraction of the side in (0, 0.5], got {self.seam_band}")
        if self.auto_levels is not None and not (np.isfinite(self.auto_levels) and 0 <= self.auto_levels < 50):
            raise TextureError(f"--auto-levels clips a percentage in [0, 50) at each end, got {self.auto_levels}")
        if self.auto_levels is not None and (self.black, self.white) != (0.0, 1.0):
            raise TextureError("give --levels or --auto-levels, not both")


class ImageTooLarge(TextureError):
    """An image with more pixels than the limit allows (``AuthoringOptions.max_pixels``).

    Parameters
    ----------
    path : str or path-like
        The image.
    size : (int, int)
        Its width and height, pixels.
    limit : int
        The most pixels allowed.
    advice : str
        What to do, in words.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from PIL import Image
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "wide.png"
    >>> Image.new("L", (20, 10)).save(path)
    >>> read_image_luminance(path, AuthoringOptions(max_pixels=100))
    Traceback (most recent call last):
    ...
    ultraglide.textures.authoring.ImageTooLarge: .../wide.png: 20×10 is 200 pixels, over the limit of 100; shrink ...
    """

    def __init__(self, path, size: tuple[int, int], limit: int,
                 advice: str = "shrink the image, or give a larger max_pixels"):
        self.path, self.size, self.limit = path, size, limit
        super().__init__(f"{path}: {size[0]}×{size[1]} is {size[0] * size[1]:,} pixels, over the limit of "
                         f"{limit:,}; {advice}")

    def advising(self, advice: str) -> ImageTooLarge:
        """The same refusal with other advice (what the caller's own options can do).

        Parameters
        ----------
        advice : str
            What to do, in words.

        Returns
        -------
        ImageTooLarge

        Examples
        --------
        >>> error = ImageTooLarge("wide.png", (20, 10), 100).advising("give --max-pixels 200")
        >>> str(error)
        'wide.png: 20×10 is 200 pixels, over the limit of 100; give --max-pixels 200'
        """
        return ImageTooLarge(self.path, self.size, self.limit, advice)


_ROWS_PER_CHUNK_PIXELS = 1 << 20  # luminance is computed a million pixels at a time: float arrays stay small


def _luminance(image: Image.Image, background) -> np.ndarray:
    """Luminance in 0..1 (float32) of an image of any mode (frame already chosen and rotated)."""
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        values = np.asarray(image).astype(np.float32)
        return np.clip(values, 0, 65535, out=values) / np.float32(65535.0)
    if mode == "F":
        values = np.nan_to_num(np.asarray(image, dtype=np.float32))
        top = values.max()
        return np.clip(values / top if top > 1 else values, 0, 1)
    if mode in ("1", "L"):
        return np.asarray(image.convert("L")).astype(np.float32) / np.float32(255.0)
    has_alpha = mode in ("LA", "La", "PA", "RGBA", "RGBa") or "transparency" in image.info
    if has_alpha:
        rgba = image.convert("RGBA")
        ground = Image.new("RGBA", rgba.size, tuple(background) + (255,))
        rgb = Image.alpha_composite(ground, rgba).convert("RGB")
    else:
        rgb = image.convert("RGB")
    pixels = np.asarray(rgb)
    luminance = np.empty(pixels.shape[:2], dtype=np.float32)
    weights = np.array([0.299, 0.587, 0.114], dtype=np.float32) / np.float32(255.0)
    step = max(1, _ROWS_PER_CHUNK_PIXELS // max(1, pixels.shape[1]))
    for row in range(0, pixels.shape[0], step):
        luminance[row:row + step] = pixels[row:row + step].astype(np.float32) @ weights
    return np.clip(luminance, 0, 1, out=luminance)


def physical_width_mm(cols: int, options: AuthoringOptions) -> float:
    """The width (mm) an image ``cols`` pixels wide (after cropping) is given by ``options``.

    Parameters
    ----------
    cols : int
        The image's width (pixels).
    options : AuthoringOptions
        Its ``dpi`` (width = cols / dpi × 25.4 mm) or else its ``width_mm`` (80 mm when neither is given).

    Returns
    -------
    float

    Examples
    --------
    >>> physical_width_mm(600, AuthoringOptions(dpi=300.0))               # 2 inches, mm
    50.8
    >>> physical_width_mm(600, AuthoringOptions(width_mm=40.0))
    40.0
    """
    if options.dpi is not None:
        return cols / options.dpi * 25.4
    return options.width_mm or DEFAULT_WIDTH_MM


def _for_resizing(image: Image.Image) -> Image.Image:
    """The image in a mode Pillow's box filter averages (alpha premultiplied, 16 bits kept)."""
    if image.mode in ("I;16", "I", "F", "L", "RGB", "RGBA"):
        return image
    if image.mode.startswith("I;16"):
        return image.convert("I")
    has_alpha = image.mode in ("LA", "La", "PA", "RGBa") or "transparency" in image.info
    return image.convert("RGBA" if has_alpha else ("L" if image.mode == "1" else "RGB"))


def _held(image: Image.Image, width_mm: float, file_size: tuple[int, int], info: dict) -> Image.Image:
    """The image reduced (exact box filter) to the resolution a texture ``width_mm`` wide is held at
    (:func:`held_size`: at most 20 pixels per mm and 16 M pixels); ``info`` notes the file's pixels
    (``held_from_pixels``) when the texture has fewer."""
    cols, rows = image.size
    size = held_size(cols, rows, width_mm, width_mm * rows / cols)
    if size != tuple(file_size):
        info["held_from_pixels"] = list(file_size)
    if size == (cols, rows):
        return image
    return _for_resizing(image).resize(size, Image.Resampling.BOX)


@contextlib.contextmanager
def _reading_image(path: Path):
    """Pillow's ways of failing, as one-line TextureErrors naming ``path``; Pillow's own pixel limit and its
    decompression-bomb warning are off inside (our limits say what to do)."""
    previous_limit = Image.MAX_IMAGE_PIXELS
    Image.MAX_IMAGE_PIXELS = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            yield
    except TextureError:
        raise
    except UnidentifiedImageError:
        raise TextureError(f"{path}: not an image (no image format Pillow knows)") from None
    except MemoryError:
        raise TextureError(f"{path}: too large to decode in the memory available") from None
    except (OSError, SyntaxError, ValueError, EOFError, struct.error) as error:
        raise TextureError(f"{path}: {pillow_failure(error)}") from None
    finally:
        Image.MAX_IMAGE_PIXELS = previous_limit


def read_image_luminance(path: str | Path, options: AuthoringOptions = AuthoringOptions()) -> tuple[np.ndarray, dict]:
    """Luminance (0..1, rows × cols, float32) of an image file, and facts about the source.

    The image is cropped here (``options.crop``, in the source's pixels after EXIF rotation) and reduced to the
    resolution a texture is held at (:func:`ultraglide.textures.fileformat.held_size`, given the physical
    size the options make it); ``info`` says so (``cropped``, ``held_from_pixels``). A JPEG is decoded at the
    reduced size directly (Pillow's ``draft``).

    Parameters
    ----------
    path : str or pathlib.Path
        An image file Pillow reads.
    options : AuthoringOptions
        The crop and the physical size (which set the resolution it is held at).

    Returns
    -------
    (numpy.ndarray, dict)
        The luminance, and ``info``: the source's mode, size, frames and format, and what was done.

    Raises
    ------
    TextureError
        Not an image, damaged, or too many pixels, in one line.

    Examples
    --------
    >>> import numpy as np, pathlib, tempfile
    >>> from PIL import Image
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "checks.png"
    >>> Image.fromarray(np.array([[0, 255], [255, 0]], dtype=np.uint8)).save(path)
    >>> luminance, info = read_image_luminance(path, AuthoringOptions(width_mm=20.0))
    >>> luminance.tolist(), info["format"], info["source_size"]
    ([[0.0, 1.0], [1.0, 0.0]], 'PNG', [2, 2])
    """
    path = Path(path)
    with _reading_image(path), open_input(path, "image file", TextureError) as stream:
        image = Image.open(stream)
        if image.width * image.height > options.max_pixels:
            raise ImageTooLarge(path, image.size, options.max_pixels)
        frames = getattr(image, "n_frames", 1)
        if frames > 1:
            warnings.warn(f"{path} is animated ({frames} frames); using the first", stacklevel=2)
            image.seek(0)
        turned = _quarter_turned(image)
        source = image.size[::-1] if turned else image.size
        info = {"source_mode": image.mode, "source_size": list(source), "frames": frames,
                "format": image.format or ""}
        file_size = tuple(options.crop[2:]) if options.crop is not None else source
        width_mm = physical_width_mm(file_size[0], options)
        if options.crop is None:
            _draft(image, width_mm, source, turned)
        image.load()
        ImageOps.exif_transpose(image, in_place=True)  # no copy of a large image
        image = _cropped(image, options, info)
        image = _held(image, width_mm, file_size, info)
        luminance = _luminance(image, options.background)
    return luminance, info


def check_image(path: str | Path) -> None:
    """:class:`TextureError` unless ``path`` is a regular file in an image format Pillow reads (only its
    header is read).

    Parameters
    ----------
    path : str or pathlib.Path

    Raises
    ------
    TextureError
        No such file, not a regular file, or not an image Pillow knows, in one line.

    Examples
    --------
    >>> import os, tempfile
    >>> path = os.path.join(tempfile.mkdtemp(), "notes.txt")
    >>> with open(path, "w") as file:
    ...     _ = file.write("hello")
    >>> check_image(path)                                              # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: .../notes.txt: not an image (no image format Pillow knows)
    """
    with _reading_image(Path(path)), open_input(path, "image file", TextureError) as stream:
        Image.open(stream).close()


def _quarter_turned(image: Image.Image) -> bool:
    """Whether the image's EXIF orientation turns it a quarter (its width and height swap when applied)."""
    try:
        return image.getexif().get(0x0112, 1) in (5, 6, 7, 8)
    except (OSError, ValueError, SyntaxError, struct.error):
        return False


def _draft(image: Image.Image, width_mm: float, source: tuple[int, int], turned: bool) -> None:
    """Let a JPEG decode at 1/2, 1/4 or 1/8 of its size when the texture is held smaller than that anyway."""
    if image.format != "JPEG":
        return
    wide, high = source
    held = held_size(wide, high, width_mm, width_mm * high / wide)
    if held != (wide, high):
        image.draft(image.mode, held[::-1] if turned else held)


def _cropped(image: Image.Image, options: AuthoringOptions, info: dict) -> Image.Image:
    """``options.crop`` of the image (pixels), or the image; a crop reaching outside is refused."""
    if options.crop is None:
        return image
    x, y, w, h = options.crop
    cols, rows = image.size
    if x + w > cols or y + h > rows:
        raise TextureError(f"crop {x},{y},{w},{h} reaches outside the {cols}×{rows} image")
    info["cropped"] = [x, y, w, h]
    return image.crop((x, y, x + w, y + h))


def _edges(values: np.ndarray, mode: str = "nearest") -> np.ndarray:
    from scipy import ndimage  # here, as below: the library (and so every command) imports this module

    strength = np.hypot(ndimage.sobel(values, axis=1, mode=mode), ndimage.sobel(values, axis=0, mode=mode))
    top = strength.max()
    return strength / top if top > 0 else strength


def texture_from_luminance(luminance: np.ndarray, options: AuthoringOptions, name: str = "",
                           source: str = "", info: dict | None = None) -> Texture:
    """Apply crop (unless :func:`read_image_luminance` did), blur, mapping, levels, gamma, invert and range to a
    luminance map.

    Parameters
    ----------
    luminance : numpy.ndarray, shape (rows, cols)
        Luminance in 0..1.
    options : AuthoringOptions
        The size (mm), the mapping and the friction range.
    name, source : str
        The texture's name and where it came from.
    info : dict, optional
        Facts from :func:`read_image_luminance`, kept in the texture's ``authoring``.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        An option out of range, in one line.

    Examples
    --------
    >>> import numpy as np
    >>> luminance = np.array([[0.0, 1.0]], dtype=np.float32)
    >>> texture = texture_from_luminance(luminance, AuthoringOptions(width_mm=40.0, ratio_range=(0.4, 1.0)))
    >>> texture.width_mm, texture.values.astype(float).round(3).tolist()     # dark slippery, light sticky
    (40.0, [[0.4, 1.0]])
    """
    values = luminance
    if options.crop is not None and "cropped" not in (info or {}):  # not yet cropped by read_image_luminance
        x, y, w, h = options.crop
        rows, cols = values.shape
        if x + w > cols or y + h > rows:
            raise TextureError(f"crop {x},{y},{w},{h} reaches outside the {cols}×{rows} image")
        values = values[y:y + h, x:x + w]
    rows, cols = values.shape
    file_cols = (info or {}).get("held_from_pixels", [cols])[0]  # the dpi counts the file's pixels
    width_mm = physical_width_mm(file_cols, options)
    values, width_mm = _seamless_step(values, width_mm, options)
    rows, cols = values.shape
    height_mm = width_mm * rows / cols
    if max(width_mm, height_mm) > MAX_SIDE_MM:
        raise TextureError(f"the texture would be {width_mm:.6g} × {height_mm:.6g} mm, more than {MAX_SIDE_MM:g} mm; "
                           "give a larger --dpi or a --width-mm")
    if options.mode == "gradient" and min(rows, cols) < 2:
        raise TextureError(f"gradient mode needs an image of 2×2 pixels or more (its slope is felt), got {cols}×{rows}")
    if options.blur_mm > max(width_mm, height_mm):
        raise TextureError(f"a blur of {options.blur_mm:g} mm is wider than the texture ({width_mm:.4g} × "
                           f"{height_mm:.4g} mm): it would flatten it; use at most {max(width_mm, height_mm):.4g} mm")
    edge_mode = "wrap" if options.seamless else "nearest"  # a tile's neighbours are across its seam
    if options.blur_mm > 0:  # on any tile: a blur that replicated its edges would keep the step across the seam
        blur_mode = "wrap" if options.seamless or options.outside == "tile" else "nearest"  # while it smooths
        from scipy import ndimage

        values = ndimage.gaussian_filter(values, sigma=options.blur_mm / (width_mm / cols), mode=blur_mode)  # inside
    if options.mode == "edges":
        values = _edges(values, edge_mode)
    black, white = _auto_levels(values, options)
    values = np.clip((values - black) / (white - black), 0.0, 1.0)
    if options.gamma != 1.0:
        values = values ** (1.0 / options.gamma)
    if options.invert:
        values = 1.0 - values
    low, high = options.ratio_range
    kind = "gradient" if options.mode == "gradient" else "friction"
    if kind == "friction":
        values = low + (high - low) * values
    authoring = {key: value for key, value in asdict(options).items() if value is not None}
    authoring.update(info or {})
    if options.auto_levels is not None:
        authoring.update(black=black, white=white)
    texture = Texture(values.astype(np.float32), width_mm, height_mm, kind=kind, outside=options.outside,
                      ratio_range=(low, high), name=name, description=f"authored from {Path(source).name}",
                      source=source, authoring=authoring)
    warn_if_seam(texture)
    return texture


def _seamless_step(values: np.ndarray, width_mm: float, options: AuthoringOptions) -> tuple[np.ndarray, float]:
    """Make the image a tile (``options.seamless``); features keep their physical size, so the
    width follows the tile's pixels (shorter by the cross-fade band, or twice as wide mirrored)."""
    if options.seamless is None:
        return values, width_mm
    pixel_mm = width_mm / values.shape[1]
    values = make_seamless(values, options.seamless, options.seam_band)
    return values, pixel_mm * values.shape[1]


def _auto_levels(values: np.ndarray, options: AuthoringOptions) -> tuple[float, float]:
    """Black and white points: the given levels, or with ``auto_levels`` the percentiles that clip
    that percentage of pixels at each end (a percentile stretch to the full range)."""
    if options.auto_levels is None:
        return options.black, options.white
    black, white = np.percentile(values, [options.auto_levels, 100.0 - options.auto_levels])
    if not white > black:
        raise TextureError("--auto-levels found a uniform image (no range to stretch); drop it or use --levels")
    return float(black), float(white)


def warn_if_seam(texture: Texture) -> None:
    """Warn when a texture that tiles has a seam a finger would feel (see :mod:`textures.seams`).

    Parameters
    ----------
    texture : Texture
        Checked only when its ``outside`` rule is ``tile``.

    Examples
    --------
    >>> import numpy as np, warnings
    >>> ramp = Texture(np.tile(np.linspace(0.0, 1.0, 8), (4, 1)), width_mm=8.0, height_mm=4.0, name="ramp")
    >>> with warnings.catch_warnings(record=True) as said:
    ...     warnings.simplefilter("always")
    ...     warn_if_seam(ramp)                                          # 1 → 0 across the edge
    >>> str(said[0].message).split(":")[0]
    'ramp tiles with a seam'
    """
    if texture.outside != "tile":
        return
    report = measure_seams(texture.values)
    if report.visible:
        warnings.warn(f"{texture.name or 'the texture'} tiles with a seam: its step across the tile's edge is "
                      f"{report.ratio:.1f}× the typical step inside (largest {report.seam_max:.2f} against "
                      f"{report.interior_max:.2f}); make it seamless (AuthoringOptions(seamless=...), or "
                      "--seamless), or let it not repeat (outside='clamp', or --outside clamp)",
                      stacklevel=3)


def author_image(path: str | Path, options: AuthoringOptions = AuthoringOptions(), name: str | None = None) -> Texture:
    """Make a texture from an image file (a photo, a drawing): its brightness (or another channel) mapped to
    friction ratios at a physical size.

    Parameters
    ----------
    path : str or pathlib.Path
        The image (PNG, JPEG, ... anything Pillow reads).
    options : AuthoringOptions
        Its physical size (``width_mm`` or ``dpi``), the channel, levels, blur (mm) and ratio range.
    name : str, optional
        The texture's name (the file's stem by default).

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        In one line, what is wrong with the image or the options.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from PIL import Image
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ramp.png"
    >>> Image.fromarray(np.tile(np.arange(0, 256, 4, dtype=np.uint8), (32, 1))).save(path)
    >>> texture = author_image(path, AuthoringOptions(width_mm=64.0, ratio_range=(0.5, 1.0), outside="clamp"))
    >>> texture.width_mm, texture.height_mm, round(float(texture.values.min()), 2)
    (64.0, 32.0, 0.5)
    """
    luminance, info = read_image_luminance(path, options)
    return texture_from_luminance(luminance, options, name or Path(path).stem, str(path), info)
