"""Textures from images: any image Pillow reads becomes a friction map.

The pipeline, in order: read (first frame; EXIF rotation applied; alpha composited on
``background``, white by default, so transparent parts read as "at rest"), luminance
(ITU-R 601: 0.299 R + 0.587 G + 0.114 B, 16-bit kept at 16 bits), crop (pixels), blur
(Gaussian, ``blur_mm`` is its sigma), mapping (``brightness``: the luminance; ``edges``: the
Sobel edge strength, normalised; ``gradient``: the luminance as a height map, felt through its
slope), levels (black and white points), gamma (v ** (1/gamma)), invert, and finally the friction
range: v = 0 gives ``ratio_range[0]`` (slippery), v = 1 gives ``ratio_range[1]`` (sticky).
So by default white is sticky (at rest) and black is slippery.

Its size is ``width_mm`` (default 80 mm, a typical plate) or follows from ``dpi``.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError
from scipy import ndimage
from ultraglide.textures.errors import TextureError
from ultraglide.textures.texture import Texture

MODES = ("brightness", "edges", "gradient")
DEFAULT_WIDTH_MM = 80.0
DEFAULT_MAX_PIXELS = 40_000_000


@dataclass(frozen=True)
class AuthoringOptions:
    """How an image becomes a texture; see the module docstring for the order of the steps."""

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
        if self.max_pixels <= 0:
            raise TextureError("the pixel limit must be positive")


def _luminance(image: Image.Image, background) -> np.ndarray:
    """Luminance in 0..1 of an image of any mode (frame already chosen and rotated)."""
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        return np.clip(np.asarray(image, dtype=np.float64), 0, 65535) / 65535.0
    if mode == "F":
        values = np.nan_to_num(np.asarray(image, dtype=np.float64))
        top = values.max()
        return np.clip(values / top if top > 1 else values, 0, 1)
    if mode in ("1", "L"):
        return np.asarray(image.convert("L"), dtype=np.float64) / 255.0
    has_alpha = mode in ("LA", "La", "PA", "RGBA", "RGBa") or "transparency" in image.info
    if has_alpha:
        rgba = image.convert("RGBA")
        ground = Image.new("RGBA", rgba.size, tuple(background) + (255,))
        rgb = Image.alpha_composite(ground, rgba).convert("RGB")
    else:
        rgb = image.convert("RGB")
    pixels = np.asarray(rgb, dtype=np.float64) / 255.0
    return pixels @ np.array([0.299, 0.587, 0.114])


def read_image_luminance(path: str | Path, options: AuthoringOptions = AuthoringOptions()) -> tuple[np.ndarray, dict]:
    """Luminance (0..1, rows × cols) of an image file, and facts about the source."""
    path = Path(path)
    if path.is_dir():
        raise TextureError(f"{path}: is a directory, not an image")
    previous_limit = Image.MAX_IMAGE_PIXELS
    Image.MAX_IMAGE_PIXELS = None  # our own limit below says what to do; Pillow's would only warn
    try:
        with Image.open(path) as image:
            if image.width * image.height > options.max_pixels:
                raise TextureError(
                    f"{path}: {image.width}×{image.height} is {image.width * image.height:,} pixels, over the "
                    f"limit of {options.max_pixels:,}; raise it with --max-pixels or shrink the image")
            frames = getattr(image, "n_frames", 1)
            if frames > 1:
                warnings.warn(f"{path} is animated ({frames} frames); using the first", stacklevel=2)
                image.seek(0)
            image.load()
            source_mode = image.mode
            image = ImageOps.exif_transpose(image)
            luminance = _luminance(image, options.background)
            info = {"source_mode": source_mode, "source_size": [image.width, image.height], "frames": frames,
                    "format": image.format or ""}
    except FileNotFoundError:
        raise TextureError(f"{path}: no such file") from None
    except UnidentifiedImageError:
        raise TextureError(f"{path}: not an image Pillow can read (empty, or not an image at all)") from None
    except (OSError, SyntaxError, ValueError) as error:
        raise TextureError(f"{path}: the image is damaged or truncated ({error})") from None
    finally:
        Image.MAX_IMAGE_PIXELS = previous_limit
    return luminance, info


def _edges(values: np.ndarray) -> np.ndarray:
    strength = np.hypot(ndimage.sobel(values, axis=1, mode="nearest"), ndimage.sobel(values, axis=0, mode="nearest"))
    top = strength.max()
    return strength / top if top > 0 else strength


def texture_from_luminance(luminance: np.ndarray, options: AuthoringOptions, name: str = "",
                           source: str = "", info: dict | None = None) -> Texture:
    """Apply crop, blur, mapping, levels, gamma, invert and range to a luminance map."""
    values = luminance
    if options.crop is not None:
        x, y, w, h = options.crop
        rows, cols = values.shape
        if x + w > cols or y + h > rows:
            raise TextureError(f"crop {x},{y},{w},{h} reaches outside the {cols}×{rows} image")
        values = values[y:y + h, x:x + w]
    rows, cols = values.shape
    if options.dpi is not None:
        width_mm = cols / options.dpi * 25.4
    else:
        width_mm = options.width_mm or DEFAULT_WIDTH_MM
    height_mm = width_mm * rows / cols
    if options.blur_mm > 0:
        values = ndimage.gaussian_filter(values, sigma=options.blur_mm / (width_mm / cols), mode="nearest")
    if options.mode == "edges":
        values = _edges(values)
    values = np.clip((values - options.black) / (options.white - options.black), 0.0, 1.0)
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
    return Texture(values.astype(np.float32), width_mm, height_mm, kind=kind, outside=options.outside,
                   ratio_range=(low, high), name=name, description=f"authored from {Path(source).name}",
                   source=source, authoring=authoring)


def author_image(path: str | Path, options: AuthoringOptions = AuthoringOptions(), name: str | None = None) -> Texture:
    """Make a texture from an image file; :class:`TextureError` says what is wrong with bad input."""
    luminance, info = read_image_luminance(path, options)
    return texture_from_luminance(luminance, options, name or Path(path).stem, str(path), info)
