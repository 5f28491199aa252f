"""Views and sprites: where a client's textures lie on its screen, and the one texture the engine renders of them.

A **view** is a client's window (or a whole screen): its size in its own units (``px`` with its physical size
in mm, or ``mm``) and a background friction ratio. A **sprite** places a loaded texture in a view: a rectangle
(top-left corner, width and height in the view's units, before rotation), a rotation about the rectangle's
centre (degrees, clockwise on the screen, as CSS ``rotate``), a ``z`` (the larger is on top, as CSS
``z-index``; equal ``z``: the later placed on top) and whether it is shown. A sprite's texture is stretched to
fill its rectangle, as an image sprite is.

The engine renders one texture and predicts the finger on it (:mod:`render.engine`), so a view is **composed**
into one friction texture covering the view (:func:`compose_view`): at every pixel of a grid in millimetres, the
ratio of the topmost shown sprite there, read from its texture (bilinear), else the background. The finger's
position in the view is then its position on that texture, and the friction under it is the topmost sprite's.
The grid's pitch is the finest of the sprites' (their texture pixels as stretched), held between
:data:`MIN_PX_PER_MM` and :data:`MAX_PX_PER_MM` and within :data:`MAX_COMPOSED_PIXELS`.

A sprite's texture's own temporal effects are not placed with it (a stretched or rotated region has no
equivalent in the effects' axis-aligned triggers); the session's effects (:mod:`apps.service.server`) play instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

UNITS = ("px", "mm")
MIN_PX_PER_MM = 2.0
MAX_PX_PER_MM = 20.0  # a texture's own finest (textures.fileformat holds files at 20 pixels per mm)
MAX_COMPOSED_PIXELS = 4_000_000  # 16 MB of float32: set in the engine in some 10 ms
MAX_SIDE_MM = 2000.0  # a view's side: any screen
MAX_SIDE_PX = 100_000


@dataclass(frozen=True)
class View:
    """A client's window: ``width`` × ``height`` in ``units``; ``width_mm`` × ``height_mm`` its physical size."""

    name: str
    width: float
    height: float
    units: str
    width_mm: float
    height_mm: float
    background_ratio: float = 1.0

    @property
    def mm_per_unit(self) -> tuple[float, float]:
        """Millimetres per unit of the view, (x, y)."""
        return self.width_mm / self.width, self.height_mm / self.height

    def to_mm(self, x: float, y: float) -> tuple[float, float]:
        """A point in the view's units to millimetres from its top-left corner."""
        sx, sy = self.mm_per_unit
        return x * sx, y * sy


@dataclass(frozen=True)
class Sprite:
    """A texture (its id in the session) at a rectangle of a view, in the view's units; ``order``: when it was
    placed (ties of ``z``: the later on top)."""

    name: str
    view: str
    texture: str
    x: float
    y: float
    width: float
    height: float
    rotation_deg: float = 0.0
    z: float = 0.0
    visible: bool = True
    order: int = 0

    def with_(self, **changes) -> Sprite:
        return replace(self, **changes)

    def local_mm(self, view: View, x_mm, y_mm):
        """Points of the view (mm) in the sprite's own rectangle: (u, v) mm from its top-left corner, unrotated;
        works on numbers and numpy arrays alike."""
        sx, sy = view.mm_per_unit
        w, h = self.width * sx, self.height * sy
        cx, cy = self.x * sx + w / 2, self.y * sy + h / 2
        theta = math.radians(self.rotation_deg)
        c, s = math.cos(theta), math.sin(theta)
        dx, dy = x_mm - cx, y_mm - cy
        return dx * c + dy * s + w / 2, -dx * s + dy * c + h / 2

    def size_mm(self, view: View) -> tuple[float, float]:
        sx, sy = view.mm_per_unit
        return self.width * sx, self.height * sy

    def contains(self, view: View, x_mm: float, y_mm: float) -> bool:
        """Whether the view's point (mm) lies on this sprite (shown or not)."""
        u, v = self.local_mm(view, x_mm, y_mm)
        w, h = self.size_mm(view)
        return 0.0 <= u < w and 0.0 <= v < h

    def bounds_mm(self, view: View) -> tuple[float, float, float, float]:
        """The rotated rectangle's bounding box in the view, mm: (left, top, right, bottom)."""
        sx, sy = view.mm_per_unit
        w, h = self.size_mm(view)
        cx, cy = self.x * sx + w / 2, self.y * sy + h / 2
        theta = math.radians(self.rotation_deg)
        c, s = abs(math.cos(theta)), abs(math.sin(theta))
        half_w, half_h = (w * c + h * s) / 2, (w * s + h * c) / 2
        return cx - half_w, cy - half_h, cx + half_w, cy + half_h


def stacked(sprites) -> list[Sprite]:
    """Sprites bottom first: by ``z``, then by when they were placed."""
    return sorted(sprites, key=lambda sprite: (sprite.z, sprite.order))


def sprite_at(view: View, sprites, x_mm: float, y_mm: float) -> Sprite | None:
    """The topmost shown sprite of ``view`` under the point (mm), or None (the background)."""
    for sprite in reversed(stacked(s for s in sprites if s.view == view.name and s.visible)):
        if sprite.contains(view, x_mm, y_mm):
            return sprite
    return None


def grid_density(view: View, sprites, textures: dict) -> float:
    """The composed grid's pixels per mm: the finest sprite's (its texture's pixels as stretched), within the
    bounds and the pixel budget."""
    finest = MIN_PX_PER_MM
    for sprite in sprites:
        texture = textures[sprite.texture]
        w, h = sprite.size_mm(view)
        finest = max(finest, texture.cols / max(w, 1e-9), texture.rows / max(h, 1e-9))
    density = min(finest, MAX_PX_PER_MM)
    budget = math.sqrt(MAX_COMPOSED_PIXELS / (view.width_mm * view.height_mm))
    return max(min(density, budget), 1e-3)


def compose_view(view: View, sprites, textures: dict, samplers: dict | None = None):
    """The view as one friction texture (see the module docstring): ``sprites`` (all of the session's; those of
    other views and the hidden ones are left out), ``textures`` their textures by id, ``samplers`` a cache of
    samplers by texture id (kept between compositions)."""
    import numpy as np
    from ultraglide.textures.sampling import Sampler
    from ultraglide.textures.texture import Texture

    samplers = {} if samplers is None else samplers
    shown = stacked(s for s in sprites if s.view == view.name and s.visible)
    density = grid_density(view, shown, textures)
    cols = max(1, round(view.width_mm * density))
    rows = max(1, round(view.height_mm * density))
    pitch_x, pitch_y = view.width_mm / cols, view.height_mm / rows
    canvas = np.full((rows, cols), view.background_ratio, dtype=np.float32)
    for sprite in shown:
        texture = textures[sprite.texture]
        left, top, right, bottom = sprite.bounds_mm(view)
        c0, c1 = max(0, math.floor(left / pitch_x)), min(cols, math.ceil(right / pitch_x) + 1)
        r0, r1 = max(0, math.floor(top / pitch_y)), min(rows, math.ceil(bottom / pitch_y) + 1)
        if c0 >= c1 or r0 >= r1:
            continue
        gx, gy = np.meshgrid((np.arange(c0, c1) + 0.5) * pitch_x, (np.arange(r0, r1) + 0.5) * pitch_y)
        u, v = sprite.local_mm(view, gx, gy)
        w, h = sprite.size_mm(view)
        inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
        if not inside.any():
            continue
        sampler = samplers.get(sprite.texture)
        if sampler is None:
            sampler = samplers[sprite.texture] = Sampler(texture, band_limited=False)
        tx = u[inside] * (texture.width_mm / w)
        ty = v[inside] * (texture.height_mm / h)
        ratio = sampler.ratio(tx, ty, direction=(np.ones_like(tx), np.zeros_like(tx)))
        block = canvas[r0:r1, c0:c1]
        block[inside] = np.clip(ratio, 0.0, 1.0)
    names = ", ".join(f"{s.name} ({textures[s.texture].name or s.texture})" for s in shown) or "background only"
    return Texture(canvas, float(view.width_mm), float(view.height_mm), outside="fixed",
                   outside_ratio=view.background_ratio, name=f"view {view.name}", description=names,
                   source="ultraglide serve", authoring={"px_per_mm": density})


def _right_angled(sprite: Sprite) -> bool:
    return math.isclose(math.remainder(sprite.rotation_deg, 90.0), 0.0, abs_tol=1e-9)


def _rectangles(mask, xs, ys) -> list[tuple[float, float, float, float]]:
    """The cells of ``mask`` (rows × columns; cell (i, j) spans xs[j]..xs[j+1] × ys[i]..ys[i+1] mm) as rectangles
    (x, y, width, height) mm: each row's runs, a run carried down while the next row has the same one."""
    import numpy as np

    out = []
    open_runs: dict[tuple[int, int], int] = {}  # (first column, past the last) -> the row it began at
    for i in range(mask.shape[0] + 1):
        runs = set()
        if i < mask.shape[0]:
            edges = np.flatnonzero(np.diff(np.concatenate(([0], mask[i].astype(np.int8), [0]))))
            runs = {(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)}
        for run in [r for r in open_runs if r not in runs]:
            start = open_runs.pop(run)
            out.append((float(xs[run[0]]), float(ys[start]), float(xs[run[1]] - xs[run[0]]), float(ys[i] - ys[start])))
        for run in runs:
            open_runs.setdefault(run, i)
    return out


def sprite_regions(view: View, sprites, name: str, max_rectangles: int, finest_mm: float = 0.25):
    """Where a sprite is felt, as at most ``max_rectangles`` axis-aligned rectangles (x, y, width, height) in mm
    on the view (the composed texture's coordinates): the part of its rectangle where it is the topmost shown
    sprite, within the view. [] when it is hidden or wholly covered; None when no set of that many rectangles
    follows it (see below).

    Where the sprite and every sprite over it are turned by a multiple of 90 degrees, the rectangles are exact:
    the cells between their edges, each judged at its centre. A sprite turned otherwise (itself, or one over it)
    has no exact set of axis-aligned rectangles: the cells are also cut every ``finest_mm`` (and coarser, by
    steps of 1.5×, until the rectangles are few enough), a staircase whose steps are that pitch.
    """
    import numpy as np

    shown = stacked(s for s in sprites if s.view == view.name and s.visible)
    index = next((k for k, s in enumerate(shown) if s.name == name), None)
    if index is None:
        return []
    target = shown[index]
    left, top, right, bottom = target.bounds_mm(view)
    left, top = max(left, 0.0), max(top, 0.0)
    right, bottom = min(right, view.width_mm), min(bottom, view.height_mm)
    if right <= left or bottom <= top:
        return []

    def overlaps(sprite):
        a, b, c, d = sprite.bounds_mm(view)
        return a < right and c > left and b < bottom and d > top

    over = [s for s in shown[index + 1:] if overlaps(s)]
    edges_x, edges_y = {left, right}, {top, bottom}
    for sprite in [target, *over]:
        a, b, c, d = sprite.bounds_mm(view)
        edges_x.update(v for v in (a, c) if left < v < right)
        edges_y.update(v for v in (b, d) if top < v < bottom)
    exact = all(_right_angled(s) for s in [target, *over])
    pitch = finest_mm
    while True:
        xs, ys = set(edges_x), set(edges_y)
        if not exact:
            xs.update(np.arange(math.ceil(left / pitch), math.floor(right / pitch) + 1) * pitch)
            ys.update(np.arange(math.ceil(top / pitch), math.floor(bottom / pitch) + 1) * pitch)
        xs = np.array(sorted(v for v in xs if left <= v <= right))
        ys = np.array(sorted(v for v in ys if top <= v <= bottom))
        xs, ys = xs[np.concatenate(([True], np.diff(xs) > 1e-9))], ys[np.concatenate(([True], np.diff(ys) > 1e-9))]
        gx, gy = np.meshgrid((xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2)
        on_top = np.full(gx.shape, -1)
        for k, sprite in enumerate([target, *over]):
            u, v = sprite.local_mm(view, gx, gy)
            w, h = sprite.size_mm(view)
            on_top[(u >= 0) & (u < w) & (v >= 0) & (v < h)] = k
        rectangles = _rectangles(on_top == 0, xs, ys)
        if len(rectangles) <= max_rectangles:
            return rectangles
        if exact or pitch > max(right - left, bottom - top):
            return None
        pitch *= 1.5
