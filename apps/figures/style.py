"""One look for every figure ultraglide draws, and saving at print quality: vector and 300 dpi PNG."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from ultraglide.apps.cli.files import atomic_path  # noqa: E402

PNG_DPI = 300
STYLE = {
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 7.5,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.4,
    "lines.markersize": 4.5,
    "savefig.bbox": "tight",
    "pdf.fonttype": 42,  # TrueType in PDFs: text stays text for journals
    "svg.fonttype": "none",
}
VECTOR_FORMATS = ("pdf", "svg")


def figure(*args, **kwargs):
    """plt.subplots under the house style."""
    with plt.rc_context(STYLE):
        return plt.subplots(*args, **kwargs)


def mosaic(layout, **kwargs):
    """plt.subplot_mosaic under the house style, with constrained layout."""
    with plt.rc_context(STYLE):
        return plt.subplot_mosaic(layout, layout="constrained", **kwargs)


def save(fig, path: Path, vector: str | None = "pdf") -> list[Path]:
    """Write ``path`` (its suffix names the format; PNG at 300 dpi) and, if ``vector`` is given and
    ``path`` is a PNG, the same figure as a vector file beside it. Each is written atomically."""
    path = Path(path)
    written = []
    targets = [path]
    if vector and path.suffix.lower() == ".png":
        targets.append(path.with_suffix(f".{vector}"))
    with plt.rc_context(STYLE):
        if fig.get_layout_engine() is None:
            fig.tight_layout()
        for target in targets:
            with atomic_path(target) as temporary:
                fig.savefig(temporary, dpi=PNG_DPI, format=target.suffix.lstrip(".").lower())
            written.append(target)
    plt.close(fig)
    return written
