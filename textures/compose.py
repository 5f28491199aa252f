"""Several textures placed on one canvas: the widgets scene of the demo, UI mock-ups."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture


@dataclass(frozen=True)
class Placement:
    """A texture's top-left corner on the canvas, mm."""

    texture: Texture
    x_mm: float
    y_mm: float

    def contains(self, x_mm: float, y_mm: float) -> bool:
        return (self.x_mm <= x_mm < self.x_mm + self.texture.width_mm
                and self.y_mm <= y_mm < self.y_mm + self.texture.height_mm)


def compose(size_mm: tuple[float, float], placements: list[Placement], background_ratio: float = 1.0,
            px_per_mm: float = 10.0, name: str = "composition") -> Texture:
    """A friction texture of ``size_mm`` with each placed texture's friction pasted where it sits;
    elsewhere ``background_ratio`` (1: bare glass, at rest)."""
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
    return Texture(canvas, float(size_mm[0]), float(size_mm[1]), outside="fixed", outside_ratio=background_ratio,
                   name=name, description=", ".join(p.texture.name for p in placements), source="composed")
