"""``ultraglide demo``: feel textures on the plate under a touch panel (pygame).

Scenes: a gallery of textures, one texture at its physical size, and widgets (a button, a slider
with detents, a toggle, a keyboard). The first finger down drives the plate; other fingers are
drawn but ignored; a held mouse button counts as a finger, and SDL's mouse events synthesised from
touches are ignored so nothing counts twice. Events are polled every millisecond and reach the
renderer as they arrive; drawing runs at the display rate. Every way out rests the plate.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # before pygame is imported: no banner

import collections  # noqa: E402
import time  # noqa: E402
import warnings
from dataclasses import dataclass

import numpy as np
from ultraglide.apps.demo_draw import (
    ACCENT,
    BACKGROUND,
    DIM,
    OTHER_FINGER,
    PANEL,
    TEXT,
    blit_texture,
    draw_chart,
    draw_trace,
    friction_colours,
    texture_surface,
)
from ultraglide.apps.errors import UsageError
from ultraglide.apps.sources import source_for
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.urls import open_device
from ultraglide.render.calibration import load_model
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.textures import procedural
from ultraglide.textures.compose import Placement, compose
from ultraglide.textures.library import library_entries, resolve_texture
from ultraglide.textures.texture import Texture

DEFAULT_MM_PER_PX = 25.4 / 96  # when the screen's size is not given: a 96 dpi screen
FRAME_S = 1 / 60
POLL_S = 0.001
CHART_SPAN_S = 3.0
TRACE_S = 1.5
MODELS = ("exponential", "paper")
HEADLESS_DRIVERS = {"dummy", "offscreen"}


def display_available() -> bool:
    driver = os.environ.get("SDL_VIDEODRIVER", "")
    return bool(driver or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@dataclass
class Button:
    label: str
    action: str
    rect: object = None


class DemoApp:
    """The demo's state and loop; ``step()`` runs one poll (and a frame when one is due)."""

    def __init__(self, texture_specs=(), device_url="sim", profile="sim-plate", model="exponential",
                 screen_width_mm: float | None = None, windowed: bool = False, size=(1280, 800)):
        import pygame

        self.pg = pygame
        if not display_available():
            raise UsageError("no display to show the demo on (set DISPLAY or run under Xvfb); to render "
                             "without a screen use `ultraglide export`")
        try:
            pygame.display.init()
            pygame.font.init()
            flags = 0 if windowed else pygame.FULLSCREEN
            self.screen = pygame.display.set_mode((0, 0) if not windowed else size, flags)
        except pygame.error as error:
            raise UsageError(f"cannot open a window ({error}); to render without a screen use "
                             "`ultraglide export`") from None
        pygame.display.set_caption("ultraglide demo")
        width_px = self.screen.get_width()
        self.mm_per_px = screen_width_mm / width_px if screen_width_mm else DEFAULT_MM_PER_PX
        self.font = pygame.font.Font(None, 22)
        self.big_font = pygame.font.Font(None, 30)
        self.textures = self._load_textures(texture_specs)
        self.index = 0
        self.scene = "gallery"
        self.widgets = self._widgets()
        self.profile = load_profile(profile)
        self.model_name = model
        friction_model = load_model(model)  # bad options fail here, before a device is opened
        self.device = open_device(device_url, self.profile)
        try:
            rate = self.device.rate_hz if self.device.signal == "audio" else 96000
            self.renderer = Renderer(self.textures[0], friction_model, self.profile,
                                     RenderSettings(audio_rate_hz=rate))
        except BaseException:
            self.device.stop()
            raise
        self.renderer.pause(True)  # at rest until a finger is on a texture
        self.chart = collections.deque(maxlen=4000)
        self.measured = collections.deque(maxlen=400)
        self.renderer.observers.append(self._observe)
        self.source = source_for(self.device, self.renderer)
        self.fingers: dict[int, tuple[float, float]] = {}
        self.driving: int | None = None  # the finger (or -1 for the mouse) that drives the plate
        self.trace: collections.deque = collections.deque()
        self.user_paused = False
        self.running = True
        self.pushed = 0
        self._surfaces: dict[int, object] = {}
        self._next_frame = 0.0
        self._layout()
        self.device.start(self.source)

    # ---- set-up --------------------------------------------------------------------------------
    def _load_textures(self, specs) -> list[Texture]:
        textures = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # plain images are authored with defaults, as documented
            for spec in specs:
                textures.append(resolve_texture(str(spec)))
            for entry in library_entries():
                textures.append(resolve_texture(entry.name))
        return textures

    def _widgets(self) -> tuple[Texture, list[Placement]]:
        placements = [
            Placement(procedural.button(size_mm=(50, 30), button_mm=(36, 18)), 10, 10),
            Placement(procedural.slider(size_mm=(90, 20), detents=6), 70, 15),
            Placement(procedural.toggle(size_mm=(40, 24)), 10, 50),
            Placement(procedural.keyboard(size_mm=(110, 36), keys=(10, 3)), 60, 50),
        ]
        return compose((180, 95), placements, name="widgets"), placements

    def _layout(self) -> None:
        pg = self.pg
        w, h = self.screen.get_size()
        self.status_rect = pg.Rect(0, 0, w, 28)
        self.toolbar_rect = pg.Rect(0, h - 64, w, 64)
        self.chart_rect = pg.Rect(0, h - 64 - 130, w, 130)
        self.area = pg.Rect(0, 28, w, h - 28 - 64 - 130)
        self.buttons = [Button(label, action) for label, action in (
            ("Gallery", "gallery"), ("Texture", "texture"), ("Widgets", "widgets"), ("< Prev", "prev"),
            ("Next >", "next"), ("Force −", "force-"), ("Force +", "force+"), ("Model", "model"),
            ("Pause", "pause"), ("Quit", "quit"))]
        width = w // len(self.buttons)
        for i, button in enumerate(self.buttons):
            button.rect = pg.Rect(i * width + 4, self.toolbar_rect.top + 8, width - 8, 48)
        count = len(self.textures)
        for columns in range(1, count + 1):  # the largest tiles with which every texture fits
            tile_w = (self.area.width - 10) // columns - 10
            tile_h = int(tile_w * 0.675)
            if -(-count // columns) * (tile_h + 10) + 10 <= self.area.height:
                break
        self.tiles = []
        for i in range(count):
            row, col = divmod(i, columns)
            self.tiles.append(pg.Rect(self.area.left + 10 + col * (tile_w + 10),
                                      self.area.top + 10 + row * (tile_h + 10), tile_w, tile_h))

    # ---- what the plate feels --------------------------------------------------------------------
    @property
    def current(self) -> Texture:
        return self.widgets[0] if self.scene == "widgets" else self.textures[self.index]

    def _observe(self, block) -> None:  # runs on the device's thread: appends only
        self.chart.append((block.time_s[-1], float(np.mean(block.ratio)), float(np.mean(block.amplitude_um_pp))))

    def _show(self, scene: str, index: int | None = None) -> None:
        if index is not None:
            self.index = index % len(self.textures)
        self.scene = scene
        if scene != "gallery":
            self.renderer.set_texture(self.current)

    def _to_mm(self, x_px: float, y_px: float) -> tuple[float, float] | None:
        """Screen pixels to millimetres on the texture, or None off the texture area."""
        if self.scene == "gallery" or not self.area.collidepoint(x_px, y_px):
            return None
        return (x_px - self.area.left) * self.mm_per_px, (y_px - self.area.top) * self.mm_per_px

    def _drive(self, x_px: float, y_px: float, down: bool) -> None:
        now = time.perf_counter()
        where = self._to_mm(x_px, y_px) if down else None
        if where is None:
            self.renderer.push(now, 0.0, 0.0, down=False)
            self.renderer.pause(True)
            return
        self.renderer.pause(self.user_paused)
        self.renderer.push(now, where[0], where[1])
        self.pushed += 1
        self.trace.append((now, x_px, y_px))

    # ---- input -----------------------------------------------------------------------------------
    def _press(self, x_px: float, y_px: float) -> bool:
        """Toolbar buttons and gallery tiles; True when the press was for the interface."""
        for button in self.buttons:
            if button.rect.collidepoint(x_px, y_px):
                self._act(button.action)
                return True
        if self.scene == "gallery":
            for i, tile in enumerate(self.tiles):
                if tile.collidepoint(x_px, y_px):
                    self._show("texture", i)
                    return True
        if self.scene == "widgets":
            where = self._to_mm(x_px, y_px)
            toggle = self.widgets[1][2]
            if where and toggle.contains(*where):
                on = not toggle.texture.authoring.get("on", False)
                self.widgets[1][2] = Placement(procedural.toggle(size_mm=(40, 24), on=on), toggle.x_mm, toggle.y_mm)
                self.widgets = (compose((180, 95), self.widgets[1], name="widgets"), self.widgets[1])
                self._surfaces.pop(id(self.widgets[0]), None)
                self.renderer.set_texture(self.widgets[0])
        return False

    def _act(self, action: str) -> None:
        if action in ("gallery", "texture", "widgets"):
            self._show(action)
        elif action in ("prev", "next"):
            self._show("texture", self.index + (1 if action == "next" else -1))
        elif action in ("force-", "force+"):
            force = self.renderer.default_force_n * (1.25 if action == "force+" else 0.8)
            self.renderer.set_default_force(min(max(force, 0.05), 5.0))
        elif action == "model":
            self.model_name = MODELS[(MODELS.index(self.model_name) + 1) % len(MODELS)] \
                if self.model_name in MODELS else MODELS[0]
            self.renderer.set_model(load_model(self.model_name))
        elif action == "pause":
            self.user_paused = not self.user_paused
            self.renderer.pause(self.user_paused)
        elif action == "quit":
            self.running = False

    def handle(self, event) -> None:
        pg = self.pg
        w, h = self.screen.get_size()
        if event.type == pg.QUIT:
            self.running = False
        elif event.type == pg.KEYDOWN:
            keys = {pg.K_ESCAPE: "quit", pg.K_q: "quit", pg.K_g: "gallery", pg.K_t: "texture", pg.K_w: "widgets",
                    pg.K_LEFT: "prev", pg.K_RIGHT: "next", pg.K_DOWN: "force-", pg.K_UP: "force+",
                    pg.K_m: "model", pg.K_SPACE: "pause"}
            if event.key in keys:
                self._act(keys[event.key])
        elif event.type == pg.FINGERDOWN:
            x, y = event.x * w, event.y * h
            self.fingers[event.finger_id] = (x, y)
            if self.driving is None and not self._press(x, y):
                self.driving = event.finger_id
                self.trace.clear()
                self._drive(x, y, True)
        elif event.type == pg.FINGERMOTION:
            x, y = event.x * w, event.y * h
            self.fingers[event.finger_id] = (x, y)
            if event.finger_id == self.driving:
                self._drive(x, y, True)
        elif event.type == pg.FINGERUP:
            self.fingers.pop(event.finger_id, None)
            if event.finger_id == self.driving:
                self.driving = None
                self._drive(event.x * w, event.y * h, False)
        elif event.type in (pg.MOUSEBUTTONDOWN, pg.MOUSEMOTION, pg.MOUSEBUTTONUP):
            if getattr(event, "touch", False):
                return  # SDL's copy of a touch: the finger events above already count it
            x, y = event.pos
            if event.type == pg.MOUSEBUTTONDOWN and event.button == 1 and self.driving is None:
                if not self._press(x, y):
                    self.driving = -1
                    self.trace.clear()
                    self._drive(x, y, True)
            elif event.type == pg.MOUSEMOTION and self.driving == -1:
                self._drive(x, y, True)
            elif event.type == pg.MOUSEBUTTONUP and event.button == 1 and self.driving == -1:
                self.driving = None
                self._drive(x, y, False)

    # ---- drawing ---------------------------------------------------------------------------------
    def _surface(self, texture: Texture):
        key = id(texture)
        if key not in self._surfaces:
            self._surfaces[key] = texture_surface(texture, self.mm_per_px)
        return self._surfaces[key]

    def draw(self) -> None:
        pg, screen = self.pg, self.screen
        screen.fill(BACKGROUND)
        if self.scene == "gallery":
            for texture, tile in zip(self.textures, self.tiles, strict=True):
                if tile.bottom > self.area.bottom:
                    break
                thumb = pg.surfarray.make_surface(np.ascontiguousarray(
                    friction_colours(texture.ratio_map()[::4, ::4]).transpose(1, 0, 2)))
                screen.blit(pg.transform.smoothscale(thumb, (tile.width, tile.height - 24)), tile.topleft)
                pg.draw.rect(screen, DIM, tile, 1)
                screen.blit(self.font.render(texture.name, True, TEXT), (tile.left + 4, tile.bottom - 20))
        else:
            texture = self.current
            outside = friction_colours(np.array([[texture.outside_ratio]]))[0, 0].tolist()
            blit_texture(screen, self._surface(texture), self.area, texture.outside == "tile", outside)
            label = f"{texture.name}: {texture.width_mm:g} × {texture.height_mm:g} mm, {texture.description}"
            text = self.font.render(label, True, ACCENT)
            backing = text.get_rect(bottomleft=(self.area.left + 8, self.area.bottom - 6)).inflate(12, 8)
            pg.draw.rect(screen, PANEL, backing, border_radius=4)
            screen.blit(text, text.get_rect(center=backing.center))
        now = time.perf_counter()
        while self.trace and now - self.trace[0][0] > TRACE_S:
            self.trace.popleft()
        draw_trace(screen, [(x, y) for _, x, y in self.trace])
        for finger, (x, y) in self.fingers.items():
            if finger != self.driving:
                pg.draw.circle(screen, OTHER_FINGER, (int(x), int(y)), 14, 2)
        telemetry = getattr(self.device, "telemetry", None)
        if telemetry is not None:
            self.measured.append((now, telemetry.measured_um_pp))
        chart = np.array(self.chart) if self.chart else np.zeros((0, 3))
        series = {"friction": chart[:, [0, 1]], "amplitude": chart[:, [0, 2]]}
        if self.measured:
            series["measured"] = np.array(self.measured)
        if len(chart):
            latest = chart[-1, 0]
            series = {k: v[v[:, 0] > latest - CHART_SPAN_S] for k, v in series.items()}
        draw_chart(screen, self.font, self.chart_rect, series, CHART_SPAN_S, self.profile.full_scale_um_pp)
        self._draw_status()
        self._draw_toolbar()
        pg.display.flip()

    def _status_text(self) -> str:
        c = self.renderer.counters
        status = self.device.status()
        underruns = status.get("underruns", status.get("late_blocks", 0))
        times = c.render_times_s[-500:]
        render_us = np.percentile(times, 99) * 1e6 if times else 0.0
        return (f"{status['device']}  |  {self.profile.name}  |  carrier {self.renderer.carrier_hz / 1000:g} kHz  |  "
                f"{'audio ' + str(self.device.rate_hz) + ' Hz' if self.device.signal == 'audio' else 'control 12 kHz'}"
                f"  |  model {self.model_name}  |  force {self.renderer.default_force_n:.2f} N  |  underruns "
                f"{underruns}  |  clipped {c.clipped_samples}  |  render p99 {render_us:.0f} µs"
                f"  |  lookahead {self.renderer.settings.lookahead_s * 1000:.0f} ms"
                f"{'  |  PAUSED' if self.user_paused else ''}")

    def _draw_status(self) -> None:
        self.pg.draw.rect(self.screen, PANEL, self.status_rect)
        self.screen.blit(self.font.render(self._status_text(), True, TEXT), (8, 6))

    def _draw_toolbar(self) -> None:
        pg = self.pg
        pg.draw.rect(self.screen, PANEL, self.toolbar_rect)
        for button in self.buttons:
            active = button.action == self.scene or (button.action == "pause" and self.user_paused)
            pg.draw.rect(self.screen, ACCENT if active else DIM, button.rect, 0 if active else 2, border_radius=8)
            text = self.big_font.render(button.label, True, BACKGROUND if active else TEXT)
            self.screen.blit(text, text.get_rect(center=button.rect.center))

    # ---- the loop --------------------------------------------------------------------------------
    def step(self) -> None:
        for event in self.pg.event.get():
            self.handle(event)
        now = time.perf_counter()
        if now >= self._next_frame:
            self._next_frame = now + FRAME_S
            self.draw()

    def run(self) -> None:
        while self.running:
            self.step()
            time.sleep(POLL_S)

    def close(self) -> None:
        """Rest the plate and close the window; safe to call more than once."""
        if not getattr(self, "_closed", False):
            self._closed = True
            self.device.stop()
            self.pg.display.quit()


def run(args) -> int:
    app = DemoApp(args.textures, args.device, args.profile, args.model, args.screen_width_mm, args.windowed)
    try:
        app.run()
    finally:
        app.close()  # window closed, Escape, Ctrl-C or an exception: the plate comes to rest
    return 0
