"""The picture ``ultraglide export --plot`` draws: friction, amplitude and position over time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from ultraglide.apps.atomic import atomic_path  # noqa: E402


def plot_envelope(data: np.ndarray, path: Path, renderer) -> Path:
    """``data`` columns: t, x, y, down, ratio, target, amplitude, drive, plate (see export)."""
    t, x, y, _, ratio, target, amplitude, drive, plate = data.T if len(data) else [np.zeros(0)] * 9
    figure, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    axes[0].plot(t, ratio, lw=0.8)
    axes[0].set(ylabel="target friction ratio", ylim=(0, 1.05), title=f"{renderer.texture.name}: "
                f"{renderer.model.describe()}")
    axes[1].plot(t, target, lw=0.8, label="model target")
    axes[1].plot(t, drive, lw=0.8, label="drive (pre-compensated)")
    axes[1].plot(t, plate, lw=0.8, label="plate (modelled)")
    axes[1].axhline(renderer.limit_um_pp, color="r", ls="--", lw=0.8, label="plate limit")
    axes[1].set(ylabel="amplitude (µm p-p)")
    axes[1].legend(fontsize=8, loc="upper right")
    axes[2].plot(t, x, lw=0.8, label="x")
    axes[2].plot(t, y, lw=0.8, label="y")
    axes[2].set(ylabel="position (mm)", xlabel="time (s)")
    axes[2].legend(fontsize=8)
    for axis in axes:
        axis.grid(alpha=0.3)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=100, format="png")
    plt.close(figure)
    return path
