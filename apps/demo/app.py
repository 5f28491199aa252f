"""``ultraglide demo``: feel textures on the plate under a touch panel (pygame).

Scenes: a gallery of textures, one texture at its physical size, and widgets (a button, a slider
with detents, a toggle, a keyboard) laid out for the screen. The first finger down drives the plate;
other fingers are drawn but ignored; a held mouse button counts as a finger, and SDL's mouse events
synthesised from touches are ignored so nothing counts twice. Touch pressure sets the force where
the panel reports it, the arrow keys otherwise.

The window comes first: the gallery is drawn, then the real-time engine (renderer and device in their
own process) starts from a thread and compiles its kernels while the gallery is on screen; touches
before it is ready are drawn, counted and not felt. The loop sleeps in SDL (``demo_wait``) and
redraws only what changed: the texture area while a finger moves or its trace fades, the chart while
the plate is active, the status line when its words change. All contact with the renderer and the
device goes through :class:`ultraglide.apps.demo.link.DemoLink`. With ``watch``, texture files (and
the images they were authored from) are polled every 200 ms and reloaded when they change. Every
way out rests the plate.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # before pygame is imported: no banner
# The window's pixels go to X directly (shared memory). Otherwise SDL may put them through OpenGL,
# which without a GPU is Mesa's llvmpipe: two software-rendering threads costing a third of a core.
os.environ.setdefault("SDL_FRAMEBUFFER_ACCELERATION", "0")

import collections  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from ultraglide.apps.cli.errors import UsageError  # noqa: E402
from ultraglide.apps.cli.signals import held  # noqa: E402
from ultraglide.apps.demo.draw import (  # noqa: E402
    ACCENT,
    BACKGROUND,
    DIM,
    OTHER_FINGER,
    PANEL,
    TEXT,
    blit_texture,
    draw_chart,
    draw_help,
    draw_trace,
    fit_text,
    friction_colours,
    texture_surface,
    thumbnail,
)
from ultraglide.apps.demo.link import DemoLink, LinkConfig, LinkStarter  # noqa: E402
from ultraglide.apps.demo.record import TouchRecorder  # noqa: E402
from ultraglide.apps.demo.wait import EventWaiter  # noqa: E402
from ultraglide.textures.texture import Texture  # noqa: E402

DEFAULT_MM_PER_PX = 25.4 / 96  # when the screen's size is not given: a 96 dpi screen
AREA_FRAME_S = 1 / 60  # the texture area while a finger moves or its trace fades
CHART_FRAME_S = 1 / 20  # the chart while the plate is active
STATUS_S = 0.25  # the status line's words are checked this often
IDLE_WAIT_S = 0.5  # the longest the loop sleeps when nothing moves
CHART_SPAN_S = 3.0
TRACE_S = 1.5
MODELS = ("exponential", "paper")
PRESSURE_FULL_SCALE_N = 2.0  # a panel's pressure 1.0 is taken as this force
FORCE_RANGE_N = (0.05, 5.0)
HELP = [
    ("touch / mouse", "drag on a texture to feel it; tap a tile in the gallery to open it"),
    ("second finger", "shown, but only the first finger drives the plate"),
    ("pressure", "sets the force where the panel reports it"),
    ("G  T  W", "gallery, texture, widgets"),
    ("Left  Right", "previous, next texture"),
    ("Up  Down", "force up, down (×1.25) when the panel reports no pressure"),
    ("M", "switch the friction model (exponential, paper)"),
    ("Space", "pause: the plate rests"),
    ("H", "this help"),
    ("Esc  Q", "quit (the plate ramps to rest)"),
]


def display_available() -> bool:
    driver = os.environ.get("SDL_VIDEODRIVER", "")
    return bool(driver or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def seconds_since_launch() -> float:
    """Seconds since this process started (Linux's /proc), or since this module loaded elsewhere."""
    try:
        start_ticks = float(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime_s = float(Path("/proc/uptime").read_text().split()[0])
        return uptime_s - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return time.perf_counter() - _LOADED_S


_LOADED_S = time.perf_counter()


@dataclass
class Button:
    label: str
    action: str
    rect: object = None


class DemoApp:
    """The demo's state and loop; ``step()`` handles pending events and redraws what is due."""

    def __init__(self, texture_specs=(), device_url="sim", profile="sim-plate", model="exponential",
                 screen_width_mm: float | None = None, windowed: bool = False, size=(1280, 800),
                 record: str | None = None, report_frames: bool = False, watch: bool = False):
        if not display_available():
            raise UsageError("no display to show the demo on (set DISPLAY or run under Xvfb); to render "
                             "without a screen use `ultraglide export`")
        if record is not None and Path(record).suffix.lower() != ".csv":
            raise UsageError(f"--record needs a .csv file, got {record}")
        self.texture_files: dict[int, tuple[Path, Texture]] = {}  # index → (file, texture) for --watch
        self.textures = self._load_textures(texture_specs)  # bad files fail here, before a window opens
        import pygame

        self.pg = pygame
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
        self.waiter = EventWaiter(pygame)
        self.font = pygame.font.Font(None, 22)
        self.big_font = pygame.font.Font(None, 30)
        self.report_frames = report_frames
        self.index = 0
        self.scene = "gallery"
        self.model_name = model
        self.force_n = 0.5
        self.pressure_seen = False  # set once the panel reports a pressure other than 0 or 1
        self.fingers: dict[int, tuple[float, float]] = {}
        self.driving: int | None = None  # the finger (or -1 for the mouse) that drives the plate
        self.trace: collections.deque = collections.deque()
        self.user_paused = False
        self.show_help = False
        self.running = True
        self.pushed = 0
        self.unfelt = 0  # touches made before the engine was ready: drawn, not felt
        self.watcher = None
        self.watch_errors: list[str] = []
        self._next_watch = 0.0
        self.link: DemoLink | None = None
        self._closed = False
        self._widgets: tuple[Texture, list] | None = None
        self._surfaces: dict[int, object] = {}
        self._status_words = ""
        self._dirty = True  # the whole screen
        self._area_dirty = False
        self._active_until = 0.0  # the chart scrolls until then
        self._next_area = self._next_chart = self._next_status = 0.0
        self.frames_drawn = 0
        self.final_status = None  # the engine's last status, once stopped
        self.underruns_at_first_touch: int | None = None
        self._layout()
        try:  # last, so that nothing above can leave a recording behind
            self.recorder = TouchRecorder(record) if record else None
        except OSError as error:
            raise UsageError(f"cannot write the recording {record}: {error.strerror}") from None
        self._draw_all()  # the first frame, before anything heavy is imported
        self.starter = LinkStarter(LinkConfig(self.textures[0], model, profile, device_url))
        if watch:
            from ultraglide.apps.demo.watch import TextureWatcher

            self.watcher = TextureWatcher(self.texture_files)

    # ---- set-up --------------------------------------------------------------------------------
    def _load_textures(self, specs) -> list[Texture]:
        """The textures named on the command line, then the bundled library's. The library's files are
        read directly (textures.library would import scipy for authoring, which the first frame does not need)."""
        from importlib.resources import files

        from ultraglide.textures.fileformat import load_texture

        textures = []
        if specs:
            from ultraglide.textures.library import resolve_texture

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # plain images are authored with defaults, as documented
                for spec in specs:
                    textures.append(resolve_texture(str(spec)))
                    if Path(spec).is_file():
                        self.texture_files[len(textures) - 1] = (Path(spec), textures[-1])
        library = Path(str(files("ultraglide.textures") / "library"))
        textures.extend(load_texture(path) for path in sorted(library.glob("*.png")))
        return textures

    def wait_ready(self, timeout_s: float = 120.0) -> DemoLink:
        """Block until the engine runs (for scripts and tests); raises what starting it raised."""
        link = self.starter.wait(timeout_s)
        if link is None:
            raise TimeoutError(f"the engine did not start within {timeout_s:g} s")
        self._adopt(link)
        return link

    def _adopt(self, link: DemoLink) -> None:
        if self.link is None:
            self.link = link
            link.set_force(self.force_n)
            if self.model_name != link.model_name:
                link.set_model(self.model_name)
            if self.scene != "gallery":
                link.set_texture(self.current)
            self._dirty = True  # the chart's scale and the status come from the device's profile now
            if self.report_frames:
                print(f"renderer ready {seconds_since_launch():.2f} s after launch "
                      f"({self.unfelt} touches before it, not felt)", flush=True)

    def _check_link(self) -> None:
        if self.link is None and self.starter.ready.is_set():
            self._adopt(self.starter.wait())

    def _widgets_for_area(self) -> tuple[Texture, list]:
        """Button, slider, toggle and keyboard in a 2 × 2 grid that fills the texture area (mm)."""
        from ultraglide.textures import procedural
        from ultraglide.textures.compose import Placement

        width_mm, height_mm = self.area.width * self.mm_per_px, self.area.height * self.mm_per_px
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

    @property
    def widgets(self) -> tuple[Texture, list]:
        if self._widgets is None:
            self._widgets = self._widgets_for_area()
        return self._widgets

    def _layout(self) -> None:
        pg = self.pg
        w, h = self.screen.get_size()
        line_h = self.font.get_linesize()
        self.status_rect = pg.Rect(0, 0, w, line_h + 10)
        self.toolbar_rect = pg.Rect(0, h - 64, w, 64)
        chart_h = max(120, min(200, h // 5))
        self.chart_rect = pg.Rect(0, self.toolbar_rect.top - chart_h, w, chart_h)
        self.area = pg.Rect(0, self.status_rect.bottom, w, self.chart_rect.top - self.status_rect.bottom)
        self.buttons = [Button(label, action) for label, action in (
            ("Gallery", "gallery"), ("Texture", "texture"), ("Widgets", "widgets"), ("< Prev", "prev"),
            ("Next >", "next"), ("Force −", "force-"), ("Force +", "force+"), ("Model", "model"),
            ("Pause", "pause"), ("Help", "help"), ("Quit", "quit"))]
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
        label_h = line_h + 4
        self.thumbs = [thumbnail(texture, (tile.width - 4, tile.height - label_h - 4))
                       for texture, tile in zip(self.textures, self.tiles, strict=True)]

    # ---- what the plate feels --------------------------------------------------------------------
    @property
    def current(self) -> Texture:
        return self.widgets[0] if self.scene == "widgets" else self.textures[self.index]

    def _show(self, scene: str, index: int | None = None) -> None:
        if index is not None:
            self.index = index % len(self.textures)
        self.scene = scene
        self.trace.clear()
        self._dirty = True
        if scene != "gallery" and self.link is not None:
            self.link.set_texture(self.current)

    def _to_mm(self, x_px: float, y_px: float) -> tuple[float, float] | None:
        """Screen pixels to millimetres on the texture, or None off the texture area."""
        if self.scene == "gallery" or not self.area.collidepoint(x_px, y_px):
            return None
        return (x_px - self.area.left) * self.mm_per_px, (y_px - self.area.top) * self.mm_per_px

    def _drive(self, x_px: float, y_px: float, down: bool, pressure: float | None = None) -> None:
        now = time.perf_counter()
        self._active_until = now + CHART_SPAN_S + 0.2
        self._area_dirty = True
        if self.link is None:  # the engine is still starting: the touch is drawn, counted, not felt
            self.unfelt += down
            return
        where = self._to_mm(x_px, y_px) if down else None
        if where is None:
            self.link.touch(now, 0.0, 0.0, down=False)
            self.link.pause(True)
            if self.recorder is not None:
                self.recorder.lift(now)
            return
        force = self._force_from(pressure)
        if self.underruns_at_first_touch is None:
            self.underruns_at_first_touch = self.link.status(0.0).underruns
        self.link.pause(self.user_paused)
        self.link.touch(now, where[0], where[1], force)
        self.pushed += 1
        self.trace.append((now, x_px, y_px))
        if self.recorder is not None:
            geometry = {"screen_px": list(self.screen.get_size()), "mm_per_px": self.mm_per_px,
                        "texture_area_px": [self.area.left, self.area.top, self.area.width, self.area.height]}
            self.recorder.touch(now, where[0], where[1], self.force_n if force is None else force,
                                self.current.name, geometry)

    def _force_from(self, pressure: float | None) -> float | None:
        """The force for a touch: from the panel's pressure once it has shown it measures one, else None."""
        if pressure is None:
            return None
        if 0.0 < pressure < 1.0:
            self.pressure_seen = True
        if not self.pressure_seen:
            return None  # panels without a sensor report 1.0 (or 0): the arrow keys' force applies
        return max(FORCE_RANGE_N[0], min(pressure * PRESSURE_FULL_SCALE_N, FORCE_RANGE_N[1]))

    # ---- input -----------------------------------------------------------------------------------
    def _press(self, x_px: float, y_px: float) -> bool:
        """Toolbar buttons and gallery tiles; True when the press was for the interface."""
        if self.show_help:
            self.show_help = False
            self._dirty = True
            return True
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
            self._maybe_flip_toggle(x_px, y_px)
        return False

    def _maybe_flip_toggle(self, x_px: float, y_px: float) -> None:
        from ultraglide.textures import procedural
        from ultraglide.textures.compose import Placement

        where = self._to_mm(x_px, y_px)
        texture, placements = self.widgets
        toggle = placements[2]
        if where and toggle.contains(*where):
            on = not toggle.texture.authoring.get("on", False)
            size = (toggle.texture.width_mm, toggle.texture.height_mm)
            placements[2] = Placement(procedural.toggle(size_mm=size, on=on), toggle.x_mm, toggle.y_mm)
            self._surfaces.pop(id(texture), None)
            self._widgets = (compose_widgets((texture.width_mm, texture.height_mm), placements), placements)
            self._dirty = True
            if self.link is not None:
                self.link.set_texture(self._widgets[0])

    def _act(self, action: str) -> None:
        self._dirty = True
        if action in ("gallery", "texture", "widgets"):
            self._show(action)
        elif action in ("prev", "next"):
            self._show("texture", self.index + (1 if action == "next" else -1))
        elif action in ("force-", "force+"):
            force = self.force_n * (1.25 if action == "force+" else 0.8)
            self.force_n = min(max(force, FORCE_RANGE_N[0]), FORCE_RANGE_N[1])
            if self.link is not None:
                self.link.set_force(self.force_n)
        elif action == "model":
            self.model_name = MODELS[(MODELS.index(self.model_name) + 1) % len(MODELS)] \
                if self.model_name in MODELS else MODELS[0]
            if self.link is not None:
                self.link.set_model(self.model_name)
        elif action == "pause":
            self.user_paused = not self.user_paused
            if self.link is not None:
                self.link.pause(self.user_paused or self.driving is None)
        elif action == "help":
            self.show_help = not self.show_help
        elif action == "quit":
            self.running = False

    def handle(self, event) -> None:
        pg = self.pg
        w, h = self.screen.get_size()
        if event.type == pg.QUIT:
            self.running = False
        elif event.type in (pg.WINDOWEXPOSED, pg.VIDEOEXPOSE, pg.WINDOWRESTORED):
            self._dirty = True
        elif event.type == pg.KEYDOWN:
            keys = {pg.K_ESCAPE: "quit", pg.K_q: "quit", pg.K_g: "gallery", pg.K_t: "texture", pg.K_w: "widgets",
                    pg.K_LEFT: "prev", pg.K_RIGHT: "next", pg.K_DOWN: "force-", pg.K_UP: "force+",
                    pg.K_m: "model", pg.K_SPACE: "pause", pg.K_h: "help"}
            if event.key == pg.K_ESCAPE and self.show_help:
                self._act("help")
            elif event.key in keys:
                self._act(keys[event.key])
        elif event.type == pg.FINGERDOWN:
            x, y = event.x * w, event.y * h
            self.fingers[event.finger_id] = (x, y)
            self._area_dirty = True
            if self.driving is None and not self._press(x, y):
                self.driving = event.finger_id
                self.trace.clear()
                self._drive(x, y, True, getattr(event, "pressure", None))
        elif event.type == pg.FINGERMOTION:
            x, y = event.x * w, event.y * h
            self.fingers[event.finger_id] = (x, y)
            self._area_dirty = True
            if event.finger_id == self.driving:
                self._drive(x, y, True, getattr(event, "pressure", None))
        elif event.type == pg.FINGERUP:
            self.fingers.pop(event.finger_id, None)
            self._area_dirty = True
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

    def _draw_all(self) -> None:
        """The whole screen, flipped; the first time, a line says how long the window took."""
        self.screen.fill(BACKGROUND)
        if self.scene == "gallery":
            self._draw_gallery()
        else:
            self._draw_area()
        self._draw_chart()
        self._draw_status(force=True)
        self._draw_toolbar()
        if self.show_help:
            draw_help(self.screen, self.font, self.big_font, HELP)
        self.pg.display.flip()
        self._dirty = False
        self.frames_drawn += 1
        if self.frames_drawn == 1:
            cpu = os.times()
            print(f"ultraglide demo: first frame drawn {seconds_since_launch():.2f} s after launch "
                  f"({cpu.user + cpu.system:.2f} s of CPU)", flush=True)
        if self.report_frames:
            print(f"frame drawn: {self.scene}{' help' if self.show_help else ''}", flush=True)

    def _draw_gallery(self) -> None:
        pg, screen = self.pg, self.screen
        label_h = self.font.get_linesize() + 4
        for texture, tile, thumb in zip(self.textures, self.tiles, self.thumbs, strict=True):
            if tile.bottom > self.area.bottom:
                break
            picture = pg.Rect(tile.left, tile.top, tile.width, tile.height - label_h)
            screen.blit(thumb, thumb.get_rect(center=picture.center))
            pg.draw.rect(screen, DIM, tile, 1)
            label = fit_text(self.font, texture.name, tile.width - 8)
            screen.blit(self.font.render(label, True, TEXT), (tile.left + 4, tile.bottom - label_h + 2))

    def _draw_area(self) -> None:
        pg, screen = self.pg, self.screen
        texture = self.current
        outside = friction_colours(np.array([[texture.outside_ratio]]))[0, 0].tolist()
        blit_texture(screen, self._surface(texture), self.area, texture.outside == "tile", outside)
        words = f"{texture.name}: {texture.width_mm:.4g} × {texture.height_mm:.4g} mm"
        if texture.description:
            words += f", {texture.description}"
        text = self.font.render(fit_text(self.font, words, self.area.width - 40), True, ACCENT)
        backing = text.get_rect(bottomleft=(self.area.left + 8, self.area.bottom - 6)).inflate(12, 8)
        pg.draw.rect(screen, PANEL, backing, border_radius=4)
        screen.blit(text, text.get_rect(center=backing.center))
        now = time.perf_counter()
        while self.trace and now - self.trace[0][0] > TRACE_S:
            self.trace.popleft()
        clip = screen.get_clip()
        screen.set_clip(self.area)
        draw_trace(screen, [(x, y) for _, x, y in self.trace])
        for finger, (x, y) in self.fingers.items():
            if finger != self.driving:
                pg.draw.circle(screen, OTHER_FINGER, (int(x), int(y)), 14, 2)
        screen.set_clip(clip)

    def _draw_chart(self) -> None:
        if self.link is None:
            chart, limit, full_scale, measured = np.zeros((0, 4)), 6.0, 6.0, False
        else:
            status = self.link.status(CHART_SPAN_S)
            chart, limit, full_scale, measured = (status.chart, status.limit_um_pp, status.full_scale_um_pp,
                                                  status.plate_measured)
        series = {"friction": chart[:, [0, 1]], "commanded": chart[:, [0, 2]], "plate": chart[:, [0, 3]]}
        label = "plate measured µm p-p" if measured else "plate (model) µm p-p"
        draw_chart(self.screen, self.font, self.chart_rect, series, CHART_SPAN_S, full_scale, limit, label)

    def status_words(self) -> str:
        """The status line: device and its state, model, force, percent limited in the last second, faults,
        then the engine's own figures."""
        if self.link is None:
            words = "starting the engine (its own process; compiling its kernels)…"
            if self.unfelt:
                words += f"   ·   {self.unfelt} touches before it was ready: not felt"
            return words
        s = self.link.status(0.0)
        device = {"sim": "simulated plate"}.get(s.device, s.device.replace("serial:", "plate on serial ")
                                                .replace("audio:", "audio output ").replace("wav:", "recording "))
        source = "touch pressure" if self.pressure_seen else "Up/Down keys"
        faults = "faults: " + ", ".join(s.faults) if s.faults else "no faults"
        # the engine is paused between touches (the plate rests); the user's pause is the Space key's
        state = "paused" if self.user_paused else ("running" if s.state == "paused" else s.state)
        words = (f"{device} {state}, {faults}   ·   {self.link.model_name} model   ·   "
                 f"{self.force_n:.2f} N ({source})   ·   limited {s.limited_pct:.0f} % of the last second, "
                 f"{s.limited_samples} samples on this texture   ·   {s.underruns} underruns, "
                 f"{s.late_blocks} late blocks, block {s.block_p50_us:.0f}/{s.block_p99_us:.0f} µs p50/p99")
        if self.recorder is not None:
            words += f"   ·   recording: {self.recorder.rows} touches"
        if self.watch_errors:
            words += "   ·   " + "; ".join(self.watch_errors)
        return words + "   ·   H: help"

    def _draw_status(self, force: bool = False) -> bool:
        words = self.status_words()
        if words == self._status_words and not force:
            return False
        self._status_words = words
        self.pg.draw.rect(self.screen, PANEL, self.status_rect)
        text = fit_text(self.font, words, self.status_rect.width - 16)
        self.screen.blit(self.font.render(text, True, TEXT), (8, 5))
        return True

    def _draw_toolbar(self) -> None:
        pg = self.pg
        pg.draw.rect(self.screen, PANEL, self.toolbar_rect)
        for button in self.buttons:
            active = (button.action == self.scene or (button.action == "pause" and self.user_paused)
                      or (button.action == "help" and self.show_help))
            pg.draw.rect(self.screen, ACCENT if active else DIM, button.rect, 0 if active else 2, border_radius=8)
            label = fit_text(self.big_font, button.label, button.rect.width - 8)
            text = self.big_font.render(label, True, BACKGROUND if active else TEXT)
            self.screen.blit(text, text.get_rect(center=button.rect.center))

    def frame(self) -> None:
        """Redraw what is due: everything after a change of scene, else only the parts that move."""
        if self._dirty:
            self._draw_all()
            now = time.perf_counter()
            self._next_area, self._next_chart, self._next_status = now + AREA_FRAME_S, now + CHART_FRAME_S, \
                now + STATUS_S
            return
        if self.show_help:
            return  # the panel covers the middle; everything is redrawn when it closes
        now = time.perf_counter()
        changed = []
        area_moving = self.scene != "gallery" and (self._area_dirty or self.trace or self.fingers)
        if area_moving and now >= self._next_area:
            self._area_dirty = False
            self._draw_area()
            changed.append(self.area)
            self._next_area = now + AREA_FRAME_S
        if now < self._active_until and now >= self._next_chart:
            self._draw_chart()
            changed.append(self.chart_rect)
            self._next_chart = now + CHART_FRAME_S
        if now >= self._next_status:
            if self._draw_status():
                changed.append(self.status_rect)
            self._next_status = now + STATUS_S
        if changed:
            self.pg.display.update(changed)

    def _wait_s(self) -> float:
        """How long the loop may sleep waiting for an event before something is due."""
        now = time.perf_counter()
        due = [self._next_status]
        if self.scene != "gallery" and (self._area_dirty or self.trace or self.fingers):
            due.append(self._next_area)
        if now < self._active_until:
            due.append(self._next_chart)
        if self.link is None:
            due.append(now + 0.05)  # look for the engine having started
        if self.watcher is not None:
            due.append(self._next_watch)
        return min(max(min(due) - now, 0.001), IDLE_WAIT_S)

    def _watch(self) -> None:
        """Every 200 ms with ``--watch``: reload the textures whose files changed; the plate feels the one shown."""
        now = time.perf_counter()
        if self.watcher is None or now < self._next_watch:
            return
        from ultraglide.apps.demo.watch import POLL_S

        self._next_watch = now + POLL_S
        reloaded = self.watcher.poll()
        self.watch_errors = self.watcher.errors
        for index, texture in reloaded:
            old = self.textures[index]
            self.textures[index] = texture
            self._surfaces.pop(id(old), None)
            tile = self.tiles[index]
            self.thumbs[index] = thumbnail(texture, (tile.width - 4, tile.height - self.font.get_linesize() - 8))
            self._dirty = True
            if self.link is not None and self.scene == "texture" and self.index == index:
                self.link.set_texture(texture)
            if self.report_frames:
                print(f"texture reloaded: {texture.name}", flush=True)

    # ---- the loop --------------------------------------------------------------------------------
    def step(self, wait_s: float = 0.0) -> None:
        """Handle the events that arrive within ``wait_s`` (0: only those pending), then redraw what is due."""
        pg = self.pg
        self._check_link()
        self._watch()
        event = self.waiter.wait(wait_s) if wait_s > 0 else pg.event.poll()
        while event.type != pg.NOEVENT:
            self.handle(event)
            event = pg.event.poll()
        self.frame()

    def run(self) -> None:
        while self.running:
            self.step(self._wait_s())

    def stats(self, final=None) -> dict:
        """The engine's figures over the run for ``--stats`` (``final``: its last status, after stop)."""
        if self.link is None:
            return {"started": False, "touches_not_felt_before_ready": self.unfelt}
        s = final if final is not None else self.link.status(0.0).engine
        return {"started": True, "device": s.device, "blocks_rendered": s.blocks, "late_blocks": s.late_blocks,
                "resting_blocks": s.resting_blocks,
                "underruns": s.underruns, "underruns_at_first_touch": self.underruns_at_first_touch,
                "block_p50_us": _rounded(s.run_block_p50_us), "block_p99_us": _rounded(s.run_block_p99_us),
                "block_times": "over every block rendered in the run (not the resting ones), ±1 % (a histogram)",
                "limited_samples": s.clipped_samples, "faults": list(s.faults), "priority": s.priority,
                "touches": self.pushed, "touches_received_by_engine": s.touches,
                "touches_dropped_by_engine": s.touches_dropped, "touches_not_felt_before_ready": self.unfelt}

    def close(self) -> None:
        """Rest the plate, finish the recording and close the window; safe to call more than once."""
        if self._closed:
            return
        self._closed = True
        try:
            link = self.link
            if link is None and getattr(self, "starter", None) is not None:
                self.starter.ready.wait(60)
                link = self.starter.link
            if link is not None:
                self.final_status = link.stop()
        finally:
            if self.recorder is not None:
                saved = self.recorder.close()
                print(f"recorded {self.recorder.rows} touches to {saved}" if saved else
                      "recorded fewer than two touches: no touch log written", file=sys.stderr)
            self.pg.display.quit()


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(value, 2)


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


def write_stats(path: str, stats: dict) -> None:
    from ultraglide.apps.cli.files import atomic_path

    with atomic_path(Path(path)) as temporary:
        temporary.write_text(json.dumps(stats, indent=2) + "\n")


def run(args) -> int:
    if args.stats and Path(args.stats).suffix.lower() != ".json":
        raise UsageError(f"--stats needs a .json file, got {args.stats}")
    app = DemoApp(args.textures, args.device, args.profile, args.model, args.screen_width_mm, args.windowed,
                  record=args.record, report_frames=args.report_frames, watch=args.watch)
    try:
        app.run()
    finally:
        with held():  # a second Ctrl-C or SIGTERM does not cut this short
            app.close()  # window closed, Escape, Ctrl-C or an exception: the plate comes to rest
    if args.stats:
        write_stats(args.stats, app.stats(app.final_status))
    return 0
