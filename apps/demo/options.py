"""The demo's set-up: its options, checked before a window opens, and the textures it shows."""

from __future__ import annotations

import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.window.screen import display_available
from ultraglide.render.physics.default_model import DEFAULT_MODEL

MODELS = ("stretched", "squeeze-film", "exponential", "paper")  # the M key cycles through these
PRESSURE_FULL_SCALE_N = 2.0  # a panel's pressure 1.0 is taken as this force
FORCE_RANGE_N = (0.05, 5.0)
START_FORCE_N = 0.5


def model_cycle(start: str) -> tuple[str, ...]:
    """The models the M key steps through from ``start``: the model the demo started with first, then the
    built-in ones, each with the friction dynamics where the start has them (so stepping never drops the
    planning a ``dynamic`` model brings, and comes back to a model given as a file).

    Parameters
    ----------
    start : str
        The model spec the demo started with (``stretched``, ``dynamic``, ``dynamic:NAME``, a file...).

    Returns
    -------
    tuple of str
        Model specs, ``start`` first, none twice.

    Examples
    --------
    >>> model_cycle("stretched")
    ('stretched', 'squeeze-film', 'exponential', 'paper')
    >>> model_cycle("dynamic")
    ('dynamic', 'dynamic:squeeze-film', 'dynamic:exponential', 'dynamic:paper')
    >>> model_cycle("p07.toml")[:2]
    ('p07.toml', 'stretched')
    >>> model_cycle("speed:0.5:dynamic")[:2]
    ('speed:0.5:dynamic', 'dynamic:stretched')
    """
    dynamic = "dynamic" in start.split(":")  # dynamic, dynamic:NAME, speed:S:dynamic, ...
    same = {start, "dynamic:stretched"} if start == "dynamic" else {start}
    built_in = tuple(f"dynamic:{name}" if dynamic else name for name in MODELS)
    return (start,) + tuple(name for name in built_in if name not in same)


@dataclass(frozen=True)
class DemoOptions:
    """What the demo starts with: texture files or names (shown before the library's), device URL, profile and
    model specs, the screen's width (mm, else 96 dpi), a window of ``size`` px instead of full screen, a touch
    log to record (.csv), a line printed for each full frame (for scripts), and reloading changed files."""

    textures: tuple = ()
    device: str = "sim"
    profile: str = "sim-plate"
    model: str = DEFAULT_MODEL
    screen_width_mm: float | None = None
    windowed: bool = False
    size: tuple[int, int] = (1280, 800)
    record: str | None = None
    report_frames: bool = False
    watch: bool = False

    def check(self) -> None:
        """Refuse, in one line, what would fail after the window opened."""
        if not display_available():
            raise UsageError("no display to show the demo on (set DISPLAY or run under Xvfb); to render "
                             "without a screen use `ultraglide export`")
        if self.record is not None and Path(self.record).suffix.lower() != ".csv":
            raise UsageError(f"--record needs a .csv file, got {self.record}")


def seconds_since_launch() -> float:
    """Seconds since this process started (Linux's /proc), or since this module loaded elsewhere."""
    try:
        start_ticks = float(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime_s = float(Path("/proc/uptime").read_text().split()[0])
        return uptime_s - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return time.perf_counter() - _LOADED_S


_LOADED_S = time.perf_counter()


def load_textures(specs, effects: str | None = None) -> tuple[list, dict[int, tuple[Path, object]]]:
    """The textures named on the command line, then the bundled library's; and for those given as files, their
    index → (file, texture), which ``--watch`` follows. Bad files fail here, before a window opens. The
    library's files are read directly (textures.library would import scipy for authoring, which the first
    frame does not need). ``effects``: a file of temporal effects (.json, .ahap, .haptic, .hjif) the textures
    named play instead of their own."""
    from importlib.resources import files

    from ultraglide.textures.fileformat import load_texture

    textures, from_files = [], {}
    if specs:
        from ultraglide.textures.effects import load_effects
        from ultraglide.textures.library import resolve_texture

        bindings = load_effects(effects) if effects else None  # what it cannot render is said, not silenced

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # plain images are authored with defaults, as documented
            for spec in specs:
                texture = resolve_texture(str(spec))
                textures.append(texture if bindings is None else texture.with_(effects=bindings))
                if Path(spec).is_file():
                    from_files[len(textures) - 1] = (Path(spec), textures[-1])
    library = Path(str(files("ultraglide.textures") / "library"))
    textures.extend(load_texture(path) for path in sorted(library.glob("*.png")))
    return textures, from_files
