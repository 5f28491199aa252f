"""The simulated finger from plain options: what ``plate-sim --finger`` and the in-process ``--device sim`` build.

:class:`FingerConfig` holds picklable values (it crosses to the engine's process); :func:`build_finger`
makes the :class:`~ultraglide.devices.sim.finger.SimulatedFinger`, its friction law loaded as the host loads a
model (``render.physics.load_model``: ``exponential``, ``stretched``, ``paper``, ``table:FILE.csv`` for a
measured finger with columns ``amplitude_um_pp,relative_friction,force_n``, a calibration TOML), since the
finger itself (in ``devices``) only takes a callable.

The default finger is unlike the host's default model on purpose: its static (stretched) law with its amplitude
scale times 0.7 (it needs 30 % less vibration) and a floor of 0.1 that vibration does not remove, drifting
±30 % in scale over a minute, its friction at rest rising 25 % with a long dwell, pressing with a force
that wanders in 0.2-1 N, sliding at 100 mm/s. Like the host's default model and measured fingers, its friction
lags the law (the published dynamics; ``dynamics=False``, ``--no-finger-dynamics``: it follows at once); on the
engine's ``--device sim`` it lags as the model rendering assumes (:meth:`FingerConfig.as_the_model_assumes`).
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, replace

import numpy as np
from ultraglide.devices.sim.finger import (
    FingerDynamics,
    FingerParams,
    FingerSpeedLaw,
    ForceScript,
    SensorFault,
    SimulatedFinger,
    adjusted_law,
)
from ultraglide.devices.sim.finger_log import FingerLog
from ultraglide.devices.sim.force_sensors import ForceSensorParams

DEFAULT_LAW = "default"
DEFAULT_BASE = "stretched"  # the host's default model's static law (the default is it with dynamics)
DEFAULT_SCALE = 0.7
DEFAULT_FLOOR = 0.1


@dataclass(frozen=True)
class FingerConfig:
    """The simulated finger's options (see :mod:`devices.finger` for each); ``law`` a model spec or ``default``;
    ``scale`` and ``floor`` adjust it (None: 0.7 and 0.1 for the default law, 1 and 0 for any other);
    ``force`` a force spec (``0.5``, ``walk``, ``walk:LOW-HIGH``, ``FILE.csv``); ``log`` a CSV of its truth.

    Examples
    --------
    >>> config = FingerConfig()
    >>> config.law_scale, config.law_floor, config.lags, FingerConfig(dynamics=False).law_words()
    (0.7, 0.1, True, "stretched (the host default's static law), scale x0.7, floor 0.1")
    >>> FingerConfig(law="dynamic").lags, config.with_log("finger.csv").log
    (True, 'finger.csv')
    """

    law: str = DEFAULT_LAW
    scale: float | None = None
    floor: float | None = None
    mu0: float = 1.0
    drift: float = 0.3
    drift_period_s: float = 60.0
    moisture: float = 0.25
    moisture_tau_s: float = 20.0
    force: str = "walk"
    speed_mm_s: float = 100.0
    noise_n: float = 0.005
    bandwidth_hz: float = 300.0
    delay_ms: float = 1.0
    log: str | None = None
    seed: int = 0
    force_points: tuple | None = None  # (times s, forces N): a scripted press instead of ``force`` (a calibration's)
    faults: tuple[str, ...] = ()  # sensor faults, KIND:START-END (devices.finger.SensorFault)
    log_hz: float = 2000.0  # the log's rows a second
    # the friction lags the law (5 ms down, 70 ms back at 22 mm/s); None: the law's own way (the default finger,
    # a dynamic[:X] law and a calibration with fitted dynamics lag, other laws follow at once)
    dynamics: bool | None = None

    @property
    def lags(self) -> bool:
        """Whether the simulated finger's friction lags in time: as asked (``dynamics``), else for the default
        finger (as the host's default model assumes; the engine asks as its own model assumes,
        :meth:`as_the_model_assumes`), a ``dynamic`` law, or a calibration whose dynamics
        were fitted on the plate.

        Examples
        --------
        >>> FingerConfig().lags, FingerConfig(dynamics=False).lags, FingerConfig(law="stretched").lags
        (True, False, False)
        >>> FingerConfig(law="dynamic:stretched").lags, FingerConfig(law="stretched", dynamics=True).lags
        (True, True)
        """
        if self.dynamics is not None:
            return self.dynamics
        inner = self.law.split(":", 2)[-1] if self.law.startswith("speed:") else self.law  # speed:S:NAME's NAME
        return (inner == DEFAULT_LAW or inner == "dynamic" or inner.startswith("dynamic:")
                or _fitted_dynamics(inner) is not None)

    @property
    def law_scale(self) -> float:
        """The amplitude scale of the finger's law: as given, else the default law's own, else 1.

        Examples
        --------
        >>> FingerConfig().law_scale, FingerConfig(law="exponential").law_scale, FingerConfig(scale=0.5).law_scale
        (0.7, 1.0, 0.5)
        """
        return self.scale if self.scale is not None else (DEFAULT_SCALE if self.law == DEFAULT_LAW else 1.0)

    @property
    def law_floor(self) -> float:
        """The ratio floor of the finger's law: as given, else the default law's own, else 0.

        Examples
        --------
        >>> FingerConfig().law_floor, FingerConfig(law="exponential").law_floor, FingerConfig(floor=0.2).law_floor
        (0.1, 0.0, 0.2)
        """
        return self.floor if self.floor is not None else (DEFAULT_FLOOR if self.law == DEFAULT_LAW else 0.0)

    def law_words(self) -> str:
        """The finger's law in words: its base model, scale, floor and whether it lags.

        Returns
        -------
        str

        Examples
        --------
        >>> FingerConfig(law="exponential", floor=0.2).law_words()
        'exponential, floor 0.2'
        >>> FingerConfig(law="exponential", dynamics=True).law_words()   # which lag: the published one, or a fit's
        'exponential, friction in time (5 ms down, 70 ms back at 22 mm/s (x (v_ref/v)^0.5))'
        """
        base = f"{DEFAULT_BASE} (the host default's static law)" if self.law == DEFAULT_LAW else self.law
        scale, floor = self.law_scale, self.law_floor
        lag = finger_dynamics(self) if self.lags else None
        return (base + (f", scale x{scale:g}" if scale != 1.0 else "") + (f", floor {floor:g}" if floor else "")
                + (f", friction in time ({lag.words().removeprefix('friction lags: ')})" if lag is not None else ""))

    def with_log(self, path: str | None) -> FingerConfig:
        """A copy that logs the finger to ``path`` (None: no log).

        Parameters
        ----------
        path : str or None
            The CSV file, or None.

        Returns
        -------
        FingerConfig

        Examples
        --------
        >>> logged = FingerConfig(speed_mm_s=80.0).with_log("finger.csv")
        >>> logged.log, logged.speed_mm_s, logged.with_log(None).log
        ('finger.csv', 80.0, None)
        """
        return replace(self, log=path)

    def as_the_model_assumes(self, model_lags: bool) -> FingerConfig:
        """The finger for a host whose model lags or not (``model_lags``): the default finger with no lag asked
        for lags as that model assumes, since a static model's loop reads a lagging finger's slow recovery as a
        slipperier finger, never finds its sensors' timing, and measures nothing; any other config as it is.

        Parameters
        ----------
        model_lags : bool
            Whether the host's model has friction dynamics.

        Returns
        -------
        FingerConfig

        Examples
        --------
        >>> FingerConfig().as_the_model_assumes(False).lags, FingerConfig().as_the_model_assumes(True).lags
        (False, True)
        >>> FingerConfig(dynamics=True).as_the_model_assumes(False).lags   # asked for: kept
        True
        """
        if self.law == DEFAULT_LAW and self.dynamics is None:
            return replace(self, dynamics=model_lags)
        return self


@functools.lru_cache(maxsize=16)
def _fitted_dynamics(law: str):
    """The friction dynamics a law's own file holds (a calibration whose ``[dynamics]`` were fitted on the plate),
    else None; a law that cannot be loaded has none here (``finger_law`` says what is wrong with it)."""
    if law == DEFAULT_LAW or law == "dynamic" or law.startswith("dynamic:") or not law.endswith(".toml"):
        return None
    return _loaded_part(law, "dynamics")


def _loaded_part(law: str, part: str):
    """The attribute ``part`` of the model ``law`` names, loaded quietly; None where it has none or cannot be
    loaded (``finger_law`` says what is wrong with such a law, where the law itself is built)."""
    from ultraglide.render.physics.calibration import load_model

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return getattr(load_model(law), part, None)
    except Exception:  # noqa: BLE001 - refused with its words where the law itself is built
        return None


def finger_dynamics(config: FingerConfig) -> FingerDynamics | None:
    """How the simulated finger's friction lags its law: the dynamics fitted for this finger where its law is a
    calibration that has them (``calibrate`` on the plate), else the published ones where the config asks for a
    lag (the default finger, ``--finger-dynamics``, a ``dynamic`` law), else none.

    Parameters
    ----------
    config : FingerConfig
        The finger's options.

    Returns
    -------
    FingerDynamics or None
        Time constants in s, the reference speed in mm/s; None for a finger whose friction follows its law at once.

    Examples
    --------
    >>> finger_dynamics(FingerConfig(dynamics=False)) is None, finger_dynamics(FingerConfig()).recovery_s
    (True, 0.07)
    """
    fitted = _fitted_dynamics(config.law)
    if fitted is not None:
        return FingerDynamics(fitted.onset_s, fitted.recovery_s, fitted.reference_speed_mm_s, fitted.speed_exponent)
    return FingerDynamics() if config.lags else None


def _speed_law(law: str):
    """The settled speed law a law holds (``speed:S:NAME``, ``dynamic:speed:S:NAME``, a calibration's ``[speed]``),
    else None. Read again each time (once a finger is built): a calibration file edited since is read as it is."""
    return None if law == DEFAULT_LAW else _loaded_part(law, "speed_law")


def finger_speed_law(config: FingerConfig) -> FingerSpeedLaw | None:
    """How the simulated finger's settled reduction weakens with its speed: the law its model spec holds
    (``--finger speed:S:NAME`` or ``dynamic:speed:S:NAME``, a calibration's ``[speed]``), handed to the plate's
    own implementation; None for no dependence.

    Parameters
    ----------
    config : FingerConfig

    Returns
    -------
    FingerSpeedLaw or None

    Examples
    --------
    >>> finger_speed_law(FingerConfig()) is None, finger_speed_law(FingerConfig(law="speed:0.5:stretched")).exponent
    (True, 0.5)
    """
    law = _speed_law(config.law)
    if law is None or law.exponent == 0.0:
        return None
    return FingerSpeedLaw(law.exponent, law.reference_speed_mm_s)


def finger_law(config: FingerConfig):
    """The finger's friction law, ratio = law(amplitude_um_pp, force_n), as the config says.

    A host model's forward law (amplitudes beyond its validity held at its edge), its amplitude axis
    stretched by the config's scale and floored: d + (1 - d) law(a / scale, F).

    Parameters
    ----------
    config : FingerConfig
        The finger's options; ``law`` a model spec or ``default``.

    Returns
    -------
    callable
        law(amplitude_um_pp, force_n) -> friction ratio (arrays in, arrays out; µm peak-to-peak, N).

    Raises
    ------
    UltraglideError
        What ``load_model`` raises for a bad spec (one line).

    Examples
    --------
    The ``stretched`` finger is the host's model; the default one is it without its floor, stretched 0.7× and
    floored at 0.1:

    >>> import numpy as np
    >>> from ultraglide.render.physics.friction_models import StretchedExponentialModel
    >>> amplitudes = np.array([0.0, 2.0])
    >>> law = finger_law(FingerConfig(law="stretched"))
    >>> bool(np.allclose(law(amplitudes, 0.5), StretchedExponentialModel().relative_friction(amplitudes, 0.5)))
    True
    >>> bare = StretchedExponentialModel(residual_ratio=0.0).relative_friction(amplitudes / 0.7, 0.5)
    >>> bool(np.allclose(finger_law(FingerConfig())(amplitudes, 0.5), 0.1 + 0.9 * bare))
    True
    """
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.physics.friction_models import StretchedExponentialModel

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a table's or a calibration's notes are for the host, not the finger
        # the default finger: the host's default law without its floor, then floored at 0.1 below (as before the
        # host's default had one); a dynamic law's steady state is its static model's
        model = (StretchedExponentialModel(residual_ratio=0.0) if config.law == DEFAULT_LAW
                 else load_model(config.law))
        model = getattr(model, "static", model)
        model = getattr(model, "static", model)  # a speed law's static model (its law: finger_speed_law)
    law = _stretched_law(model) or _gridded_law(model)
    law.__qualname__ = config.law_words()
    return adjusted_law(law, config.law_scale, config.law_floor)


def _stretched_law(model):
    """The stretched law's formula from the model's own parameters, d + (1 - d) exp(-(a / s(F))^beta) with
    s(F) = s0 (F / 0.5 N)^p, without the model's checks and notes: the simulated plate calls it a thousand times a
    second on short arrays, where the checks cost most of the time (tests compare it with the model's own)."""
    from ultraglide.render.physics import friction_models as fm

    if not isinstance(model, fm.StretchedExponentialModel) or type(model).relative_friction is not \
            fm.StretchedExponentialModel.relative_friction:
        return None
    s0, beta, exponent, floor = model.scale_um_pp, model.shape, model.force_exponent, model.residual_ratio
    reference, low, high = fm.REFERENCE_FORCE_N, fm.MIN_FORCE_N, fm.MAX_FORCE_N

    def law(amplitude_um_pp, force_n):
        scale = s0 * np.power(np.minimum(np.maximum(force_n, low), high) / reference, exponent)  # np.clip's values
        falling = np.exp(-np.power(np.asarray(amplitude_um_pp, dtype=float) / scale, beta))
        return floor + (1.0 - floor) * falling if floor else falling

    return law


GRID_AMPLITUDES = 1025  # the forward law tabulated from 0 to the model's ceiling: 6 nm apart on 6 µm
GRID_FORCES = 97  # and from 0.01 to 10 N, evenly in log force (7 % apart: a squeeze film within 0.005)


def _gridded_law(model):
    """Any model's forward law, tabulated once and interpolated (bilinear in amplitude and log force): a table's or
    a squeeze film's forward law is a bisection through its inverse, 0.7 ms for the 48 samples of one of the
    simulated plate's 1 ms chunks, too slow for a plate that runs in real time beside the host (this: under 0.1 ms).
    Amplitudes beyond the model's validity are held at its edge, forces at 0.01 and 10 N."""
    ceiling = float(model.max_amplitude_um_pp)
    amplitudes = np.linspace(0.0, ceiling, GRID_AMPLITUDES)
    log_forces = np.linspace(np.log(0.01), np.log(10.0), GRID_FORCES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # force-range notes: the finger goes where it likes
        grid = np.array([model.relative_friction(amplitudes, float(np.exp(f))) for f in log_forces])
    a_step, f_step = amplitudes[1] - amplitudes[0], log_forces[1] - log_forces[0]

    def law(amplitude_um_pp, force_n):
        a = np.clip(np.asarray(amplitude_um_pp, dtype=float), 0.0, ceiling) / a_step
        f = (np.log(np.clip(np.asarray(force_n, dtype=float), 0.01, 10.0)) - log_forces[0]) / f_step
        a, f = np.broadcast_arrays(a, f)
        i = np.minimum(a.astype(np.intp), GRID_AMPLITUDES - 2)
        j = np.minimum(f.astype(np.intp), GRID_FORCES - 2)
        u, v = a - i, f - j
        return ((1 - v) * ((1 - u) * grid[j, i] + u * grid[j, i + 1])
                + v * ((1 - u) * grid[j + 1, i] + u * grid[j + 1, i + 1]))

    return law


def build_finger(config: FingerConfig, sample_rate_hz: int = 48000, sensor_rate_hz: int = 1000) -> SimulatedFinger:
    """The simulated finger the config describes, with its log (a file, written as it goes) if asked.

    Parameters
    ----------
    config : FingerConfig
        The finger's options.
    sample_rate_hz : int
        The finger's simulation rate, Hz.
    sensor_rate_hz : int
        Its force sensors' rate, Hz.

    Returns
    -------
    SimulatedFinger

    Raises
    ------
    UltraglideError
        A bad law, force script or fault spec, in one line.

    Examples
    --------
    >>> finger = build_finger(FingerConfig(force="0.5"))
    >>> finger.name  # doctest: +NORMALIZE_WHITESPACE
    "stretched (the host default's static law), scale x0.7, floor 0.1, friction in time (5 ms down, 70 ms back at
    22 mm/s (x (v_ref/v)^0.5))"
    """
    params = FingerParams(config.mu0, config.drift, config.drift_period_s, config.moisture, config.moisture_tau_s)
    sensors = ForceSensorParams(config.noise_n, config.bandwidth_hz, config.delay_ms / 1000.0, sensor_rate_hz,
                                seed=config.seed + 1)
    if config.force_points is not None:
        times, forces = config.force_points
        script = ForceScript.points(times, forces, [config.speed_mm_s] * len(times))
    else:
        script = ForceScript.parse(config.force, config.speed_mm_s, config.seed)
    law = finger_law(config)
    faults = tuple(SensorFault.parse(spec) for spec in config.faults)
    log = FingerLog(config.log, rate_hz=config.log_hz, sample_rate_hz=sample_rate_hz) if config.log else None
    dynamics = finger_dynamics(config)
    return SimulatedFinger(law, script, params, sensors, log, sample_rate_hz, name=config.law_words(), faults=faults,
                           dynamics=dynamics, speed_law=finger_speed_law(config))


def finger_words(config: FingerConfig) -> str:
    """One line for people: the finger's law, force, speed, drift and sensors.

    Parameters
    ----------
    config : FingerConfig
        The finger's options.

    Returns
    -------
    str

    Examples
    --------
    >>> finger_words(FingerConfig(force="0.5", drift=0.0, dynamics=False))  # doctest: +NORMALIZE_WHITESPACE
    "finger: stretched (the host default's static law), scale x0.7, floor 0.1; mu0 1, no drift, +25 % with dwell;
    force 0.5 at 100 mm/s; sensors 5 mN, 300 Hz, 1 ms"
    """
    drift = f"drift ±{100 * config.drift:g} % over {config.drift_period_s:g} s" if config.drift else "no drift"
    moisture = f"+{100 * config.moisture:g} % with dwell" if config.moisture else "no moisture"
    return (f"finger: {config.law_words()}; mu0 {config.mu0:g}, {drift}, {moisture}; force {config.force} at "
            f"{config.speed_mm_s:g} mm/s; sensors {1000 * config.noise_n:g} mN, {config.bandwidth_hz:g} Hz, "
            f"{config.delay_ms:g} ms")
