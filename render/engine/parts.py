"""What the engine's process opens before it renders: the texture, the model, the plate's profile and the
device (with the simulated finger the config asks for, or on ``sim`` with the closed loop the default finger; the
default finger lags where the model has friction dynamics, unless asked otherwise), and, for the closed loop, the
check that the device has force sensors. Errors are one line, for the app to show (:func:`engine_main` sends them
up the pipe).
"""

from __future__ import annotations


def load_parts(config):
    """Texture, model, profile and an opened device (with the simulated finger the config asks); one-line errors.

    Parameters
    ----------
    config : EngineConfig
        The engine's configuration: texture, model, profile and device by name, the finger and the loop.

    Returns
    -------
    tuple
        (Texture, FrictionModel, PlateProfile, Device): the device opened, not started.

    Raises
    ------
    UltraglideError
        A texture, model, profile or device that cannot be loaded or opened, or a finger or closed loop the
        device cannot take, in one line.

    Examples
    --------
    >>> from ultraglide.render.engine import EngineConfig
    >>> texture, model, profile, device = load_parts(EngineConfig(texture="grating-1mm", device="null"))
    >>> texture.name, model.name, profile.name, device.signal
    ('grating-1mm', 'dynamic', 'sim-plate', 'audio')
    >>> load_parts(EngineConfig(texture="grating-1mm", device="null", closed_loop=True))
    Traceback (most recent call last):
    ...
    ultraglide.devices.errors.DeviceError: the closed loop needs a plate driver with force sensors ... not null
    """
    import warnings

    from ultraglide.devices.rig import load_plate
    from ultraglide.devices.urls import open_device, parse_device_url
    from ultraglide.render.physics.calibration import load_model

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        texture = texture_of(config.texture)
    model = load_model(config.model)
    profile = load_plate(config.profile)
    kind = parse_device_url(config.device).kind
    finger = None
    if config.finger is not None or (config.closed_loop and kind == "sim"):
        if kind != "sim":
            from ultraglide.devices.errors import DeviceError

            raise DeviceError(f"a simulated finger goes on the in-process simulator (--device sim), not on "
                              f"{config.device}; a plate-sim on a port takes its own (plate-sim --finger)")
        from ultraglide.render.engine.finger_setup import FingerConfig, build_finger

        wanted = config.finger or FingerConfig()
        finger = build_finger(wanted.as_the_model_assumes(getattr(model, "dynamics", None) is not None))
    if config.closed_loop and kind not in ("sim", "serial"):
        from ultraglide.devices.errors import DeviceError

        raise DeviceError(f"the closed loop needs a plate driver with force sensors (sim or serial:PORT), not "
                          f"{config.device}")
    extra = {"finger": finger} if finger is not None else {}
    if config.closed_loop:
        extra["amplitude_loop"] = True
    device = open_device(config.device, profile, control_rate_hz=int(config.control_rate_hz),
                         carrier_hz=config.carrier_hz, track_resonance=config.track_resonance, **extra)
    return texture, model, profile, device


def texture_of(spec):
    """A library name or file, loaded here; or a Texture the app composed in memory (it came pickled).

    Parameters
    ----------
    spec : str or Texture
        A library name, a texture file's path, or a Texture.

    Returns
    -------
    Texture

    Raises
    ------
    ValueError
        ``spec`` is neither.
    TextureError
        No texture by that name or file.

    Examples
    --------
    >>> texture_of("grating-1mm").name
    'grating-1mm'
    >>> texture_of(42)
    Traceback (most recent call last):
    ...
    ValueError: a texture must be a name, a file or a Texture, not int
    """
    if isinstance(spec, str):
        from ultraglide.textures.library import resolve_texture

        return resolve_texture(spec)
    from ultraglide.textures.texture import Texture

    if not isinstance(spec, Texture):
        raise ValueError(f"a texture must be a name, a file or a Texture, not {type(spec).__name__}")
    return spec


def check_sensors(device, loop) -> None:
    """Check the device has normal and lateral force sensors for the closed loop; the loop takes their rate.

    Parameters
    ----------
    device : Device
        The opened device; a plate driver states its sensors in its handshake (``hello()``).
    loop : FrictionLoop
        The closed loop, told the device's sensor rate (Hz).

    Returns
    -------
    None

    Raises
    ------
    DeviceError
        The device declares no normal and lateral force sensors.

    Examples
    --------
    The null device states no sensors:

    >>> from ultraglide.devices.profiles import load_profile
    >>> from ultraglide.devices.urls import open_device
    >>> check_sensors(open_device("null", load_profile("sim-plate")), None)
    Traceback (most recent call last):
    ...
    ultraglide.devices.errors.DeviceError: the closed loop needs normal and lateral force sensors ... open loop ...
    """
    from ultraglide.devices import protocol as p
    from ultraglide.devices.errors import DeviceError

    hello = device.hello() if hasattr(device, "hello") else None
    wanted = p.SENSOR_NORMAL_FORCE | p.SENSOR_LATERAL_FORCE
    if hello is None or (hello.sensors & wanted) != wanted:
        raise DeviceError("the closed loop needs normal and lateral force sensors under the plate, and this plate "
                          "driver declares none; run it open loop (leave out --closed-loop)")
    loop.set_sensor_rate(hello.sensor_rate_hz)
