"""One look for every figure ultraglide draws, laid out for print: an IEEE column (3.5 in) or the
page's two columns (7.16 in), text of 8 pt or more at that size, saved as vector and 300 dpi PNG.

A figure is drawn at its print width (``width_in``, :data:`COLUMN_IN` unless a caller asks for
:data:`PAGE_IN`), so that its text keeps its size in print. Legends go beside or below the data
(never over it); fitted laws are lines, measurements markers.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from ultraglide.apps.cli.files import atomic_path  # noqa: E402

COLUMN_IN = 3.5  # one IEEE column
PAGE_IN = 7.16  # two IEEE columns
WIDTHS_IN = {"column": COLUMN_IN, "page": PAGE_IN}
MIN_TEXT_PT = 8.0
PNG_DPI = 300
STYLE = {
    "font.size": 8.5,
    "axes.titlesize": 9,
    "axes.labelsize": 8.5,
    "legend.fontsize": 8,
    "legend.title_fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "figure.titlesize": 9,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.2,
    "lines.markersize": 4,
    "legend.frameon": False,
    "legend.handlelength": 1.8,
    "legend.borderaxespad": 0.3,
    "axes.titlepad": 4,
    "savefig.bbox": "tight",
    "savefig.pad_inches": 0.03,
    "pdf.fonttype": 42,  # TrueType in PDFs: text stays text for journals
    "svg.fonttype": "none",
}
VECTOR_FORMATS = ("pdf", "svg")
matplotlib.rcParams.update(STYLE)  # legends and texts added after a figure is made take the house style too
LAYOUT_TABLES = ("GSUB", "GPOS", "GDEF")  # OpenType's substitution and positioning rules, for shaping text
EMBEDDING_FORMATS = ("pdf", "ps", "eps")  # formats that embed a subset of each font (Type 42)


def before_saving(fmt: str) -> None:
    """Call before saving a figure as ``fmt``: for a format that embeds fonts, leave their layout tables out.

    A PDF embeds the subset of each font its text uses; a viewer draws the glyphs the file names where the file
    puts them and never shapes text, so the layout tables are dead weight in it, and subsetting them (and the
    glyphs their rules reach) was a third of a figure's PDF (0.1 s of 0.3 s of CPU; 6 % of its bytes).
    Matplotlib subsets with fontTools's default options, whose list of tables to drop is a class attribute of
    fontTools's: left as it is should fontTools keep that list elsewhere (tests/test_figures_print.py reads the
    fonts a PDF embeds). fontTools is imported here, not with this module: 0.08 s a process that saves no PDF
    would not need."""
    if fmt.lower() not in EMBEDDING_FORMATS:
        return
    from fontTools import subset

    dropped = getattr(subset.Options, "_drop_tables_default", None)
    if isinstance(dropped, list) and not set(LAYOUT_TABLES) <= set(dropped):
        subset.Options._drop_tables_default = dropped + [t for t in LAYOUT_TABLES if t not in dropped]


def width_of(width: str | float | None) -> float:
    """A print width in inches from ``"column"``, ``"page"`` or a number (None: a column)."""
    if width is None:
        return COLUMN_IN
    if isinstance(width, str):
        return WIDTHS_IN[width]
    return float(width)


def figure(*args, **kwargs):
    """plt.subplots under the house style, with constrained layout unless another is asked for; the
    figure's width is its print width (see :func:`save`)."""
    kwargs.setdefault("layout", "constrained")
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(*args, **kwargs)
    fig.print_width_in = float(fig.get_size_inches()[0])
    return fig, axes


def mosaic(layout, **kwargs):
    """plt.subplot_mosaic under the house style, with constrained layout."""
    with plt.rc_context(STYLE):
        fig, axes = plt.subplot_mosaic(layout, layout="constrained", **kwargs)
    fig.print_width_in = float(fig.get_size_inches()[0])
    return fig, axes


def fit_print_width(fig):
    """Narrow a figure whose drawing (a long legend, a title) spills past its print width until the
    saved page is that wide, so that its text prints at the size it was set in. Returns the drawing's
    tight box (inches) as last drawn at its final size, or None when it has no print width or could not
    be fitted (a layout that cannot fit, or still spilling after four tries)."""
    target = getattr(fig, "print_width_in", None)
    if target is None:
        return None
    pad = 2 * float(plt.rcParams["savefig.pad_inches"])
    for _ in range(4):
        fig.draw_without_rendering()  # laid out and measured; the files draw it
        box = fig.get_tightbbox(fig.canvas.get_renderer())
        spill = box.width + pad - target
        if spill <= 0.002:
            return box
        width, height = fig.get_size_inches()
        if width - spill < 0.6 * target:  # a layout that cannot fit: leave it, the checks will say so
            return None
        fig.set_size_inches(width - spill - 0.002, height)
    return None


def print_layout(fig, dpi: float = PNG_DPI) -> dict:
    """Fit ``fig`` to its print width (:func:`fit_print_width`) laid out at ``dpi`` (the PNG's), and keep that
    layout: the savefig options that write it as laid out and measured then. savefig would otherwise lay the
    figure out and measure its tight box again for every file, at each file's resolution, each pass moving a
    legend placed beside its axes a little (constrained layout settles over passes): the PDF comes out as the PNG
    (laid out once more at 72 dpi, its text was up to 1.6 pt apart). The fit's last pass is that layout, so the
    figure is laid out no more times than the fit takes. A figure that could not be fitted is saved with a tight
    box as before."""
    pad = float(plt.rcParams["savefig.pad_inches"])
    drawn_dpi = fig.dpi
    fig.set_dpi(dpi)
    try:
        box = fit_print_width(fig)  # text measured at the resolution the PNG draws it at
    finally:
        fig.set_dpi(drawn_dpi)
    if box is None:
        return {"bbox_inches": "tight", "pad_inches": pad}
    with plt.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)  # None, not "none" (a placeholder engine, for which savefig lays out again)
    return {"bbox_inches": box.padded(pad)}


def legend_below(axis, ncol: int = 1, **kwargs):
    """A legend under the axes, clear of the data."""
    return axis.legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), ncol=ncol, **kwargs)


def legend_right(axis, **kwargs):
    """A legend to the right of the axes, clear of the data."""
    return axis.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), **kwargs)


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
        options = print_layout(fig)
        for target in targets:
            fmt = target.suffix.lstrip(".").lower()
            before_saving(fmt)
            with atomic_path(target) as temporary:
                fig.savefig(temporary, dpi=PNG_DPI, format=fmt, **options)
            written.append(target)
    plt.close(fig)
    return written
