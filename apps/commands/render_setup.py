"""Build a renderer from the options of ``export`` and ``play``."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.options import refuse_ignored
from ultraglide.apps.commands.plate_choice import plate_of
from ultraglide.apps.commands.render_options import planning_asked
from ultraglide.devices.profiles import PlateProfile
from ultraglide.render.paths import SwipePath
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.touch_log import read_touch_log
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.texture import Texture


def refuse_ignored_path_options(args) -> None:
    """A swipe's options with ``--trajectory`` (which replays its log), or one shape's option with another path:
    refused in one line, not silently ignored."""
    from ultraglide.apps.commands.render_options import SWIPE_DEFAULTS

    if args.trajectory:
        refuse_ignored(args, SWIPE_DEFAULTS, "{option} shapes a swipe, and --trajectory replays its log instead: "
                                             "leave one of them out")
        return
    if args.path != "circle":
        refuse_ignored(args, {"radius_mm": SWIPE_DEFAULTS["radius_mm"]},
                       "{option} is the radius of --path circle: add --path circle or leave it out")
    if args.path != "zigzag":
        refuse_ignored(args, {"zigzag_width_mm": SWIPE_DEFAULTS["zigzag_width_mm"]},
                       "{option} is the pass length of --path zigzag: add --path zigzag or leave it out")


def swipe_of(args, texture: Texture) -> SwipePath:
    """The swipe the options describe (:meth:`SwipePath.across`: by default left of centre, across the middle)."""
    return SwipePath.across(texture.width_mm, texture.height_mm, args.path, args.speed_mm_s, args.duration_s,
                            args.start, args.direction_deg, args.radius_mm, args.zigzag_width_mm, args.force)


@dataclass(frozen=True)
class Inputs:
    """Everything the options name, loaded and checked: where a person's mistakes show up."""

    texture: Texture
    model: FrictionModel
    profile: PlateProfile
    trajectory: RecordedTrajectory | SwipePath


def load_inputs(args) -> Inputs:
    """Texture, model, profile and path from parsed options; one-line errors for bad ones."""
    refuse_ignored_path_options(args)
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        texture = resolve_texture(args.texture)
    model = load_model(args.model)
    profile = plate_of(args)
    if getattr(args, "carrier_hz", None) is not None:
        profile.check_carrier(args.carrier_hz)  # the plate's range, before any device or engine: CarrierError, exit 2
    if args.trajectory:
        trajectory = read_touch_log(args.trajectory)
        if args.force is not None and trajectory.has_force:
            raise UsageError(f"{args.trajectory} logs its own force_n; --force is for a swipe or a log without one")
    else:
        trajectory = swipe_of(args, texture)
    return Inputs(texture, model, profile, trajectory)


def make_renderer(inputs: Inputs, args, rate_hz: int, live: bool = False) -> Renderer:
    """A renderer at ``rate_hz``; ``live`` leaves the path to be fed in real time, as touches."""
    settings = RenderSettings(
        audio_rate_hz=rate_hz, control_rate_hz=12000.0, carrier_hz=args.carrier_hz,
        precompensate=not args.no_precompensation, lookahead_s=args.lookahead_ms / 1000.0,
        plan=planning_asked(args, inputs.model),
        default_force_n=0.5 if args.force is None else args.force,  # touches without a force: a log without one
    )
    return Renderer(inputs.texture, inputs.model, inputs.profile, settings,
                    trajectory=None if live else inputs.trajectory)
