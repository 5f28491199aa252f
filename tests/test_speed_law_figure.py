"""The speed law's figure (the reduction against amplitude at three speeds) at print width: no text below 8 pt,
none overlapping (tests/pdf_text.py)."""

import pytest
from test_figures_print import assert_readable
from ultraglide.render.physics.calibration import load_model


@pytest.mark.parametrize("width", ["column", "page"])
def test_the_speed_law_figure_reads_at_print_width(tmp_path, width):
    from ultraglide.apps.figures.speed_law import speed_figure

    written = speed_figure(tmp_path / "speed-law.png", load_model("speed:0.5:stretched"), 0.5, 6.0, width)
    assert [path.name for path in written] == ["speed-law.png", "speed-law.pdf"]
    assert_readable(tmp_path / "speed-law.pdf", width)
