"""The friction-in-time figures at print width: no text below 8 pt, none overlapping (tests/pdf_text.py)."""

from __future__ import annotations

import pytest
from test_figures_print import assert_readable
from ultraglide.render.physics.dynamics import FrictionDynamics


@pytest.mark.parametrize("width", ["column", "page"])
def test_friction_in_time_reads_at_print_width(tmp_path, width):
    from ultraglide.apps.figures.dynamics import friction_in_time

    friction_in_time(tmp_path / "friction-in-time.pdf", FrictionDynamics(), 0.168, width)
    assert_readable(tmp_path / "friction-in-time.pdf", width)


def test_contrast_transfer_reads_at_a_column(tmp_path):
    from ultraglide.apps.figures.dynamics import contrast_figure

    contrast_figure(tmp_path / "contrast-transfer.pdf", FrictionDynamics(), 0.168, "column")
    assert_readable(tmp_path / "contrast-transfer.pdf", "column")
