"""A picture of a texture for its author: the source, the friction map, and a swipe across it."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from ultraglide.apps.cli.files import atomic_path  # noqa: E402
from ultraglide.textures.sampling import Sampler  # noqa: E402
from ultraglide.textures.texture import Texture  # noqa: E402


def write_preview(texture: Texture, path: Path, source: np.ndarray | None = None) -> Path:
    """Write a PNG with the source image (if given), the friction map with a colour bar, and the
    friction along a left-to-right swipe through the middle."""
    panels = 3 if source is not None else 2
    figure, axes = plt.subplots(1, panels, figsize=(5 * panels, 4.2))
    extent = (0, texture.width_mm, texture.height_mm, 0)
    index = 0
    if source is not None:
        axes[0].imshow(source, cmap="gray", vmin=0, vmax=1, extent=extent)
        axes[0].set(title="source (luminance)", xlabel="x (mm)", ylabel="y (mm)")
        index = 1
    ratio = texture.ratio_map()
    image = axes[index].imshow(ratio, cmap="viridis", vmin=0, vmax=1, extent=extent, interpolation="nearest")
    axes[index].axhline(texture.height_mm / 2, color="w", ls="--", lw=1)
    axes[index].set(title=f"friction ratio: {texture.name}", xlabel="x (mm)", ylabel="y (mm)")
    figure.colorbar(image, ax=axes[index], label="friction ratio µ/µ0 (1 = at rest)")
    x = np.linspace(0, texture.width_mm, 2000, endpoint=False)
    y = np.full_like(x, texture.height_mm / 2)
    swipe = Sampler(texture).ratio(x, y, direction=(np.ones_like(x), np.zeros_like(x)))
    axes[index + 1].plot(x, swipe)
    axes[index + 1].set(title="left-to-right swipe along the dashed line", xlabel="x (mm)",
                        ylabel="friction ratio", ylim=(0, 1.05))
    axes[index + 1].grid(alpha=0.3)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=100, format="png")
    plt.close(figure)
    return path
