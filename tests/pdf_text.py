"""Text read back from a figure's PDF with pdfminer.six: each string's size and box, as printed at a width.

Matplotlib writes each text (a label, a tick, a legend entry) as its own text-showing operation; the
device below records each such string with its characters' effective font size (the font size times the
scale of the text matrix, so rotated and scaled text counts as printed) and its box. :func:`problems`
scales the page to a print width and lists text smaller than a minimum and pairs of strings whose boxes
overlap: what a reader of the printed figure would not be able to read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from pdfminer.converter import PDFPageAggregator
from pdfminer.layout import LTChar
from pdfminer.pdfinterp import PDFPageInterpreter, PDFResourceManager
from pdfminer.pdfpage import PDFPage


@dataclass
class String:
    """One text-showing operation: its characters, the smallest effective font size (pt) and its box."""

    text: str
    size: float
    box: tuple[float, float, float, float]  # x0, y0, x1, y1 in PDF points


class _Recorder(PDFPageAggregator):
    def __init__(self, manager):
        super().__init__(manager, laparams=None)
        self.strings: list[String] = []
        self._open = False

    def render_string(self, textstate, seq, ncs, graphicstate):
        self._open = True  # the characters of this call form one string
        self._new = True
        super().render_string(textstate, seq, ncs, graphicstate)

    def render_char(self, matrix, font, fontsize, scaling, rise, cid, ncs, graphicstate):
        advance = super().render_char(matrix, font, fontsize, scaling, rise, cid, ncs, graphicstate)
        item = self.cur_item._objs[-1]
        if isinstance(item, LTChar) and item.get_text().strip():
            a, b, c, d, _, _ = matrix
            size = fontsize * math.sqrt(abs(a * d - b * c))
            # the glyph body: from the baseline's descent to cap height, not the font's whole line box
            x0, y0, x1, y1 = item.bbox
            if getattr(self, "_new", True) or not self.strings:
                self.strings.append(String(item.get_text(), size, (x0, y0, x1, y1)))
                self._new = False
            else:
                last = self.strings[-1]
                last.text += item.get_text()
                last.size = min(last.size, size)
                bx0, by0, bx1, by1 = last.box
                last.box = (min(bx0, x0), min(by0, y0), max(bx1, x1), max(by1, y1))
        return advance


def read_strings(path: Path) -> tuple[float, list[String]]:
    """The first page's width (pt) and its strings."""
    manager = PDFResourceManager()
    device = _Recorder(manager)
    interpreter = PDFPageInterpreter(manager, device)
    with open(path, "rb") as stream:
        page = next(PDFPage.get_pages(stream))
        interpreter.process_page(page)
        width = page.mediabox[2] - page.mediabox[0]
    return float(width), device.strings


def _shrunk(box, size):
    """A string's box without the font's leading: a fifth of the size off top and bottom, a tenth off the ends."""
    x0, y0, x1, y1 = box
    horizontal = x1 - x0 >= y1 - y0 or (y1 - y0) < 1.5 * size
    if horizontal:
        return (x0 + 0.1 * size, y0 + 0.2 * size, x1 - 0.1 * size, y1 - 0.2 * size)
    return (x0 + 0.2 * size, y0 + 0.1 * size, x1 - 0.2 * size, y1 - 0.1 * size)


def problems(path: Path, print_width_in: float = 3.5, min_pt: float = 8.0) -> list[str]:
    """What would be unreadable with the PDF printed ``print_width_in`` wide: text below ``min_pt`` and
    overlapping strings, one line each."""
    width, strings = read_strings(path)
    scale = print_width_in * 72.0 / width
    found = []
    for s in strings:
        if s.size * scale < min_pt - 1e-6:
            found.append(f"{s.text!r} is {s.size * scale:.2f} pt printed {print_width_in} in wide")
    boxes = [_shrunk(s.box, s.size) for s in strings]
    for i in range(len(strings)):
        for j in range(i + 1, len(strings)):
            a, b = boxes[i], boxes[j]
            if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                found.append(f"{strings[i].text!r} overlaps {strings[j].text!r}")
    return found
