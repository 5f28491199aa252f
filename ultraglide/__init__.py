# pyright: basic, reportUnsupportedDunderAll=false
"""ultraglide: tactile texture rendering for ultrasonic friction displays.

The public API is the names in ``__all__``, importable from ``ultraglide`` itself::

    >>> import ultraglide
    >>> texture = ultraglide.grating(wavelength_mm=2.0, size_mm=(20.0, 10.0))
    >>> model = ultraglide.load_model("exponential")
    >>> round(float(model.amplitude_um_pp(0.5, 0.5).amplitude_um_pp), 2)    # µm p-p for half the friction
    3.11

Each name is imported when first used (PEP 562), so ``import ultraglide`` and the command stay
quick. Everything else (``ultraglide.render.kernels``, ``ultraglide.apps``, ...) is internal and
may change between versions. The packages ``ultraglide.textures``, ``ultraglide.render``,
``ultraglide.devices`` and ``ultraglide.apps`` live in the repository's top-level folders of the
same names (setuptools' package-dir mapping in pyproject.toml); :mod:`ultraglide.api` holds the
few functions that span them (export to a WAV, a renderer as a device's source).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ultraglide.lazy import lazy_exports

__version__ = "0.2.0"

# public name -> the module that defines it
_EXPORTS: dict[str, str] = {
    # the root of every error of ours: ``except ultraglide.UltraglideError`` catches anything refused
    "UltraglideError": "ultraglide.errors",
    # textures: the type, files, the library, authoring, procedural patterns, composition, sampling
    "Texture": "ultraglide.textures.texture",
    "load_texture": "ultraglide.textures.fileformat",
    "save_texture": "ultraglide.textures.fileformat",
    "resolve_texture": "ultraglide.textures.library",
    "library_entries": "ultraglide.textures.library",
    "AuthoringOptions": "ultraglide.textures.authoring",
    "author_image": "ultraglide.textures.authoring",
    "grating": "ultraglide.textures.procedural",
    "checkerboard": "ultraglide.textures.procedural",
    "dots": "ultraglide.textures.procedural",
    "noise": "ultraglide.textures.procedural",
    "fractal": "ultraglide.textures.procedural",
    "Sampler": "ultraglide.textures.sampling",
    "TextureError": "ultraglide.textures.errors",
    # models, their inverse, measurements and calibration
    "FrictionModel": "ultraglide.render.physics.friction_models",
    "PaperModel": "ultraglide.render.physics.friction_models",
    "ExponentialModel": "ultraglide.render.physics.friction_models",
    "StretchedExponentialModel": "ultraglide.render.physics.friction_models",
    "TableModel": "ultraglide.render.physics.friction_models",
    "SqueezeFilmModel": "ultraglide.render.physics.squeeze_film",
    "FilmParams": "ultraglide.render.physics.squeeze_film",
    "DynamicFrictionModel": "ultraglide.render.physics.dynamics",  # friction in time (load_model("dynamic"))
    "FrictionDynamics": "ultraglide.render.physics.dynamics",
    "SpeedLawModel": "ultraglide.render.physics.speed_law",  # the reduction weakening with speed ("speed:S:NAME")
    "SpeedLaw": "ultraglide.render.physics.speed_law",
    "ForceRangeWarning": "ultraglide.render.physics.errors",
    "load_model": "ultraglide.render.physics.calibration",
    "read_measurements": "ultraglide.render.physics.measurements",
    "fit_model": "ultraglide.render.physics.calibration",
    "compare_models": "ultraglide.render.physics.calibration",
    "calibration_toml": "ultraglide.render.physics.calibration",
    "read_calibration": "ultraglide.render.physics.calibration",
    "ModelError": "ultraglide.render.physics.errors",
    # the renderer and the finger's path
    "Renderer": "ultraglide.api",  # render.renderer's, taking names and arrays
    "RenderSettings": "ultraglide.render.renderer",
    "RecordedTrajectory": "ultraglide.render.trajectory",
    "SwipePath": "ultraglide.render.paths",
    "read_touch_log": "ultraglide.render.touch_log",
    "RenderError": "ultraglide.render.errors",
    # the real-time engine: renderer and device in their own process, fed touches
    "Engine": "ultraglide.render.engine",
    "EngineConfig": "ultraglide.render.engine",
    "EngineStatus": "ultraglide.render.engine",
    "EngineError": "ultraglide.render.engine",
    "FitError": "ultraglide.devices.characterisation.resonance",
    "ProtocolError": "ultraglide.devices.protocol",
    # devices
    "PlateProfile": "ultraglide.devices.profiles",
    "load_profile": "ultraglide.devices.profiles",
    "open_device": "ultraglide.devices.urls",
    "BlockSource": "ultraglide.devices.output.source",
    "Device": "ultraglide.devices.output.source",
    "OutputStage": "ultraglide.devices.output.stage",
    "output_stage": "ultraglide.devices.output.stage",
    "DeviceError": "ultraglide.devices.errors",
    # what spans the packages
    "render_swipe": "ultraglide.api",
    "Rendered": "ultraglide.api",
    "export_wav": "ultraglide.api",
    "ExportResult": "ultraglide.api",
    "EnvelopeSource": "ultraglide.render.engine.sources",
    "renderer_source": "ultraglide.render.engine.sources",
}

__all__ = ["__version__", *_EXPORTS]
# each name imported on first use and kept (PEP 562)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


if TYPE_CHECKING:  # for type checkers and IDEs; at run time the names load lazily
    from ultraglide.api import ExportResult, Rendered, Renderer, export_wav, render_swipe
    from ultraglide.devices.characterisation.resonance import FitError
    from ultraglide.devices.errors import DeviceError
    from ultraglide.devices.output.source import BlockSource, Device
    from ultraglide.devices.output.stage import OutputStage, output_stage
    from ultraglide.devices.profiles import PlateProfile, load_profile
    from ultraglide.devices.protocol import ProtocolError
    from ultraglide.devices.urls import open_device
    from ultraglide.errors import UltraglideError
    from ultraglide.render.engine import Engine, EngineConfig, EngineError, EngineStatus
    from ultraglide.render.engine.sources import EnvelopeSource, renderer_source
    from ultraglide.render.errors import RenderError
    from ultraglide.render.paths import SwipePath
    from ultraglide.render.physics.calibration import (
        calibration_toml,
        compare_models,
        fit_model,
        load_model,
        read_calibration,
    )
    from ultraglide.render.physics.dynamics import DynamicFrictionModel, FrictionDynamics
    from ultraglide.render.physics.errors import ForceRangeWarning, ModelError
    from ultraglide.render.physics.friction_models import (
        ExponentialModel,
        FrictionModel,
        PaperModel,
        StretchedExponentialModel,
        TableModel,
    )
    from ultraglide.render.physics.measurements import read_measurements
    from ultraglide.render.physics.speed_law import SpeedLaw, SpeedLawModel
    from ultraglide.render.physics.squeeze_film import FilmParams, SqueezeFilmModel
    from ultraglide.render.renderer import RenderSettings
    from ultraglide.render.touch_log import read_touch_log
    from ultraglide.render.trajectory import RecordedTrajectory
    from ultraglide.textures.authoring import AuthoringOptions, author_image
    from ultraglide.textures.errors import TextureError
    from ultraglide.textures.fileformat import load_texture, save_texture
    from ultraglide.textures.library import library_entries, resolve_texture
    from ultraglide.textures.procedural import checkerboard, dots, fractal, grating, noise
    from ultraglide.textures.sampling import Sampler
    from ultraglide.textures.texture import Texture
