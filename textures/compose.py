"""
Combining textures and images into one texture: weighted mix, minimum, maximum, product, masking by
an image, and one texture tiled inside a region of another; also several textures placed on one
canvas (the demo's widgets scene, UI mock-ups).

Sizes are reconciled on a common millimetre grid. The result covers the first texture's area (or
``size_mm``; for :func:`tile_inside`, the outer texture's), with square pixels at the finest pitch
among the inputs (or ``px_per_mm``). Every input lies with its top-left corner at the origin at its
own physical size and is read at the result's pixel centres by bilinear interpolation,
band-limited (the sampler's pyramid) where the result's pixels are coarser than its own; beyond its
edges its own rule holds: a tiling input repeats, a clamped one extends its edge, a fixed one gives
its fixed ratio. Friction textures combine their friction ratios, gradient textures their heights
(the result is a gradient texture); the two kinds do not mix. The result takes the first input's
rule beyond its edges (``outside`` overrides it), so a composition of tiles tiles when every tile
fits a whole number of times; a tiling result with a seam gets the authoring warning.

The result keeps every input's temporal effects (:mod:`ultraglide.textures.effects`), each once: the
inputs lie from the top-left corner at their own size, so their regions and lines stay where they were
(a mask keeps both sides' effects, wherever the mask shows them). :func:`tile_inside` moves the inner
texture's effects into the region, repeated in every tile; :func:`compose` moves each placed texture's
effects to where it sits. More than a texture keeps (32) is an error; ``texture.with_(effects=())``
drops them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from ultraglide.textures import effects
from ultraglide.textures.authoring import warn_if_seam
from ultraglide.textures.errors import TextureError
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

OPERATIONS = ("mix", "min", "max", "multiply", "mask", "tile")
MAX_PIXELS = 16_000_000


@dataclass(frozen=True)
class Placement:
    """A texture's top-left corner on the canvas, mm.

    Parameters
    ----------
    texture : Texture
        The texture placed.
    x_mm, y_mm : float
        Its top-left corner on the canvas, mm.

    Examples
    --------
    >>> import numpy as np
    >>> patch = Placement(Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=5.0), 20.0, 0.0)
    >>> patch.contains(20.0, 0.0), patch.contains(29.9, 4.9), patch.contains(30.0, 2.0)     # right edge out
    (True, True, False)
    """

    texture: Texture
    x_mm: float
    y_mm: float

    def contains(self, x_mm: float, y_mm: float) -> bool:
        """Whether the point (mm, on the canvas) lies on this texture: left and top edges in, right and bottom out.

        Parameters
        ----------
        x_mm, y_mm : float
            The point, mm on the canvas.

        Returns
        -------
        bool

        Examples
        --------
        >>> import numpy as np
        >>> patch = Placement(Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=5.0), 20.0, 0.0)
        >>> patch.contains(25.0, 2.5), patch.contains(25.0, 5.0)                 # bottom edge out
        (True, False)
        """
        return (self.x_mm <= x_mm < self.x_mm + self.texture.width_mm
                and self.y_mm <= y_mm < self.y_mm + self.texture.height_mm)


def compose(size_mm: tuple[float, float], placements: list[Placement], background_ratio: float = 1.0,
            px_per_mm: float = 10.0, name: str = "composition") -> Texture:
    """A friction texture of ``size_mm`` with each placed texture's friction pasted where it sits;
    elsewhere ``background_ratio`` (1: bare glass, at rest). Each placed texture's effects come with it,
    moved to where it sits (those that played anywhere on it play on it).

    Parameters
    ----------
    size_mm : (float, float)
        The canvas's width and height (mm).
    placements : list of Placement
        The textures and their top-left corners (mm); a later one covers an earlier.
    background_ratio : float
        The friction ratio where nothing is placed.
    px_per_mm : float
        The canvas's resolution.
    name : str
        The result's name.

    Returns
    -------
    Texture

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> canvas = compose((20.0, 10.0), [Placement(a, 0.0, 0.0)], background_ratio=1.0)
    >>> canvas, float(canvas.values[0, 0]), float(canvas.values[0, -1])     # on a, then bare glass
    (Texture('composition', 20 × 10 mm, 200 × 100 px), 0.5, 1.0)
    """
    cols, rows = round(size_mm[0] * px_per_mm), round(size_mm[1] * px_per_mm)
    x = (np.arange(cols) + 0.5) / px_per_mm
    y = (np.arange(rows) + 0.5) / px_per_mm
    canvas = np.full((rows, cols), background_ratio, dtype=np.float32)
    for placement in placements:
        t = placement.texture
        inside_x = (x >= placement.x_mm) & (x < placement.x_mm + t.width_mm)
        inside_y = (y >= placement.y_mm) & (y < placement.y_mm + t.height_mm)
        if not inside_x.any() or not inside_y.any():
            continue
        gx, gy = np.meshgrid(x[inside_x] - placement.x_mm, y[inside_y] - placement.y_mm)
        ratio = Sampler(t, band_limited=False).ratio(gx, gy, direction=(np.ones_like(gx), np.zeros_like(gx)))
        canvas[np.ix_(inside_y, inside_x)] = ratio
    placed = effects.combined(*(effects.moved(p.texture.effects, p.x_mm, p.y_mm,
                                              (p.x_mm, p.y_mm, p.texture.width_mm, p.texture.height_mm))
                                for p in placements))
    return Texture(canvas, float(size_mm[0]), float(size_mm[1]), outside="fixed", outside_ratio=background_ratio,
                   name=name, description=", ".join(p.texture.name for p in placements), source="composed",
                   effects=placed)


@dataclass(frozen=True)
class Grid:
    """The common grid of a composition: its size in mm and its pixels (square, ``px_per_mm`` a side).

    Parameters
    ----------
    width_mm, height_mm : float
        The grid's size, mm.
    px_per_mm : float
        Pixels a mm, each way.

    Examples
    --------
    >>> grid = Grid(20.0, 5.0, 0.2)                 # 4 × 1 pixels of 5 mm
    >>> x, y = grid.centres()
    >>> grid.shape, x.tolist(), y.tolist()
    ((1, 4), [[2.5, 7.5, 12.5, 17.5]], [[2.5, 2.5, 2.5, 2.5]])
    """

    width_mm: float
    height_mm: float
    px_per_mm: float

    @property
    def shape(self) -> tuple[int, int]:
        """The grid's (rows, cols): its size (mm) times ``px_per_mm``, one pixel or more each way.

        Examples
        --------
        >>> Grid(20.0, 5.0, 0.2).shape                        # 20 mm × 0.2 px/mm across, 5 mm × 0.2 down: (rows, cols)
        (1, 4)
        """
        return max(1, round(self.height_mm * self.px_per_mm)), max(1, round(self.width_mm * self.px_per_mm))

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y (mm) of every pixel centre, rows × cols each.

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            x and y of every pixel's centre, mm, each of the grid's shape.

        Examples
        --------
        >>> x, y = Grid(10.0, 10.0, 0.2).centres()                  # 2 × 2 pixels of 5 mm
        >>> x.tolist(), y.tolist()
        ([[2.5, 7.5], [2.5, 7.5]], [[2.5, 2.5], [7.5, 7.5]])
        """
        rows, cols = self.shape
        x = (np.arange(cols) + 0.5) * (self.width_mm / cols)
        y = (np.arange(rows) + 0.5) * (self.height_mm / rows)
        return np.meshgrid(x, y)


def common_grid(textures: Sequence[Texture], size_mm: tuple[float, float] | None = None,
                px_per_mm: float | None = None) -> Grid:
    """The grid a composition of ``textures`` is made on (see the module docstring).

    Parameters
    ----------
    textures : sequence of Texture
    size_mm : (float, float), optional
        The result's width and height (mm); the first input's by default.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> common_grid([a, b], size_mm=(20.0, 10.0), px_per_mm=5.0).shape    # rows, cols
    (50, 100)
    """
    if not textures:
        raise TextureError("a composition needs at least one texture")
    width_mm, height_mm = size_mm or (textures[0].width_mm, textures[0].height_mm)
    density = px_per_mm or max(1.0 / min(t.pixel_mm) for t in textures)
    if not (np.isfinite(density) and density > 0 and width_mm > 0 and height_mm > 0):
        raise TextureError("a composition needs a positive size and resolution")
    grid = Grid(float(width_mm), float(height_mm), float(density))
    rows, cols = grid.shape
    if rows * cols > MAX_PIXELS:
        raise TextureError(f"the composition would be {cols}×{rows} pixels, too many; give a smaller --px-per-mm")
    return grid


def _kind_of(textures: Sequence[Texture]) -> str:
    kinds = {t.kind for t in textures}
    if len(kinds) > 1:
        names = ", ".join(f"{t.name or '?'} ({t.kind})" for t in textures)
        raise TextureError(f"friction and gradient textures do not combine: {names}")
    return kinds.pop()


def resample(texture: Texture, grid: Grid, x_mm: float = 0.0, y_mm: float = 0.0,
             outside: str | None = None) -> np.ndarray:
    """The texture's friction ratio (a gradient texture's height) at the grid's pixel centres, with its
    top-left corner at (``x_mm``, ``y_mm``) and its own rule beyond its edges (or ``outside``).

    Parameters
    ----------
    texture : Texture
    grid : Grid
        Where to sample: its size (mm) and pixels.
    x_mm, y_mm : float
        Where the texture's top-left corner lies on the grid (mm).
    outside : {"tile", "clamp", "fixed"}, optional
        The rule beyond the texture's edges; its own by default.

    Returns
    -------
    numpy.ndarray, shape (rows, cols)

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.array([[0.2, 0.8]]), width_mm=10.0, height_mm=5.0)
    >>> resample(a, Grid(20.0, 5.0, 0.2))[0].astype(float).round(2).tolist()     # tiled: 0.2 0.8 0.2 0.8
    [0.2, 0.8, 0.2, 0.8]
    """
    rule = outside or texture.outside
    if texture.kind == "gradient":  # heights: flat ground beyond a fixed height map is its edge extended
        texture = texture.with_(kind="friction", outside="clamp" if rule == "fixed" else rule)
    elif rule != texture.outside:
        texture = texture.with_(outside=rule)
    x, y = grid.centres()
    step_mm = 1.0 / grid.px_per_mm
    sampler = Sampler(texture, band_limited=step_mm > min(texture.pixel_mm))
    return sampler.ratio(x - x_mm, y - y_mm, step_mm=step_mm)


def _result(values: np.ndarray, grid: Grid, base: Texture, kind: str, name: str, description: str,
            outside: str | None, effects: tuple = (), **authoring) -> Texture:
    values = np.clip(values, 0.0, 1.0).astype(np.float32)
    if kind == "friction":
        ratio_range = (float(values.min()), float(values.max()))
    else:
        ratio_range = base.ratio_range
    texture = Texture(values, grid.width_mm, grid.height_mm, kind=kind, outside=outside or base.outside,
                      outside_ratio=base.outside_ratio, ratio_range=ratio_range, name=name,
                      description=description, source="composed", effects=effects,
                      authoring={"operation": authoring.pop("operation"), "px_per_mm": grid.px_per_mm, **authoring})
    warn_if_seam(texture)
    return texture


def _names(textures: Sequence[Texture]) -> list[str]:
    return [t.name or f"input {i + 1}" for i, t in enumerate(textures)]


def _combine(operation: str, textures: Sequence[Texture], size_mm, px_per_mm):
    if len(textures) < 2:
        raise TextureError(f"{operation} needs two textures or more, got {len(textures)}")
    kind = _kind_of(textures)
    grid = common_grid(textures, size_mm, px_per_mm)
    return grid, kind, np.stack([resample(t, grid) for t in textures])


def mix(textures: Sequence[Texture], weights: Sequence[float] | None = None, size_mm=None,
        px_per_mm: float | None = None, name: str = "mix", outside: str | None = None) -> Texture:
    """The weighted mean Σ wᵢ vᵢ / Σ wᵢ of the inputs (equal weights unless given).

    Parameters
    ----------
    textures : sequence of Texture
    weights : sequence of float, optional
        One weight per texture, >= 0 and not all 0.
    size_mm : (float, float), optional
        The result's width and height (mm); the first input's by default.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.
    name : str
        The result's name.
    outside : {"tile", "clamp", "fixed"}, optional
        The result's rule beyond its edges; the first input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> round(float(mix([a, b]).values[0, 0]), 3), round(float(mix([a, b], weights=[3, 1]).values[0, 0]), 3)
    (0.65, 0.575)
    """
    weights = np.ones(len(textures)) if weights is None else np.asarray(weights, dtype=float)
    if weights.shape != (len(textures),):
        raise TextureError(f"give one weight per texture: {len(textures)} textures, {weights.size} weights")
    if not (np.all(np.isfinite(weights)) and np.all(weights >= 0) and weights.sum() > 0):
        raise TextureError("weights must be zero or more, and not all zero")
    grid, kind, stack = _combine("mix", textures, size_mm, px_per_mm)
    weights = weights / weights.sum()
    values = np.tensordot(weights, stack, axes=1)
    parts = ", ".join(f"{n} ({w:.3g})" for n, w in zip(_names(textures), weights, strict=True))
    return _result(values, grid, textures[0], kind, name, f"weighted mix of {parts}", outside, operation="mix",
                   inputs=_names(textures), weights=weights.tolist(),
                   effects=effects.combined(*(t.effects for t in textures)))


def minimum(textures: Sequence[Texture], size_mm=None, px_per_mm: float | None = None, name: str = "min",
            outside: str | None = None) -> Texture:
    """The lowest value of the inputs at each point (for friction: the slipperiest).

    Parameters
    ----------
    textures : sequence of Texture
    size_mm : (float, float), optional
        The result's width and height (mm); the first input's by default.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.
    name : str
        The result's name.
    outside : {"tile", "clamp", "fixed"}, optional
        The result's rule beyond its edges; the first input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> round(float(minimum([a, b]).values[0, 0]), 3)
    0.5
    """
    grid, kind, stack = _combine("min", textures, size_mm, px_per_mm)
    return _result(stack.min(axis=0), grid, textures[0], kind, name, f"minimum of {', '.join(_names(textures))}",
                   outside, operation="min", inputs=_names(textures),
                   effects=effects.combined(*(t.effects for t in textures)))


def maximum(textures: Sequence[Texture], size_mm=None, px_per_mm: float | None = None, name: str = "max",
            outside: str | None = None) -> Texture:
    """The highest value of the inputs at each point (for friction: the stickiest).

    Parameters
    ----------
    textures : sequence of Texture
    size_mm : (float, float), optional
        The result's width and height (mm); the first input's by default.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.
    name : str
        The result's name.
    outside : {"tile", "clamp", "fixed"}, optional
        The result's rule beyond its edges; the first input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> round(float(maximum([a, b]).values[0, 0]), 3)
    0.8
    """
    grid, kind, stack = _combine("max", textures, size_mm, px_per_mm)
    return _result(stack.max(axis=0), grid, textures[0], kind, name, f"maximum of {', '.join(_names(textures))}",
                   outside, operation="max", inputs=_names(textures),
                   effects=effects.combined(*(t.effects for t in textures)))


def multiply(textures: Sequence[Texture], size_mm=None, px_per_mm: float | None = None, name: str = "multiply",
             outside: str | None = None) -> Texture:
    """The product of the inputs: friction reductions compound (0.5 × 0.8 = 0.4).

    Parameters
    ----------
    textures : sequence of Texture
    size_mm : (float, float), optional
        The result's width and height (mm); the first input's by default.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.
    name : str
        The result's name.
    outside : {"tile", "clamp", "fixed"}, optional
        The result's rule beyond its edges; the first input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> round(float(multiply([a, b]).values[0, 0]), 3)
    0.4
    """
    grid, kind, stack = _combine("multiply", textures, size_mm, px_per_mm)
    return _result(stack.prod(axis=0), grid, textures[0], kind, name, f"product of {', '.join(_names(textures))}",
                   outside, operation="multiply", inputs=_names(textures),
                   effects=effects.combined(*(t.effects for t in textures)))


def mask(texture: Texture, weights: Texture | np.ndarray, other: Texture | None = None, other_ratio: float = 1.0,
         size_mm=None, px_per_mm: float | None = None, name: str = "mask", outside: str | None = None) -> Texture:
    """``texture`` where the mask is 1, ``other`` (or the constant ``other_ratio``) where it is 0, blended
    in between: m·A + (1 − m)·B.

    ``weights`` is a texture (its values, 0..1, at its physical size with its rule beyond its edges)
    or an image's luminance (rows × cols in 0..1), stretched over the whole result.

    Parameters
    ----------
    texture : Texture
        A: where the mask is 1.
    weights : Texture or numpy.ndarray
        The mask m, 0..1.
    other : Texture, optional
        B: where the mask is 0.
    other_ratio : float
        B as a constant friction ratio (0..1) when ``other`` is not given.
    size_mm : (float, float), optional
        The result's width and height (mm); the first input's by default.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.
    name : str
        The result's name.
    outside : {"tile", "clamp", "fixed"}, optional
        The result's rule beyond its edges; the first input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> mask(a, np.array([[1.0, 0.0], [1.0, 0.0]]), other_ratio=1.0).values[0].round(3).tolist()
    [0.5, 1.0]
    """
    inputs = [texture] + ([other] if other is not None else [])
    kind = _kind_of(inputs)
    if other is None and not 0 <= other_ratio <= 1:
        raise TextureError(f"the ratio outside the mask must lie in 0..1, got {other_ratio}")
    sized = inputs + ([weights] if isinstance(weights, Texture) else [])
    grid = common_grid(sized, size_mm, px_per_mm)
    if isinstance(weights, Texture):
        m, mask_name = resample(weights.with_(kind="friction"), grid), weights.name or "a mask"
    else:
        weights = np.asarray(weights, dtype=np.float32)
        stretched = Texture(np.clip(weights, 0, 1), grid.width_mm, grid.height_mm, outside="clamp")
        m, mask_name = resample(stretched, grid), "an image"
    a = resample(texture, grid)
    b = resample(other, grid) if other is not None else np.full_like(a, other_ratio)
    values = m * a + (1 - m) * b
    where_not = other.name if other is not None else f"ratio {other_ratio:g}"
    return _result(values, grid, texture, kind, name, f"{texture.name} masked by {mask_name}, else {where_not}",
                   outside, operation="mask", inputs=_names(inputs), mask=mask_name,
                   effects=effects.combined(*(t.effects for t in inputs)),
                   **({} if other is not None else {"other_ratio": other_ratio}))


def tile_inside(inner: Texture, outer: Texture, region_mm: tuple[float, float, float, float],
                px_per_mm: float | None = None, name: str = "tiled", outside: str | None = None) -> Texture:
    """``outer`` with the rectangle ``region_mm`` (x, y, width, height) filled by ``inner`` repeated
    from the region's top-left corner; the result has the outer texture's size.

    Parameters
    ----------
    inner : Texture
        What fills the region, repeated.
    outer : Texture
        The ground, and the result's size.
    region_mm : (float, float, float, float)
        x, y, width, height (mm) on ``outer``.
    px_per_mm : float, optional
        The result's resolution; the finest input's by default.
    name : str
        The result's name.
    outside : {"tile", "clamp", "fixed"}, optional
        The result's rule beyond its edges; the first input's by default.

    Returns
    -------
    Texture

    Raises
    ------
    TextureError
        No input, friction and gradient textures together, or a result of too many pixels.

    Examples
    --------
    >>> import numpy as np
    >>> a = Texture(np.full((2, 2), 0.5), width_mm=10.0, height_mm=10.0, name="a")
    >>> b = Texture(np.full((2, 2), 0.8), width_mm=10.0, height_mm=10.0, name="b")
    >>> outer = Texture(np.full((4, 4), 1.0), width_mm=40.0, height_mm=40.0, name="glass")
    >>> tiled = tile_inside(a, outer, (10.0, 10.0, 20.0, 20.0))
    >>> tiled, float(tiled.values[0, 0]), float(tiled.values[4, 4])        # the ground, inside the region
    (Texture('tiled', 40 × 40 mm, 8 × 8 px), 1.0, 0.5)
    """
    x0, y0, width, height = (float(v) for v in region_mm)
    if not (width > 0 and height > 0 and np.isfinite([x0, y0, width, height]).all()):
        raise TextureError(f"the region is X,Y,WIDTH,HEIGHT in mm with a positive size, got {region_mm}")
    kind = _kind_of([outer, inner])
    grid = common_grid([outer, inner], None, px_per_mm)
    x, y = grid.centres()
    inside = (x >= x0) & (x < x0 + width) & (y >= y0) & (y < y0 + height)
    if not inside.any():
        raise TextureError(f"the region {x0:g},{y0:g},{width:g},{height:g} mm misses the "
                           f"{outer.width_mm:g} × {outer.height_mm:g} mm texture")
    values = np.where(inside, resample(inner, grid, x0, y0, outside="tile"), resample(outer, grid))
    return _result(values, grid, outer, kind, name,
                   f"{inner.name} tiled in {width:g} × {height:g} mm at ({x0:g}, {y0:g}) of {outer.name}",
                   outside, operation="tile", inputs=[inner.name, outer.name], region_mm=[x0, y0, width, height],
                   effects=effects.combined(outer.effects, _tiled_effects(inner, (x0, y0, width, height))))


def _tiled_effects(inner: Texture, region_mm: tuple[float, float, float, float]) -> tuple:
    """``inner``'s effects where it is tiled in ``region_mm``: those that played anywhere on it play once in the
    whole region (a finger sliding from tile to tile stays in it); those in a region of it, and crossings of
    its lines, in every tile, as far as the tiled region goes."""
    x0, y0, width, height = region_mm
    whole = [b for b in inner.effects if b.trigger.region_mm is None and b.trigger.on != "cross"]
    each = [b for b in inner.effects if b not in whole]
    out = list(effects.moved(whole, x0, y0, region_mm))
    columns, rows = int(np.ceil(width / inner.width_mm)), int(np.ceil(height / inner.height_mm))
    if each and columns * rows * len(each) > effects.MAX_BINDINGS:
        raise TextureError(f"{inner.name}'s {len(each)} effects in {columns * rows} tiles are more than the "
                           f"{effects.MAX_BINDINGS} a texture keeps; tile it without them (inner.with_(effects=()), "
                           "or --no-effects)")
    for row in range(rows):
        for column in range(columns):
            dx, dy = x0 + column * inner.width_mm, y0 + row * inner.height_mm
            for binding in effects.moved(each, dx, dy, (dx, dy, inner.width_mm, inner.height_mm)):
                bx, by, bw, bh = binding.trigger.region_mm  # clipped to the tiled region
                left, top = max(bx, x0), max(by, y0)
                right, bottom = min(bx + bw, x0 + width), min(by + bh, y0 + height)
                if right > left and bottom > top:
                    trigger = replace(binding.trigger, region_mm=(left, top, right - left, bottom - top))
                    out.append(replace(binding, trigger=trigger))
    return tuple(out)
