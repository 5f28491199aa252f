"""The texture: a map of target friction ratios with a physical size.

Coordinates are millimetres from the top-left corner, x to the right and y downwards, as on a
screen and in an image; pixel (row, col) covers [col, col+1) × [row, row+1) pixels and its value
holds at its centre. Values are float32 in [0, 1].

A ``friction`` texture stores the friction ratio itself (1 = plate at rest). A ``gradient``
texture stores a height map (0..1); friction then follows the slope along the finger's motion,
uphill stickier and downhill slipperier, so a bump feels like a bump from every direction
(the TPad's gradient mode, see :mod:`textures.sampling`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from ultraglide.textures.errors import TextureError

KINDS = ("friction", "gradient")
OUTSIDE_RULES = ("tile", "clamp", "fixed")
MIN_PIXEL_MM = 1e-6  # 1 nm: nothing real is finer, and every later division by the pitch stays finite


@dataclass(frozen=True, eq=False)
class Texture:
    """A friction map (or height map) with its physical size and metadata; immutable.

    Parameters
    ----------
    values : array_like, shape (rows, cols)
        The map, in [0, 1] (stored as a read-only float32 array): friction ratios (1 = the plate at rest) for a
        ``friction`` texture, heights for a ``gradient`` one. Row 0 is the top edge, column 0 the left.
    width_mm, height_mm : float
        The map's physical size (mm), > 0; its pixels are 1 nm or more.
    kind : {"friction", "gradient"}
        What ``values`` holds; a gradient texture's friction follows the slope along the motion.
    outside : {"tile", "clamp", "fixed"}
        What lies beyond the edges: the map repeated, its edge extended, or ``outside_ratio``.
    outside_ratio : float
        The friction ratio beyond the edges with ``outside="fixed"``, in [0, 1].
    ratio_range : (float, float)
        Gradient kind: the ratios at the steepest downhill and uphill slopes, 0 <= low <= high <= 1.
    full_slope_per_mm : float
        Gradient kind: the slope (height per mm) that reaches the ends of ``ratio_range``; 0: the map's
        steepest.
    name, description, source : str
        What a person reads: the texture's name, a sentence, where it came from.
    authoring : dict
        How it was made from an image (:mod:`textures.authoring`), for the file.
    effects : tuple of textures.effects.Binding
        Temporal effects played with this texture.

    Raises
    ------
    TextureError
        A map that is not 2-D or has values outside [0, 1], a size that is not positive and finite, pixels
        under 1 nm, or an unknown kind, outside rule or ratio range.

    Examples
    --------
    >>> import numpy as np
    >>> tiles = Texture(np.array([[1.0, 0.5], [0.25, 1.0]]), width_mm=4.0, height_mm=2.0, name="tiles")
    >>> tiles
    Texture('tiles', 4 × 2 mm, 2 × 2 px)
    >>> tiles.pixel_mm                                       # (x, y), mm
    (2.0, 1.0)
    >>> tiles.with_(outside="clamp").outside
    'clamp'
    >>> Texture(np.array([[1.5]]), width_mm=1.0, height_mm=1.0)
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: texture values must be finite and within 0..1
    """

    values: np.ndarray  # (rows, cols) float32 in [0, 1]
    width_mm: float
    height_mm: float
    kind: str = "friction"
    outside: str = "tile"  # what lies beyond the edges: repeat, extend the edge, or a fixed ratio
    outside_ratio: float = 1.0
    ratio_range: tuple[float, float] = (0.0, 1.0)  # gradient kind: ratios at steepest down/uphill
    full_slope_per_mm: float = 0.0  # gradient kind: slope reaching the range ends; 0 = the map's steepest
    name: str = ""
    description: str = ""
    source: str = ""
    authoring: dict = field(default_factory=dict)
    effects: tuple = ()  # textures.effects.Binding: temporal effects played with this texture

    def __repr__(self) -> str:
        """``Texture('wood', 90 × 60 mm, 1024 × 683 px)``: its name, size and pixels, not its array."""
        kind = "" if self.kind == "friction" else f", {self.kind}"
        return (f"Texture({self.name!r}, {self.width_mm:g} × {self.height_mm:g} mm, "
                f"{self.cols} × {self.rows} px{kind})")

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float32)
        if values.ndim != 2 or min(values.shape) < 1:
            raise TextureError(f"a texture needs a 2-D map, got shape {values.shape}")
        low, high = values.min(), values.max()  # a NaN anywhere is the minimum's and the maximum's: one check
        if not (np.isfinite(low) and np.isfinite(high)) or low < 0 or high > 1:
            raise TextureError("texture values must be finite and within 0..1")
        if not (self.width_mm > 0 and self.height_mm > 0 and np.isfinite(self.width_mm * self.height_mm)):
            raise TextureError(f"texture size must be positive, got {self.width_mm} × {self.height_mm} mm")
        if min(self.width_mm / values.shape[1], self.height_mm / values.shape[0]) < MIN_PIXEL_MM:
            raise TextureError(f"texture pixels must be {MIN_PIXEL_MM:g} mm or more, got {values.shape[1]}×"
                               f"{values.shape[0]} over {self.width_mm:g} × {self.height_mm:g} mm")
        if self.kind not in KINDS:
            raise TextureError(f"texture kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "gradient" and min(values.shape) < 2:
            raise TextureError(f"a gradient texture needs 2×2 pixels or more (its slope is felt), got "
                               f"{values.shape[1]}×{values.shape[0]}; use a larger size or --px-per-mm")
        if self.outside not in OUTSIDE_RULES:
            raise TextureError(f"outside rule must be one of {', '.join(OUTSIDE_RULES)}, got {self.outside!r}")
        if not 0 <= self.outside_ratio <= 1:
            raise TextureError(f"outside ratio must lie in 0..1, got {self.outside_ratio}")
        low, high = self.ratio_range
        if not 0 <= low <= high <= 1:
            raise TextureError(f"ratio range must satisfy 0 <= low <= high <= 1, got {low} {high}")
        from ultraglide.textures.effects import Binding

        effects = tuple(self.effects)
        if not all(isinstance(binding, Binding) for binding in effects):
            raise TextureError("a texture's effects must be textures.effects.Binding values")
        object.__setattr__(self, "effects", effects)
        values.setflags(write=False)
        object.__setattr__(self, "values", values)
        if self.kind == "gradient" and not self.full_slope_per_mm > 0:
            slope_y, slope_x = np.gradient(values.astype(float), *self.pixel_mm[::-1])
            steepest = float(np.max(np.hypot(slope_x, slope_y)))
            object.__setattr__(self, "full_slope_per_mm", steepest if steepest > 0 else 1.0)
        object.__setattr__(self, "ratio_range", (float(low), float(high)))

    @property
    def rows(self) -> int:
        """The map's rows of pixels (down its height).

        Examples
        --------
        >>> import numpy as np
        >>> Texture(np.ones((20, 40)), width_mm=80.0, height_mm=40.0).rows
        20
        """
        return self.values.shape[0]

    @property
    def cols(self) -> int:
        """The map's columns of pixels (across its width).

        Examples
        --------
        >>> import numpy as np
        >>> Texture(np.ones((20, 40)), width_mm=80.0, height_mm=40.0).cols
        40
        """
        return self.values.shape[1]

    @property
    def pixel_mm(self) -> tuple[float, float]:
        """Pixel size (x, y) in millimetres: the width over the columns, the height over the rows.

        Examples
        --------
        >>> import numpy as np
        >>> Texture(np.ones((20, 40)), width_mm=80.0, height_mm=30.0).pixel_mm          # 80 / 40, 30 / 20
        (2.0, 1.5)
        """
        return self.width_mm / self.cols, self.height_mm / self.rows

    def with_(self, **changes: object) -> Texture:
        """A copy with some fields changed (checked as a new texture is).

        Parameters
        ----------
        **changes : object
            Field names (``width_mm``, ``outside`` ...) and their new values.

        Returns
        -------
        Texture

        Raises
        ------
        TextureError
            A changed value a texture refuses.

        Examples
        --------
        >>> from ultraglide.textures.procedural import grating
        >>> grating(wavelength_mm=2.0, size_mm=(20.0, 10.0)).with_(width_mm=40.0)
        Texture('grating-sine', 40 × 10 mm, 200 × 100 px)
        """
        return replace(self, **changes)

    def ratio_map(self) -> np.ndarray:
        """The friction ratio at every pixel; for a gradient texture, under a left-to-right swipe.

        Returns
        -------
        numpy.ndarray, shape (rows, cols), float32
            Friction ratios in [0, 1].

        Examples
        --------
        >>> import numpy as np
        >>> Texture(np.array([[0.2, 0.8]]), width_mm=2.0, height_mm=1.0).ratio_map()
        array([[0.2, 0.8]], dtype=float32)
        """
        if self.kind == "friction":
            return self.values
        from ultraglide.textures.sampling import gradient_maps

        slope_x, _ = gradient_maps(self)
        return gradient_ratio(self, slope_x)


def gradient_ratio(texture: Texture, slope):
    """Friction ratio for a slope along the motion (height units per mm) on a gradient texture.

    The steepest slope in the map reaches the ends of ``ratio_range``; flat ground is its middle.

    Parameters
    ----------
    texture : Texture
        A gradient texture.
    slope : array_like
        Slopes along the motion (height units per mm): uphill > 0.

    Returns
    -------
    numpy.ndarray of float32

    Examples
    --------
    >>> hill = Texture(np.array([[0.0, 0.5, 1.0]] * 2), width_mm=3.0, height_mm=2.0, kind="gradient",
    ...                full_slope_per_mm=0.5)
    >>> gradient_ratio(hill, [0.0, 0.5, -1.0]).tolist()               # flat, steepest up, beyond steepest down
    [0.5, 1.0, 0.0]
    """
    low, high = texture.ratio_range
    middle, half = 0.5 * (low + high), 0.5 * (high - low)
    ratio = middle + (half / texture.full_slope_per_mm) * np.asarray(slope, dtype=np.float32)
    return np.clip(ratio, low, high).astype(np.float32, copy=False)
