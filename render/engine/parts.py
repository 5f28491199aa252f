"""What the engine's process opens before it renders: the texture, the model, the plate's profile and the
device (with the simulated finger the config asks for), and, for the closed loop, the check that the device
has force sensors. Errors are one line, for the app to show (:func:`engine_main` sends them up the pipe).
"""

from __future__ import annotations


def load_parts(config):
    """Texture, model, profile and an opened device (with the simulated finger the config asks); one-line errors
    for bad ones."""
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

        finger = build_finger(config.finger or FingerConfig())
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
    """A library name or file, loaded here; or a Texture the app composed in memory (it came pickled)."""
    if isinstance(spec, str):
        from ultraglide.textures.library import resolve_texture

        return resolve_texture(spec)
    from ultraglide.textures.texture import Texture

    if not isinstance(spec, Texture):
        raise ValueError(f"a texture must be a name, a file or a Texture, not {type(spec).__name__}")
    return spec


def check_sensors(device, loop) -> None:
    """The closed loop needs normal and lateral force sensors: DeviceError if the connected device has none; the
    loop takes the device's sensor rate."""
    from ultraglide.devices import protocol as p
    from ultraglide.devices.errors import DeviceError

    hello = device.hello() if hasattr(device, "hello") else None
    wanted = p.SENSOR_NORMAL_FORCE | p.SENSOR_LATERAL_FORCE
    if hello is None or (hello.sensors & wanted) != wanted:
        raise DeviceError("the closed loop needs normal and lateral force sensors under the plate, and this plate "
                          "driver declares none; run it open loop (leave out --closed-loop)")
    loop.set_sensor_rate(hello.sensor_rate_hz)
