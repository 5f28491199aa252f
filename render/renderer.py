"""The renderer: finger → friction → amplitude → drive envelope, block by block.

A :class:`Renderer` owns one texture, one friction model and one plate profile. ``control(n)``
gives the next n samples of the drive envelope at the control rate (µm p-p), computed just in
time from the finger state at that moment, so a touch report pushed now shapes the very next
block. Devices pull it through their output stage (:mod:`ultraglide.devices.output.stage`), which
limits the drive and, for audio devices, puts it on the carrier; the renderer makes no carrier.

Example, offline::

    >>> from ultraglide.render.physics.friction_models import ExponentialModel
    >>> from ultraglide.render.trajectory import RecordedTrajectory
    >>> from ultraglide.textures.procedural import grating
    >>> from ultraglide.devices.profiles import load_profile
    >>> path = RecordedTrajectory([0, 1], [10, 110], [25, 25])   # 100 mm/s
    >>> r = Renderer(grating(1.0), ExponentialModel(), load_profile("sim-plate"), trajectory=path)
    >>> block = r.control(12000)    # one second at 12 kHz
    >>> bool(block.drive_um_pp.max() <= 8.0)   # the plate's max_drive_um_pp
    True
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from ultraglide.render import kernels
from ultraglide.render.effects import EffectPlayer
from ultraglide.render.envelope import EnvelopeChain
from ultraglide.render.errors import RenderError
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.render.physics.speed_law import reach_limit, scaled_inverse, speed_law_of
from ultraglide.render.planning import Planner
from ultraglide.render.trajectory import FingerState, LiveTrajectory, RecordedTrajectory
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.texture import Texture

RESYNC_S = 0.02  # re-anchor the live clock when the device's clock has drifted this far


class Plate(Protocol):
    """What the renderer needs to know of the plate it renders for (a ``devices.profiles.PlateProfile`` is
    one): its resonance (Hz), the steady limit and the drive's ceiling (µm p-p), its envelope's time
    constant (s), and which carriers it takes.

    Examples
    --------
    A plate profile is one, and so is the same plate seen through an amplitude loop:

    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.engine.loop_plate import AmplitudeLoopPlate
    >>> members = ("name", "resonance_hz", "max_amplitude_um_pp", "max_drive_um_pp", "time_constant_s", "check_carrier")
    >>> profile = load_profile("sim-plate")
    >>> all(hasattr(plate, m) for plate in (profile, AmplitudeLoopPlate.of(profile)) for m in members)
    True
    """

    @property
    def name(self) -> str:
        """The plate's name, for messages.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> load_profile("sim-plate").name
        'sim-plate'
        """
        ...

    @property
    def resonance_hz(self) -> float:
        """The plate's resonance (Hz): the carrier unless the settings say otherwise.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> load_profile("sim-plate").resonance_hz          # the bundled profile's resonance_hz = 25000
        25000.0
        """
        ...

    @property
    def max_amplitude_um_pp(self) -> float:
        """The plate's amplitude limit (µm p-p), never exceeded.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> load_profile("sim-plate").max_amplitude_um_pp    # the bundled profile's max_amplitude_um_pp
        6.0
        """
        ...

    @property
    def max_drive_um_pp(self) -> float | None:
        """The drive's ceiling (µm p-p) for pre-compensation; None: the limit.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> load_profile("sim-plate").max_drive_um_pp        # the bundled profile's overdrive ceiling
        8.0
        """
        ...

    @property
    def time_constant_s(self) -> float:
        """The plate's envelope time constant (s): Q / (π f0).

        Examples
        --------
        >>> import math
        >>> from ultraglide.devices.profiles import load_profile
        >>> plate = load_profile("sim-plate")
        >>> round(plate.time_constant_s, 9), round(200 / (math.pi * 25000), 9)      # Q 200 at 25 kHz
        (0.002546479, 0.002546479)
        """
        ...

    def check_carrier(self, carrier_hz: float, audio_rate_hz: float | None = None) -> None:
        """Raise an error of ours unless ``carrier_hz`` (Hz) lies in the plate's carrier range and, given an audio
        rate (Hz), that rate can carry it.

        Parameters
        ----------
        carrier_hz : float
            The carrier, Hz.
        audio_rate_hz : float, optional
            The output's sample rate, Hz.

        Raises
        ------
        UltraglideError
            A carrier outside the plate's range, or one the audio rate cannot carry.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> load_profile("sim-plate").check_carrier(25000.0, 96000)     # in 20-28 kHz, under 48 kHz: nothing raised
        >>> load_profile("sim-plate").check_carrier(19000.0)
        Traceback (most recent call last):
        ...
        ultraglide.devices.errors.CarrierError: carrier 19000 Hz is outside plate sim-plate's range 20000-28000 Hz
        """
        ...


@dataclass(frozen=True)
class RenderSettings:
    """How the renderer turns friction into drive. Rates in Hz, times in s, amplitudes µm p-p.

    Parameters
    ----------
    control_rate_hz : float
        The envelope's rate (Hz), 10 kHz or more.
    audio_rate_hz : int
        The audio the output stage makes from it (Hz), a whole multiple of the control rate.
    carrier_hz : float, optional
        The carrier (Hz); the plate's resonance by default.
    default_force_n : float
        The force (N) assumed when touches carry none, > 0.
    attack_s, release_s : float
        The gate's ramps (s) when the finger lands and lifts.
    band_hz : float
        The envelope's band limit (Hz).
    slew_um_per_ms : float
        The fastest the amplitude may change (µm p-p per ms).
    precompensate : bool
        Pre-compensate the plate's slow resonant response.
    band_limited_lookup : bool
        Average the texture over each sample's step.
    predictor : str
        How a live finger's path is predicted ahead (``lsq`` ...).
    lookahead_s : float
        How far ahead (s) to predict, cancelling the touch panel's latency.
    plan : bool
        With a model that has friction dynamics: plan the friction felt.

    Raises
    ------
    RenderError
        A control rate under 10 kHz, an audio rate that is not a whole multiple of it, or a force <= 0.

    Examples
    --------
    >>> RenderSettings().upsampling, RenderSettings(audio_rate_hz=48000).upsampling   # audio per control sample
    (8, 4)
    >>> RenderSettings(audio_rate_hz=44100)
    Traceback (most recent call last):
    ...
    ultraglide.render.errors.RenderError: the audio rate (44100) must be a whole multiple of the control rate (12000)
    """

    control_rate_hz: float = 12000.0
    audio_rate_hz: int = 96000  # of the audio the output stage makes from the envelope (checked here, early)
    carrier_hz: float | None = None  # None: the plate's resonance
    default_force_n: float = 0.5
    attack_s: float = 0.005
    release_s: float = 0.010
    band_hz: float = 1000.0
    slew_um_per_ms: float = 30.0
    precompensate: bool = True
    band_limited_lookup: bool = True
    predictor: str = "lsq"
    lookahead_s: float = 0.0
    plan: bool = True  # with a model that has friction dynamics: plan the friction felt (render/planning.py)

    def __post_init__(self) -> None:
        if self.control_rate_hz < 10000:
            raise RenderError(f"the control rate must be at least 10 kHz, got {self.control_rate_hz:g} Hz")
        ratio = self.audio_rate_hz / self.control_rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
            raise RenderError(f"the audio rate ({self.audio_rate_hz}) must be a whole multiple of the "
                              f"control rate ({self.control_rate_hz:g})")
        if not self.default_force_n > 0:
            raise RenderError("the default force must be positive")

    @property
    def upsampling(self) -> int:
        """Audio samples per control sample: ``audio_rate_hz / control_rate_hz``, a whole number.

        Examples
        --------
        >>> RenderSettings(control_rate_hz=12000.0, audio_rate_hz=96000).upsampling     # 96000 / 12000
        8
        """
        return round(self.audio_rate_hz / self.control_rate_hz)


@dataclass
class Counters:
    """What a person watching the renderer wants to know.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.paths import SwipePath
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> from ultraglide.textures.library import resolve_texture
    >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
    ...                     trajectory=SwipePath(duration_s=0.1, speed_mm_s=100.0))
    >>> _ = renderer.control(120)
    >>> renderer.counters.control_samples, renderer.counters.clipped_samples, len(renderer.counters.render_times_s)
    (120, 0, 1)
    """

    control_samples: int = 0
    clipped_samples: int = 0  # target ratio below what the plate reaches: amplitude held at the limit
    drive_clipped_samples: int = 0  # pre-compensation wanted more than the drive's headroom (max_drive_um_pp)
    ramps: int = 0
    late_blocks: int = 0
    render_times_s: list[float] = field(default_factory=list)


@dataclass(slots=True)
class ControlBlock:
    """One block of the envelope and how it came about; amplitudes µm p-p.

    Examples
    --------
    120 control samples (10 ms at 12 kHz) of a swipe at 100 mm/s: the finger moves 119 / 12000 s × 100 mm/s:

    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.paths import SwipePath
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> from ultraglide.textures.library import resolve_texture
    >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
    ...                     trajectory=SwipePath(duration_s=0.1, speed_mm_s=100.0))
    >>> block = renderer.control(120)
    >>> block.time_s.shape, round(float(block.x_mm[-1] - block.x_mm[0]), 6), round(119 / 12000 * 100.0, 6)
    ((120,), 0.991667, 0.991667)
    >>> bool(block.amplitude_um_pp.max() <= 6.0)          # the plate's limit
    True
    """

    time_s: np.ndarray
    x_mm: np.ndarray
    y_mm: np.ndarray
    down: np.ndarray
    ratio: np.ndarray  # target friction ratio under the finger
    target_um_pp: np.ndarray  # the model's amplitude for that ratio, within the limit
    amplitude_um_pp: np.ndarray  # after ramps and band/slew limits: what the plate should do
    drive_um_pp: np.ndarray  # what is asked of the output stage: pre-compensated for the plate's dynamics
    plate_um_pp: np.ndarray  # what the plate model says it does
    # the static ratio the model's inverse was asked for: the planner's command with a model that has friction
    # dynamics (what the renderer means the finger to feel through them), else ``ratio`` itself
    planned_ratio: np.ndarray | None = None


class ControlBuffers:
    """Preallocated outputs for :meth:`Renderer.control`, so a live block allocates no arrays of its own.

    The block it returns is reused: its arrays are overwritten by the next block of the same length.
    Every stage writes into them (the texture lookup, the model inverse, the envelope), so a live block
    allocates no array.

    Parameters
    ----------
    capacity : int
        The longest block, control samples.

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.paths import SwipePath
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> from ultraglide.textures.library import resolve_texture
    >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
    ...                     trajectory=SwipePath(duration_s=0.1))
    >>> buffers = ControlBuffers(256)
    >>> first = renderer.control(64, out=buffers)
    >>> renderer.control(64, out=buffers) is first is buffers.block(64)      # the same arrays, overwritten
    True
    """

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.time_s, self.x_mm, self.y_mm = np.empty(capacity), np.empty(capacity), np.empty(capacity)
        self.ratio = np.empty(capacity, dtype=np.float32)  # as the texture's lookup gives it
        self.target_um_pp = np.empty(capacity)
        self.amplitude_um_pp, self.drive_um_pp, self.plate_um_pp = (np.empty(capacity), np.empty(capacity),
                                                                    np.empty(capacity))
        self._blocks: dict[int, ControlBlock] = {}
        self._ratio_views: dict[int, np.ndarray] = {}

    def block(self, n: int) -> ControlBlock:
        """The reusable block of length ``n`` (views of the buffers; built once per length).

        Parameters
        ----------
        n : int
            Control samples, at most the capacity.

        Returns
        -------
        ControlBlock

        Examples
        --------
        >>> buffers = ControlBuffers(256)
        >>> block = buffers.block(64)
        >>> len(block.time_s), block is buffers.block(64), block.time_s.base is buffers.time_s
        (64, True, True)
        """
        block = self._blocks.get(n)
        if block is None:
            block = ControlBlock(self.time_s[:n], self.x_mm[:n], self.y_mm[:n], False, self.ratio[:n],
                                 self.target_um_pp[:n], self.amplitude_um_pp[:n], self.drive_um_pp[:n],
                                 self.plate_um_pp[:n])
            if len(self._blocks) < 64:
                self._blocks[n] = block
                self._ratio_views[n] = block.ratio
        return block

    def ratio_view(self, n: int) -> np.ndarray:
        """The lookup's buffer for a block of length ``n`` (the block's own ratio may be an effect player's).

        Parameters
        ----------
        n : int

        Returns
        -------
        numpy.ndarray
            float32, ``n`` long.

        Examples
        --------
        >>> buffers = ControlBuffers(256)
        >>> view = buffers.ratio_view(32)
        >>> len(view), view.dtype, view.base is buffers.ratio
        (32, dtype('float32'), True)
        """
        view = self._ratio_views.get(n)
        return self.ratio[:n] if view is None else view


class Renderer:
    """See the module docstring. Thread use: ``push`` from any thread; one thread pulls.

    Parameters
    ----------
    texture : Texture
        The friction texture.
    model : FrictionModel
        The friction model: ratio to amplitude (µm p-p).
    profile : Plate
        The plate (its limit, drive ceiling, time constant, carriers).
    settings : RenderSettings
        Rates (Hz), carrier, default force (N), pre-compensation, prediction, planning.
    trajectory : RecordedTrajectory or SwipePath or LiveTrajectory, optional
        Where the finger is (default: live touches pushed with :meth:`push`).
    effects : tuple of Binding, optional
        Temporal effects (default: the texture's own).
    sampler : Sampler, optional
        The texture's lookup (default: one made here).

    Examples
    --------
    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.render.paths import SwipePath
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> from ultraglide.textures.library import resolve_texture
    >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
    ...                     trajectory=SwipePath(duration_s=0.01))
    >>> block = renderer.control(duration_s=0.01)        # the whole swipe: 10 ms at 12 kHz
    >>> len(block.time_s), bool(block.amplitude_um_pp.max() <= renderer.profile.max_amplitude_um_pp)
    (120, True)
    """

    def __init__(self, texture: Texture, model: FrictionModel, profile: Plate,
                 settings: RenderSettings = RenderSettings(),
                 trajectory: RecordedTrajectory | SwipePath | LiveTrajectory | None = None,
                 effects: tuple | None = None, sampler: Sampler | None = None):
        """``effects``: temporal effects (``textures.effects.Binding``) to play instead of the texture's own;
        ``sampler``: the lookup already built for ``texture`` with ``settings.band_limited_lookup`` (a caller
        rendering the same texture again, e.g. a dry run's repeated trials), else built here."""
        self.texture, self.model, self.profile, self.settings = texture, model, profile, settings
        self.carrier_hz = settings.carrier_hz or profile.resonance_hz
        try:
            profile.check_carrier(self.carrier_hz, settings.audio_rate_hz)
        except (ValueError, RuntimeError) as error:  # DeviceError: the plate or the audio rate refuses the carrier
            raise RenderError(str(error)) from None
        kernels.warm_up()
        model.warm_up()
        rate = settings.control_rate_hz
        self.limit_um_pp = profile.max_amplitude_um_pp
        if sampler is not None and sampler.texture is not texture:
            raise RenderError("the sampler given was built for another texture")
        self.sampler = sampler if sampler is not None else Sampler(texture, band_limited=settings.band_limited_lookup)
        if isinstance(trajectory, SwipePath):  # a path without a start crosses this texture as across() would
            trajectory = trajectory.placed_on(texture.width_mm, texture.height_mm)
        self.trajectory = trajectory or LiveTrajectory(settings.predictor, settings.lookahead_s)
        self.envelope = EnvelopeChain(rate, settings.attack_s, settings.release_s, settings.band_hz,
                                      settings.slew_um_per_ms, self.limit_um_pp, profile.time_constant_s,
                                      profile.max_drive_um_pp, settings.precompensate)
        self.counters = Counters()
        self.offline = not isinstance(self.trajectory, LiveTrajectory)
        self.observers: list = []  # callables given each ControlBlock as it is rendered
        self.default_force_n = settings.default_force_n
        self.paused = False
        self._next_time = self.trajectory.start_s if self.offline else None
        self._last_xy = None
        self._running = True
        self._last_drive = 0.0  # the last drive sample rendered
        self._offsets = np.zeros(0)
        self.last_block: ControlBlock | None = None  # the newest block rendered
        self._buffers: ControlBuffers | None = None  # used by every block when set (control_buffers(always=True))
        self._effects_override = effects
        self.effects = self._player(texture)
        self.planner: Planner | None = None  # set for a model with friction dynamics (settings.plan)
        self._plan_buffers(model)
        self.speed_scale = 1.0  # the settled speed law's amplitude scale at the last block's finger speed (1: none)

    def _plan_buffers(self, model: FrictionModel) -> None:
        """A planner and its buffers for a model with friction dynamics (built outside any real-time block)."""
        dynamics = getattr(model, "dynamics", None)
        self._plan_floor = 0.0  # the planner's floor, below which the effects mixed after it are counted
        if dynamics is None or not self.settings.plan:
            self.planner = None
            return
        self.planner = Planner(dynamics, self.settings.control_rate_hz)
        room = 128
        self._ahead_t, self._ahead_x, self._ahead_y = np.empty(room), np.empty(room), np.empty(room)
        self._ahead_ratio = np.empty(room, dtype=np.float32)
        self._command = np.empty(4096)

    def _player(self, texture: Texture) -> EffectPlayer | None:
        bindings = texture.effects if self._effects_override is None else self._effects_override
        return EffectPlayer(bindings, self.settings.control_rate_hz) if bindings else None

    def set_effects(self, effects: tuple | None) -> None:
        """Play these effects (``textures.effects.Binding``) from the next block on; None: the texture's own.

        Parameters
        ----------
        effects : tuple of Binding or None

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> renderer.set_effects(())                   # none, whatever the texture holds
        >>> renderer.effects is None
        True
        """
        self._effects_override = None if effects is None else tuple(effects)
        self.effects = self._player(self.texture)

    def trigger(self, name: str, t_s: float | None = None) -> bool:
        """The app's named event (a widget's value changing) at ``t_s`` (perf_counter s, default now):
        starts the effects bound to it. False if none is.

        Parameters
        ----------
        name : str
            The event's name, as the effects' bindings say it.
        t_s : float, optional
            When, perf_counter s.

        Returns
        -------
        bool
            Whether an effect is bound to ``name``.

        Examples
        --------
        A grating holds no effects, so no event starts one:

        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> renderer.trigger("click")
        False
        """
        player = self.effects
        return player is not None and player.trigger(name, time.perf_counter() if t_s is None else t_s)

    def control_buffers(self, capacity: int = 4096, always: bool = False) -> ControlBuffers:
        """Preallocated outputs to pass as ``control(..., out=)`` on a real-time path. ``always``: every
        block is written into them, also those ``audio()`` asks for (which copies what it keeps); only
        for a renderer whose observers, if any, do not keep blocks (the engine's).

        Parameters
        ----------
        capacity : int
            The longest block, control samples.
        always : bool

        Returns
        -------
        ControlBuffers

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.paths import SwipePath
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
        ...                     trajectory=SwipePath(duration_s=0.1))
        >>> buffers = renderer.control_buffers(128)
        >>> block = renderer.control(100, out=buffers)
        >>> buffers.capacity, block.amplitude_um_pp.base is buffers.amplitude_um_pp
        (128, True)
        """
        self._offsets = np.arange(capacity) * (1.0 / self.settings.control_rate_hz)
        buffers = ControlBuffers(capacity)
        if always:
            self._buffers = buffers
        return buffers

    # ---- input -------------------------------------------------------------------------------
    def push(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None = None, down: bool = True) -> None:
        """A touch report (perf_counter seconds, mm, N). Only for live rendering.

        Parameters
        ----------
        t_s : float
            When the panel saw it, perf_counter s.
        x_mm, y_mm : float
            Where, mm on the texture.
        force_n : float, optional
            The finger's force, N (default: the renderer's default force).
        down : bool
            Whether the finger touches.

        Raises
        ------
        RenderError
            A renderer playing a recorded trajectory or a swipe.

        Examples
        --------
        A finger resting on a grating: the plate, at rest before, vibrates (the attack ramp, 5 ms):

        >>> import time
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> now = time.perf_counter()
        >>> float(renderer.control(120, now_s=now).amplitude_um_pp.max())          # 10 ms, no finger
        0.0
        >>> renderer.push(now + 0.01, 10.0, 10.0)
        >>> float(renderer.control(120, now_s=now + 0.01).amplitude_um_pp.max()) > 0
        True
        """
        if self.offline:
            raise RenderError("this renderer plays a recorded trajectory; it takes no live reports")
        self.trajectory.push(t_s, x_mm, y_mm, force_n, down)

    @property
    def tail_s(self) -> float:
        """How long the output takes to come to rest after the finger lifts, s: the release, seven of the plate's time
        constants, and five periods of the envelope's band limit.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> round(renderer.tail_s, 6), round(0.010 + 7 * 200 / (3.141592653589793 * 25000) + 5 / 1000, 6)
        (0.032825, 0.032825)
        """
        return self.settings.release_s + 7.0 * self.profile.time_constant_s + 5.0 / self.settings.band_hz

    def stop(self) -> None:
        """Ramp the output down (release); :attr:`finished` turns true when it is at rest.

        Examples
        --------
        >>> import time
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> now = time.perf_counter()
        >>> renderer.push(now, 10.0, 10.0)
        >>> _ = renderer.control(120, now_s=now)
        >>> renderer.stop()
        >>> _ = renderer.control(duration_s=2 * renderer.tail_s, now_s=now + 0.01)    # the release, then rest
        >>> renderer.finished
        True
        """
        self._running = False

    # ---- live changes (from the UI thread; each is one reference swap) ------------------------------
    def set_texture(self, texture: Texture) -> None:
        """Render another texture from the next block on (its lookup tables are built here).

        Parameters
        ----------
        texture : Texture

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> renderer.set_texture(resolve_texture("grating-2mm"))
        >>> renderer.texture.name, renderer.sampler.texture is renderer.texture
        ('grating-2mm', True)
        """
        sampler = Sampler(texture, band_limited=self.settings.band_limited_lookup)
        player = self._player(texture)
        self.texture, self.sampler, self.effects = texture, sampler, player

    def set_model(self, model: FrictionModel) -> None:
        """Use another friction model from the next block on.

        Parameters
        ----------
        model : FrictionModel

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import ExponentialModel, StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> renderer.set_model(ExponentialModel())
        >>> type(renderer.model).__name__, renderer.planner        # a model without friction dynamics plans nothing
        ('ExponentialModel', None)
        """
        if getattr(model, "dynamics", None) is not None and self.settings.plan:
            self._plan_buffers(model)
        else:
            self.planner = None
        self.model = model

    def set_default_force(self, force_n: float) -> None:
        """The force assumed when the panel does not measure it, N.

        Parameters
        ----------
        force_n : float
            N, > 0.

        Raises
        ------
        RenderError
            A force that is not positive.

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> renderer.set_default_force(1)
        >>> renderer.default_force_n
        1.0
        >>> renderer.set_default_force(0.0)
        Traceback (most recent call last):
        ...
        ultraglide.render.errors.RenderError: the default force must be positive, got 0.0
        """
        if not force_n > 0:
            raise RenderError(f"the default force must be positive, got {force_n}")
        self.default_force_n = float(force_n)

    def pause(self, paused: bool = True) -> None:
        """Ramp the output to rest while paused, and back when resumed.

        Parameters
        ----------
        paused : bool

        Examples
        --------
        A finger on a grating, paused from the start: the plate stays at rest:

        >>> import time
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"))
        >>> renderer.pause()
        >>> now = time.perf_counter()
        >>> renderer.push(now, 10.0, 10.0)
        >>> float(renderer.control(120, now_s=now).amplitude_um_pp.max())
        0.0
        """
        self.paused = paused

    def __repr__(self) -> str:
        """``Renderer(Texture('wood', ...), ExponentialModel(...), plate 'sim-plate', live)``."""
        path = "live"
        if self.offline:
            path = f"{type(self.trajectory).__name__} of {self.trajectory.end_s - self.trajectory.start_s:.3g} s"
        return f"Renderer({self.texture!r}, {self.model!r}, plate {self.profile.name!r}, {path})"

    @property
    def finished(self) -> bool:
        """At rest after a stop, or (offline) after the path's end.

        Examples
        --------
        A 10 ms swipe: not finished at its end, finished once the output has come to rest (:attr:`tail_s`):

        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.paths import SwipePath
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
        ...                     trajectory=SwipePath(duration_s=0.01))
        >>> _ = renderer.control(duration_s=0.01)
        >>> renderer.finished
        False
        >>> _ = renderer.control(duration_s=2 * renderer.tail_s)
        >>> renderer.finished
        True
        """
        ended = not self._running or (self.offline and self._next_time > self.trajectory.end_s)
        return ended and self.envelope.at_rest and abs(self._last_drive) < 1e-6

    # ---- control rate ----------------------------------------------------------------------------
    def _times(self, n: int, now_s: float | None, out: np.ndarray | None = None) -> np.ndarray:
        period = 1.0 / self.settings.control_rate_hz
        if self.offline:
            now_s = None  # a recorded path runs on its own sample clock, whoever pulls it
        if self._next_time is None or (now_s is not None and abs(self._next_time - now_s) > RESYNC_S):
            if self._next_time is not None and now_s > self._next_time:
                self.counters.late_blocks += 1
            self._next_time = now_s if now_s is not None else time.perf_counter()
        if len(self._offsets) < n:
            self._offsets = np.arange(n) * period
        times = np.add(self._offsets[:n], self._next_time, out=out)
        self._next_time += n * period
        return times

    @property
    def control_rate_hz(self) -> float:
        """The control rate (Hz): how many envelope samples a second of :meth:`control` gives (12 kHz unless
        the settings say otherwise).

        Examples
        --------
        >>> from ultraglide.devices.profiles import load_profile
        >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
        >>> from ultraglide.textures.library import resolve_texture
        >>> renderer = Renderer(resolve_texture("grating-1mm"), StretchedExponentialModel(), load_profile("sim-plate"),
        ...                     RenderSettings(control_rate_hz=16000.0))
        >>> renderer.control_rate_hz, len(renderer.control(duration_s=0.01).time_s)      # 16 kHz × 10 ms
        (16000.0, 160)
        """
        return self.settings.control_rate_hz

    def control(self, n: int | None = None, now_s: float | None = None, out: ControlBuffers | None = None, *,
                duration_s: float | None = None) -> ControlBlock:
        """The next stretch of the drive envelope, at the control rate (:attr:`control_rate_hz`).

        One pipeline for every source of finger positions (a live finger, a recorded log, a swipe): times,
        the finger, the lookup (with the finger's step and direction), the effects, the model's inverse at
        the finger's force, the envelope.

        Parameters
        ----------
        n : int, optional
            How many control samples (at :attr:`control_rate_hz`); or give ``duration_s``.
        now_s : float, optional
            The ``time.perf_counter`` time (s) the first of them reaches the plate (live rendering); the
            renderer re-anchors its clock to it if needed. Ignored for a recorded path or a swipe.
        out : ControlBuffers, optional
            Preallocated buffers (:meth:`control_buffers`); the block returned is then reused, and a live
            finger's block allocates no array.
        duration_s : float, optional
            How long a stretch (s), instead of ``n``: ``round(duration_s * control_rate_hz)`` samples.

        Returns
        -------
        ControlBlock
            The samples' times (s), the finger (mm), the target friction ratio, and the amplitudes at each
            stage (µm p-p): target, envelope, drive and the plate model's.

        Raises
        ------
        RenderError
            Neither or both of ``n`` and ``duration_s``, or a negative one.

        Examples
        --------
        >>> from ultraglide.render.physics.friction_models import ExponentialModel
        >>> from ultraglide.textures.procedural import grating
        >>> from ultraglide.devices.profiles import load_profile
        >>> r = Renderer(grating(1.0), ExponentialModel(), load_profile("sim-plate"), trajectory=SwipePath())
        >>> len(r.control(duration_s=0.25).drive_um_pp), r.control_rate_hz     # a quarter second at 12 kHz
        (3000, 12000.0)
        """
        if duration_s is not None or n is None:
            n = self._samples_for(n, duration_s)
        started = time.perf_counter()
        out = out or self._buffers
        block = out.block(n) if out is not None and n <= out.capacity else None  # a longer catch-up block allocates
        times = self._times(n, now_s, None if block is None else block.time_s)
        finger = self.trajectory.state(times, out=None if block is None else (block.x_mm, block.y_mm))
        x, y = finger.x_mm, finger.y_mm
        step, direction = self._motion(finger, n)
        ratio = self.sampler.ratio(x, y, step_mm=step if self.settings.band_limited_lookup else None,
                                   direction=direction, out=None if block is None else out.ratio_view(n))
        force = self._force(finger.force_n)
        down = finger.down & self._running & (not self.paused)  # a bool for a live finger, else one per sample
        planner = self.planner
        asked = ratio
        law = speed_law_of(self.model)  # read each block: a closed loop's host model may change under it
        if law is None:
            self.speed_scale = 1.0
        if planner is not None or law is not None:
            speed, one_step, heading = self._speed(finger, step, direction, n)
            # the settled reduction's speed law: the amplitude a ratio needs at this block's speed over the
            # model's (1 without a law); the inverse is asked within limit / scale (render/physics/speed_law.py)
            self.speed_scale = law.one_scale(speed) if law is not None else 1.0
            if planner is not None:  # the texture is planned (its future is known along the path)...
                asked = self._planned(times, ratio, force, down, speed, one_step, heading, n)
        player = self.effects
        if player is not None:  # ...the effects are not: a tap cannot be foreseen, so they play as authored, mixed
            above, below = player.clipped_samples, player.below_floor  # before the inverse (the same envelope,
            planned = asked is not ratio  # clamps and limiter), from the planner's command where it plans
            mixed = player.mix(times, x, y, finger.down, ratio, also=asked if planned else None,
                               also_floor=self._plan_floor)
            self.counters.clipped_samples += player.clipped_samples - above + player.below_floor - below
            # the planner's felt prediction stays the texture command's own: told what the effect took, it would
            # raise its command to undo the effect (a 50 Hz buzz would be cancelled)
            if block is None:
                mixed = mixed.copy()  # the player's buffer is overwritten by the next block
            asked = mixed if not planned else asked
            ratio = mixed
        scale = self.speed_scale
        inversion = scaled_inverse(self.model, asked, force, self.limit_um_pp, scale,
                                   out=None if block is None else block.target_um_pp)
        if planner is not None:
            self.counters.clipped_samples += self._unreachable
        elif np.all(down):
            self.counters.clipped_samples += inversion.clamped
        elif inversion.clamped and np.any(down):  # count only the clamps while the finger touches
            floor = self.model.floor_ratio(force, reach_limit(self.limit_um_pp, scale))
            self.counters.clipped_samples += int(np.count_nonzero((ratio < floor) & down))
        target = inversion.amplitude_um_pp
        if block is not None:  # the real-time path: timed by its caller, nothing appended
            self.envelope.process(target, down, out=(block.amplitude_um_pp, block.drive_um_pp, block.plate_um_pp))
            if block.x_mm is not x:
                block.x_mm[:], block.y_mm[:] = x, y
            block.down, block.ratio, block.target_um_pp = finger.down, ratio, target
            block.planned_ratio = asked  # a view of the planner's buffer (the next block overwrites it), or ratio
        else:
            envelope = self.envelope.process(target, down)
            block = ControlBlock(times, x, y, finger.down, ratio, target, envelope.amplitude_um_pp,
                                 envelope.drive_um_pp, envelope.plate_um_pp,
                                 asked.copy() if asked is not ratio else ratio)
            self.counters.render_times_s.append(time.perf_counter() - started)
            if len(self.counters.render_times_s) > 100_000:
                del self.counters.render_times_s[:50_000]
        counters = self.counters
        counters.ramps = self.envelope.ramps
        counters.drive_clipped_samples = self.envelope.drive_clipped
        counters.control_samples += n
        if n:
            self._last_drive = float(block.drive_um_pp[n - 1])
        self.last_block = block
        for observer in self.observers:
            observer(block)
        return block

    def _speed(self, finger: FingerState, step, direction, n: int) -> tuple[float, float, tuple]:
        """The finger's speed over the block (mm/s, one a block), its step per control sample (mm) and its heading:
        a live prediction's velocity, else the mean step while the finger touches times the control rate (a
        block that ends a stroke, as an export's second-long blocks do, is not slowed by the samples after it)."""
        if finger.velocity_mm_s is not None:
            return math.hypot(*finger.velocity_mm_s), step, direction
        down = finger.down
        touching = np.count_nonzero(down) if isinstance(down, np.ndarray) and n else 0
        if touching and touching < n:
            one_step = float(np.add.reduce(step, where=down)) / touching
        else:
            one_step = float(np.mean(step)) if n else 0.0
        heading = (float(direction[0][n - 1]), float(direction[1][n - 1])) if n else (0.0, 0.0)
        return one_step * self.settings.control_rate_hz, one_step, heading

    def _planned(self, times, ratio, force, down, speed: float, one_step: float, heading, n: int) -> np.ndarray:
        """The planning stage: the static ratio to command so the felt friction follows ``ratio`` (the texture's
        targets), from the texture along the finger's path over the planner's horizon, at the finger's ``speed``
        (mm/s) with its step (mm) and heading; sets the count of unreachable targets (below the floor at that
        speed, while the finger touches)."""
        planner = self.planner
        planner.set_speed(speed)
        steps = planner.steps
        touching = bool(np.any(down))
        ahead_ratio = self._ahead_ratio[:steps]  # read only at a decision (the kernel holds its command between)
        if touching and planner.decides_within(n):  # so the path and the texture ahead are looked up only then
            ahead_t = planner.ahead_times(float(times[0]) if n else 0.0, n, out=self._ahead_t)
            ahead = self.trajectory.state(ahead_t, out=(self._ahead_x[:steps], self._ahead_y[:steps]))
            ahead_ratio = self.sampler.ratio(ahead.x_mm, ahead.y_mm,
                                             step_mm=one_step * planner.stride if self.settings.band_limited_lookup
                                             else None,
                                             direction=heading, out=ahead_ratio)
        scalar_force = float(force) if not isinstance(force, np.ndarray) else float(np.mean(force))
        floor = self.model._floor(scalar_force, min(reach_limit(float(self.limit_um_pp), self.speed_scale),
                                                    self.model.max_amplitude_um_pp))
        if len(self._command) < n:
            self._command = np.empty(n)  # a catch-up block longer than any before: once
        below = planner.below_floor
        self._plan_floor = floor  # the effects subtracted from the command after it count below it
        command = planner.plan(ratio, ahead_ratio, floor, touching, self._command[:n])
        self._unreachable = (planner.below_floor - below) if touching else 0
        return command

    def _samples_for(self, n: int | None, duration_s: float | None) -> int:
        if (n is None) == (duration_s is None):
            raise RenderError("give control() either n (control samples) or duration_s (s), one of them")
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise RenderError(f"duration_s must be a duration in seconds (0 or more), got {duration_s}")
        return round(duration_s * self.settings.control_rate_hz)

    def _motion(self, finger: FingerState, n: int) -> tuple:
        """The finger's step per control sample (mm) and its direction, for the band-limited lookup: one step and
        one direction when the finger moves on a line over the block (a live prediction), else one per sample,
        from each sample to the next (a jump between blocks, a corrected prediction or a new stroke, is not
        motion: the first sample takes the second's)."""
        x, y = finger.x_mm, finger.y_mm
        if finger.velocity_mm_s is not None:
            dx, dy = finger.velocity_mm_s
            step = math.hypot(dx, dy) / self.settings.control_rate_hz
        else:
            previous = self._last_xy if self._last_xy is not None else (x[0], y[0])
            dx, dy, step = np.empty(n), np.empty(n), np.empty(n)
            kernels.motion(x, y, float(previous[0]), float(previous[1]), dx, dy, step)
        if n:
            self._last_xy = (x[n - 1], y[n - 1])
        return step, (dx, dy)

    def _force(self, force_n):
        """The finger's force, N: the touch's where it was measured, else the default (a number, or one per
        sample)."""
        if not isinstance(force_n, np.ndarray):
            return self.default_force_n if math.isnan(force_n) else float(force_n)
        return np.where(np.isnan(force_n), self.default_force_n, force_n)
