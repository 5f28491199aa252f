"""Every figure at print width: its PDF read back (pdfminer.six, tests/pdf_text.py) has no text below
8 pt printed one IEEE column (3.5 in) or two (7.16 in) wide, and no two strings that overlap."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pdf_text import problems, read_strings
from ultraglide.apps.figures.style import COLUMN_IN, PAGE_IN

ROOT = Path(__file__).resolve().parent.parent
WIDTHS = {"column": COLUMN_IN, "page": PAGE_IN}


def assert_readable(pdf: Path, width: str) -> None:
    found = problems(pdf, WIDTHS[width])
    assert not found, f"{pdf.name} at {WIDTHS[width]} in: " + "; ".join(found[:8])


def test_the_checker_sees_small_and_overlapping_text(tmp_path):
    import matplotlib.pyplot as plt

    with plt.rc_context({"savefig.bbox": "standard"}):  # the whole 3.5 in page, not the text's box
        fig = plt.figure(figsize=(3.5, 2))
        fig.text(0.1, 0.5, "small", fontsize=6)
        fig.text(0.5, 0.5, "one label", fontsize=9)
        fig.text(0.55, 0.5, "other label", fontsize=9)
        fig.savefig(tmp_path / "bad.pdf")
        plt.close(fig)
    width, strings = read_strings(tmp_path / "bad.pdf")
    assert width == pytest.approx(252.0)
    assert {s.text for s in strings} == {"small", "onelabel", "otherlabel"}  # pdfminer drops the spaces
    found = problems(tmp_path / "bad.pdf")
    assert any("'small' is 6.00 pt" in line for line in found)
    assert any("overlaps" in line and "onelabel" in line for line in found)
    assert not any("small" in line for line in problems(tmp_path / "bad.pdf", min_pt=5.0) if "overlaps" not in line)


@pytest.mark.slow
@pytest.mark.parametrize("width", ["column", "page"])
def test_the_papers_figures_and_the_model_report_read_at_print_width(tmp_path, width):
    from ultraglide.apps.commands.model import summary
    from ultraglide.apps.figures.model_report import write_report
    from ultraglide.apps.figures.paper import write_paper_figures
    from ultraglide.render.physics.fingerprint import FingerParams
    from ultraglide.render.physics.friction_models import PaperModel, StretchedExponentialModel

    data = ROOT / "apps" / "data" / "monnoyer2018-fit.csv"
    pngs = write_paper_figures(tmp_path, data, FingerParams(), None, StretchedExponentialModel(), width)
    assert len(pngs) == 8
    for png in pngs:
        assert_readable(png.with_suffix(".pdf"), width)
    for model in (PaperModel(), StretchedExponentialModel()):
        report = tmp_path / f"report-{model.name}.pdf"
        params = model.params if isinstance(model, PaperModel) else None
        write_report(report, model, summary(0.3, model, None), params, width)
        assert_readable(report, width)
        text = "".join(s.text for s in read_strings(report)[1])
        assert ("contactarea" in text) == (params is not None)  # a law without a contact says nothing of one


@pytest.mark.slow
@pytest.mark.parametrize("width", ["column", "page"])
def test_the_calibration_figure_reads_at_print_width_with_a_band_per_force(tmp_path, width):
    from ultraglide.apps.figures.calibration import write_calibration_figure
    from ultraglide.render.physics.calibration import compare_models
    from ultraglide.render.physics.friction_models import StretchedExponentialModel
    from ultraglide.render.physics.measurements import Measurements

    rng = np.random.default_rng(4)
    amplitude = np.tile(np.arange(0.0, 6.01, 0.5), 3)
    force = np.repeat([0.2, 0.5, 1.0], 13)
    ratio = StretchedExponentialModel(3.5, 1.8, 0.4).relative_friction(amplitude, force) + rng.normal(0, 0.02, 39)
    data = Measurements(amplitude, np.clip(ratio, 0, 1.2), force, "synthetic-three-forces.csv")
    fits = compare_models(data, ("stretched", "exponential", "table"))
    pdf = write_calibration_figure(fits, tmp_path / "cal.png", width)[1]
    assert_readable(pdf, width)
    text = "".join(s.text for s in read_strings(pdf)[1])
    assert "synthetic-three-forces.csv" in text and "fit±2rms,0.2N" in text and "3forces" in text


@pytest.mark.slow
@pytest.mark.parametrize("width", ["column", "page"])
def test_the_plate_sweep_figure_reads_at_print_width(tmp_path, width):
    from ultraglide.apps.figures.sweep import plot_sweep
    from ultraglide.devices.characterisation.resonance import ResonanceFit
    from ultraglide.devices.characterisation.sweep import SweepPoint

    fit = ResonanceFit(25_000.0, 180.0, 8.0, 1.5, 3.0, 0.05, 0.01)
    points = [SweepPoint(f, float(fit.amplitude_um_pp(f)) * 0.15, 0.15, True) for f in np.linspace(23e3, 27e3, 41)]
    plot_sweep(tmp_path / "sweep.pdf", points, fit, 0.15, width)
    assert_readable(tmp_path / "sweep.pdf", width)


@pytest.mark.slow
def test_the_experiment_figures_read_at_a_column(tmp_path):
    from conftest import run_cli

    out = tmp_path / "session"
    run_cli("experiment", "threshold", "grating-1mm", "--method", "staircase", "--trials", "30", "--observer",
            "sim:threshold=0.08,slope=3", "--out", out, check=True)
    for name in ("track.pdf", "psychometric.pdf"):
        assert_readable(out / name, "column")


@pytest.mark.slow
@pytest.mark.parametrize("width", ["column", "page"])
def test_export_plot_and_texture_show_read_at_print_width(tmp_path, width):
    from conftest import run_cli

    run_cli("export", "grating-1mm", "-o", tmp_path / "a.wav", "--duration-s", "1", "--plot", tmp_path / "plot.pdf",
            "--figure-width", width, check=True)
    assert_readable(tmp_path / "plot.pdf", width)
    run_cli("texture", "show", "wood", "-o", tmp_path / "wood.pdf", "--figure-width", width, check=True)
    assert_readable(tmp_path / "wood.pdf", width)
    page_pt = read_strings(tmp_path / "wood.pdf")[0]
    assert page_pt == pytest.approx(WIDTHS[width] * 72, abs=0.5)  # the whole page: 1 mm drawn is 1 mm printed


def _embedded_fonts(pdf: Path) -> list[bytes]:
    """The font programs a PDF embeds (FontFile2: TrueType), read with pdfminer's object parser."""
    from pdfminer.pdfdocument import PDFDocument
    from pdfminer.pdfparser import PDFParser
    from pdfminer.pdftypes import resolve1

    fonts = []
    with open(pdf, "rb") as handle:
        document = PDFDocument(PDFParser(handle))
        for xref in document.xrefs:
            for number in xref.get_objids():
                found = resolve1(document.getobj(number))
                if isinstance(found, dict) and "FontFile2" in found:
                    fonts.append(resolve1(found["FontFile2"]).get_data())
    return fonts


def test_a_figures_pdf_embeds_its_fonts_without_their_layout_tables_and_its_text_reads_back(tmp_path):
    """A viewer never shapes a PDF's text: the layout tables (GSUB, GPOS, GDEF) of the fonts it embeds are dead
    weight, and subsetting them was a third of a PDF's save. The fonts are embedded (Type 42) with their outlines
    and character map; the text reads back as drawn."""
    import io

    from fontTools.ttLib import TTFont
    from ultraglide.apps.figures import style

    fig, ax = style.figure(figsize=(style.COLUMN_IN, 2.4))
    ax.plot([0, 1, 2], [0.3, 0.5, 0.4], label="friction ratio − fit")
    ax.set_xlabel("amplitude (µm p-p)")
    ax.set_ylabel("ratio")
    style.legend_below(ax)
    pdf = style.save(fig, tmp_path / "f.png")[1]
    fonts = [TTFont(io.BytesIO(data)) for data in _embedded_fonts(pdf)]
    assert fonts, "no TrueType font embedded"
    for font in fonts:
        assert not {"GSUB", "GPOS", "GDEF"} & set(font.keys()), sorted(font.keys())
        assert {"glyf", "cmap", "hmtx"} <= set(font.keys())
        assert len(font.getGlyphOrder()) < 100  # a subset: the glyphs drawn, not the font's 6000
    assert max(len(font.getGlyphOrder()) for font in fonts) > 15
    text = "".join(s.text for s in read_strings(pdf)[1])
    assert "amplitude(µmp-p)" in text and "frictionratio−fit" in text  # pdfminer drops the spaces
