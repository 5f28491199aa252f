"""Which plate a command drives: ``--profile``, ``--rig``, or the simulated plate's own, by one rule.

Every command that takes a device (``play``, ``demo``, ``experiment``, ``calibrate``, ``latency``,
``plate sweep``, ``plate check``; ``export`` renders a file and takes them too) adds its options with
:func:`add_plate_options`, and ``ultraglide``'s main calls :func:`choose_plate` before the command runs:

- ``--rig RIG.toml`` names the plate (its profile with the drive chain's full scale and the smallest limit,
  :mod:`ultraglide.devices.rig`), and the device when ``--device`` is not given (``--device`` overrides the
  rig's device, not its plate: ``--rig RIG.toml --device wav:dry.wav`` records what the rig's plate would play).
  ``--rig`` and ``--profile`` are mutually exclusive: the rig names its plate itself.
- ``--profile PROFILE`` names the plate.
- Neither: a plate driver on a serial port that describes its plate in its handshake (its resonance, Q, full
  scale, limit, drive ceiling and carrier range: protocol v3's ``FEATURE_LINK_STATED``; the simulated and
  emulated boards do) supplies the profile, and the command says so in one line (on stderr, so that ``--json``
  stays JSON). Any other real output (``audio``, a ``serial:`` device that does not describe its plate) is
  refused in one line, exit 2, saying what to give; the simulated plate (``sim``), a recording (``wav:``),
  ``null`` and a command's simulated default keep the built-in ``sim-plate`` profile. A plate driver on a serial
  port binds its own limit at every handshake when it is smaller than the profile's, whoever named the profile.

The plate then travels as a spec string (``args.profile``): a profile's name or file, ``rig:PATH``, or
``hello:{...}`` (the plate a device described), which :func:`ultraglide.devices.rig.load_plate` turns into the
plate wherever it is loaded (the engine's own process too).
"""

from __future__ import annotations

import argparse
import sys

from ultraglide.apps.cli.errors import UsageError

REAL_OUTPUTS = ("audio", "serial")  # outputs that move a real plate: refused without a plate named
PROFILE_DEFAULT_WORDS = "without --rig: sim-plate, for the simulated plate, wav: and null only"


def add_plate_options(container, parser: argparse.ArgumentParser, device_default: str | None = "sim",
                      profile_help: str = "the plate's profile: a bundled name or a TOML file") -> None:
    """``--profile`` and ``--rig`` (one or the other) on ``container`` (a parser or an argument group of
    ``parser``); ``device_default``: the command's device when neither ``--device`` nor the rig names one (None:
    the command chooses, e.g. an experiment's null or sim)."""
    either = container.add_mutually_exclusive_group()
    either.add_argument("--profile", metavar="PROFILE", help=f"{profile_help} ({PROFILE_DEFAULT_WORDS}; "
                                                             "needed for audio and serial outputs)")
    either.add_argument("--rig", metavar="RIG.toml",
                        help="a rig file: the plate, its drive chain and limits, the output device (unless --device), "
                             "the touch panel and display (see examples/rig.toml, `ultraglide rig check`)")
    parser.set_defaults(plate_device_default=device_default)


def choose_plate(args) -> None:
    """Settle ``args.profile`` (a plate spec) and ``args.device`` by the rule in the module docstring; keeps the
    loaded rig as ``args.loaded_rig`` (None without one) for the touch panel and display.

    Raises
    ------
    UsageError
        A real output and no plate named (the caller exits 2).
    RigError
        The rig file is unusable (one line).
    """
    if not hasattr(args, "rig"):
        return
    from ultraglide.devices.rig import RIG_PREFIX, load_rig

    rig = load_rig(args.rig) if args.rig else None
    args.loaded_rig = rig
    if getattr(args, "device", None) is None:
        args.device = rig.device if rig is not None and rig.device else args.plate_device_default
    if rig is not None:
        args.profile = RIG_PREFIX + args.rig
        return
    if args.profile is not None:
        return
    kind = _kind(args.device)
    why = ""
    if kind == "serial":
        from ultraglide.devices.errors import DeviceError

        try:
            described = _described_plate(args.device)
        except DeviceError as error:  # no plate from the device: the rule's refusal, with what happened
            described, why = None, f" (and the plate driver there described none: {error})"
        else:
            why = "" if described is not None else " (its plate driver does not describe its plate in its handshake)"
        if described is not None:
            from ultraglide.devices.serial.handshake import hello_spec

            args.profile = hello_spec(described)
            command = " ".join(filter(None, ("ultraglide", getattr(args, "command", None))))
            print(f"{command}: no --profile or --rig: {plate_words(described, args.profile)}", file=sys.stderr,
                  flush=True)
            return
    if kind in REAL_OUTPUTS:
        raise UsageError(f"--device {args.device} drives a real plate and nothing names it{why}: give --rig RIG.toml "
                         "(see examples/rig.toml) or --profile PROFILE (e.g. from `ultraglide plate sweep`); the "
                         "built-in sim-plate is for sim, wav: and null only")
    from ultraglide.devices.profiles import DEFAULT_PROFILE

    args.profile = DEFAULT_PROFILE


def plate_of(args):
    """The plate a command drives: its profile, from ``--rig`` or ``--profile`` settled by :func:`choose_plate`
    (run here too when the command was not started through ``main``, as tests and scripts do)."""
    from ultraglide.devices.rig import load_plate

    if getattr(args, "profile", None) is None:
        choose_plate(args)
    return load_plate(args.profile)


def display_width_mm(args) -> float | None:
    """The display's width in mm: ``--screen-width-mm``, else the rig's ``[display] width_mm``, else None."""
    given = getattr(args, "screen_width_mm", None)
    rig = getattr(args, "loaded_rig", None)
    return given if given is not None or rig is None else rig.display_width_mm


def plate_words(profile, spec: str) -> str:
    """The plate a command drives and where it came from, in one line, e.g. ``plate: bench-1's plate (rig
    examples/rig.toml): resonance 26400 Hz; a sample of 1.0 is 10 µm p-p; limit 5 µm p-p``."""
    from ultraglide.devices.rig import RIG_PREFIX
    from ultraglide.devices.serial.handshake import HELLO_PREFIX

    source = f"rig {spec[len(RIG_PREFIX):]}" if spec.startswith(RIG_PREFIX) else \
        "as the plate driver describes it in its handshake" if spec.startswith(HELLO_PREFIX) else f"profile {spec}"
    return (f"plate: {profile.shown_name} ({source}): resonance {profile.resonance_hz:g} Hz; a sample of 1.0 is "
            f"{profile.full_scale_um_pp:g} µm p-p; limit {profile.max_amplitude_um_pp:g} µm p-p")


def _described_plate(device: str):
    """The plate a serial device describes in its handshake (a PlateProfile), or None if it does not; DeviceError
    in one line if the port cannot be opened or nobody answers."""
    from ultraglide.devices import protocol as p
    from ultraglide.devices.serial.handshake import plate_of_hello
    from ultraglide.devices.serial.link import probe_hello
    from ultraglide.devices.urls import parse_device_url

    url = parse_device_url(device)
    raw = probe_hello(url.target, url.options.get("baud", 921600))
    try:
        hello = p.parse_hello_reply(raw)
    except p.ProtocolError:
        return None  # the driver's own handshake says what is wrong with it, once a profile is given
    return plate_of_hello(hello)


def _kind(device: str | None) -> str | None:
    """The device URL's kind (None without a device); a malformed URL is the first mistake, said as such."""
    if device is None:
        return None
    from ultraglide.devices.urls import parse_device_url

    return parse_device_url(device).kind
