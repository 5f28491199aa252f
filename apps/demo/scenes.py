"""The demo's scenes: the gallery, one texture at its physical size, and widgets laid out for the screen.

:class:`Scenes` knows which scene is shown, the texture under the finger there, and where a pixel of the
texture area lies on it in millimetres; the widgets (a button, a slider with detents, a toggle, a keyboard)
are composed in memory for the area's size, with their temporal effects.
"""

from __future__ import annotations

import numpy as np
from ultraglide.textures.texture import Texture

SCENES = ("gallery", "texture", "widgets")


class Scenes:
    """The scene shown and its texture. ``area``: the texture area (a pygame Rect, px); ``mm_per_px``: the
    screen's pitch."""

    def __init__(self, textures: list[Texture], area, mm_per_px: float):
        self.textures = textures
        self.area = area
        self.mm_per_px = mm_per_px
        self.scene = "gallery"
        self.index = 0
        self._widgets: tuple[Texture, list] | None = None

    @property
    def current(self) -> Texture:
        """The texture the finger feels: the widgets' in that scene, else the chosen texture."""
        return self.widgets[0] if self.scene == "widgets" else self.textures[self.index]

    @property
    def widgets(self) -> tuple[Texture, list]:
        """The widgets' texture and their placements (composed on first use)."""
        if self._widgets is None:
            self._widgets = widgets_for_area((self.area.width * self.mm_per_px, self.area.height * self.mm_per_px))
        return self._widgets

    def show(self, scene: str, index: int | None = None) -> None:
        if index is not None:
            self.index = index % len(self.textures)
        self.scene = scene

    def step(self, by: int) -> None:
        """The next (``by`` = 1) or previous (−1) texture, shown."""
        self.show("texture", self.index + by)

    def replace(self, index: int, texture: Texture) -> Texture:
        """Put a reloaded texture in place of the one at ``index``; returns the old one."""
        old, self.textures[index] = self.textures[index], texture
        return old

    def to_mm(self, x_px: float, y_px: float) -> tuple[float, float] | None:
        """Screen pixels to millimetres on the texture, or None off the texture area (or in the gallery)."""
        if self.scene == "gallery" or not self.area.collidepoint(x_px, y_px):
            return None
        return (x_px - self.area.left) * self.mm_per_px, (y_px - self.area.top) * self.mm_per_px

    def flip_toggle_at(self, x_px: float, y_px: float) -> tuple[Texture, Texture] | None:
        """In the widgets scene, a press on the toggle flips it: (old texture, new texture), else None."""
        from ultraglide.textures import procedural
        from ultraglide.textures.compose import Placement

        if self.scene != "widgets":
            return None
        where = self.to_mm(x_px, y_px)
        texture, placements = self.widgets
        toggle = placements[2]
        if not where or not toggle.contains(*where):
            return None
        on = not toggle.texture.authoring.get("on", False)
        size = (toggle.texture.width_mm, toggle.texture.height_mm)
        placements[2] = Placement(procedural.toggle(size_mm=size, on=on), toggle.x_mm, toggle.y_mm)
        self._widgets = (compose_widgets((texture.width_mm, texture.height_mm), placements), placements)
        return texture, self._widgets[0]


def widgets_for_area(size_mm: tuple[float, float]) -> tuple[Texture, list]:
    """Button, slider, toggle and keyboard in a 2 × 2 grid that fills an area of ``size_mm``."""
    from ultraglide.textures import procedural
    from ultraglide.textures.compose import Placement

    width_mm, height_mm = size_mm
    margin = 8.0
    cell_w, cell_h = (width_mm - 3 * margin) / 2, (height_mm - 3 * margin) / 2

    def fit(most_w, most_h):
        return (round(min(cell_w, most_w), 1), round(min(cell_h, most_h), 1))

    button_size, slider_size = fit(80, 50), fit(140, 24)
    toggle_size, keyboard_size = fit(60, 34), fit(150, 50)

    def at(size, col, row):
        return (margin + col * (cell_w + margin) + (cell_w - size[0]) / 2,
                margin + row * (cell_h + margin) + (cell_h - size[1]) / 2)

    placements = [
        Placement(procedural.button(size_mm=button_size, button_mm=(button_size[0] * 0.7, button_size[1] * 0.6)),
                  *at(button_size, 0, 0)),
        Placement(procedural.slider(size_mm=slider_size, detents=6), *at(slider_size, 1, 0)),
        Placement(procedural.toggle(size_mm=toggle_size), *at(toggle_size, 0, 1)),
        Placement(procedural.keyboard(size_mm=keyboard_size, keys=(10, 3)), *at(keyboard_size, 1, 1)),
    ]
    return compose_widgets((width_mm, height_mm), placements), placements


def widget_effects(placements: list) -> tuple:
    """The widgets' temporal effects (mm on the composed texture): a click when the button is pressed,
    a pulse at each of the slider's detents and a buzz while it moves, a snap when the toggle is touched
    (it flips on press). ``placements``: button, slider, toggle, keyboard, as the widgets scene lays them."""
    from ultraglide.textures import effects

    button, slider, toggle = placements[:3]
    bw, bh = button.texture.width_mm, button.texture.height_mm
    face = (button.x_mm + bw * 0.15, button.y_mm + bh * 0.2, bw * 0.7, bh * 0.6)  # button_mm = 0.7 w × 0.6 h
    sw, sh = slider.texture.width_mm, slider.texture.height_mm
    detents = int(slider.texture.authoring.get("detents", 6))
    stops = slider.x_mm + np.linspace(0.08 * sw, 0.92 * sw, detents)  # as procedural.slider places them
    track = (slider.x_mm, slider.y_mm + 0.3 * sh, sw, 0.4 * sh)
    knob = (toggle.x_mm, toggle.y_mm, toggle.texture.width_mm, toggle.texture.height_mm)
    return (
        effects.Binding(effects.Trigger("start", face), effects.click(), label="button click"),
        effects.Binding(effects.Trigger("cross", track, lines_mm=tuple(float(v) for v in stops)), effects.pulse(),
                        label="slider detent"),
        effects.Binding(effects.Trigger("while", track, min_speed_mm_s=20.0), effects.buzz(), release_s=0.04,
                        label="slider buzz"),
        effects.Binding(effects.Trigger("start", knob), effects.snap(), label="toggle snap"),
    )


def compose_widgets(size_mm: tuple[float, float], placements: list) -> Texture:
    """The widgets scene's texture: the placed widgets with their effects."""
    from ultraglide.textures.compose import compose

    return compose(size_mm, placements, name="widgets").with_(effects=widget_effects(placements))
