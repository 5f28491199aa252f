"""Where things go on the demo's screen: the status line at the top, the texture area, the chart, the toolbar
at the bottom, and the gallery's tiles in the texture area."""

from __future__ import annotations

from dataclasses import dataclass

TOOLBAR = (("Gallery", "gallery"), ("Texture", "texture"), ("Widgets", "widgets"), ("< Prev", "prev"),
           ("Next >", "next"), ("Force −", "force-"), ("Force +", "force+"), ("Model", "model"),
           ("Pause", "pause"), ("Help", "help"), ("Quit", "quit"))


@dataclass
class Button:
    label: str
    action: str
    rect: object = None


class Layout:
    """The screen's rectangles (pygame Rects, px) for a screen of ``size`` px, text of ``line_h`` px a line,
    and ``tile_count`` textures in the gallery."""

    def __init__(self, pg, size: tuple[int, int], line_h: int, tile_count: int):
        w, h = size
        self.line_h = line_h
        self.status_rect = pg.Rect(0, 0, w, 2 * line_h + 12)  # two lines: the plate, and what is around it
        self.toolbar_rect = pg.Rect(0, h - 64, w, 64)
        chart_h = max(120, min(200, h // 5))
        self.chart_rect = pg.Rect(0, self.toolbar_rect.top - chart_h, w, chart_h)
        self.area = pg.Rect(0, self.status_rect.bottom, w, self.chart_rect.top - self.status_rect.bottom)
        self.buttons = [Button(label, action) for label, action in TOOLBAR]
        width = w // len(self.buttons)
        for i, button in enumerate(self.buttons):
            button.rect = pg.Rect(i * width + 4, self.toolbar_rect.top + 8, width - 8, 48)
        self.tiles = gallery_tiles(pg, self.area, tile_count)
        self.label_h = line_h + 4  # a tile's name under its picture

    def button_at(self, x_px: float, y_px: float) -> Button | None:
        return next((button for button in self.buttons if button.rect.collidepoint(x_px, y_px)), None)

    def tile_at(self, x_px: float, y_px: float) -> int | None:
        return next((i for i, tile in enumerate(self.tiles) if tile.collidepoint(x_px, y_px)), None)

    def thumbnail_size(self, index: int) -> tuple[int, int]:
        """The picture's room in a tile, px (the tile less its label and a border)."""
        tile = self.tiles[index]
        return tile.width - 4, tile.height - self.label_h - 4


def gallery_tiles(pg, area, count: int) -> list:
    """``count`` tiles in rows over ``area``, the largest with which every texture fits (10 px apart)."""
    for columns in range(1, count + 1):
        tile_w = (area.width - 10) // columns - 10
        tile_h = int(tile_w * 0.675)
        if -(-count // columns) * (tile_h + 10) + 10 <= area.height:
            break
    tiles = []
    for i in range(count):
        row, col = divmod(i, columns)
        tiles.append(pg.Rect(area.left + 10 + col * (tile_w + 10), area.top + 10 + row * (tile_h + 10), tile_w, tile_h))
    return tiles
