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

import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError
from scipy import ndimage
from ultraglide.textures.errors import TextureError
from ultraglide.textures.seams import DEFAULT_BAND, METHODS, make_seamless, measure_seams
from ultraglide.textures.texture import Texture

MODES = ("brightness", "edges", "gradient")
DEFAULT_WIDTH_MM = 80.0
DEFAULT_MAX_PIXELS = 40_000_000
MAX_PIXELS_LIMIT = 100_000_000  # what a texture file may hold (textures.fileformat.MAX_PIXELS)
MAX_SIDE_MM = 10_000.0  # what a texture file may measure


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
        if not 0 < self.max_pixels <= MAX_PIXELS_LIMIT:
            raise TextureError(f"the pixel limit must be 1 to {MAX_PIXELS_LIMIT:,} (the texture file's own limit), "
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


def _edges(values: np.ndarray, mode: str = "nearest") -> np.ndarray:
    strength = np.hypot(ndimage.sobel(values, axis=1, mode=mode), ndimage.sobel(values, axis=0, mode=mode))
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
    """Warn when a texture that tiles has a seam a finger would feel (see :mod:`textures.seams`)."""
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
    """Make a texture from an image file; :class:`TextureError` says what is wrong with bad input."""
    luminance, info = read_image_luminance(path, options)
    return texture_from_luminance(luminance, options, name or Path(path).stem, str(path), info)
