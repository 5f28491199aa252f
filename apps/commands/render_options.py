"""Options shared by ``export`` and ``play``: the texture, model, profile, effects, and the finger's path."""

from __future__ import annotations

import argparse

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.options import MODEL_HELP
from ultraglide.apps.cli.types import (
    ANGLE_DEG,
    AUDIO_RATE_HZ,
    CARRIER_HZ,
    DURATION_S,
    FORCE_N,
    LENGTH_MM,
    LOOKAHEAD_MS,
    SPEED_MM_S,
    point_mm,
)
from ultraglide.apps.commands.plate_choice import add_plate_options
from ultraglide.render.physics.default_model import DEFAULT_MODEL

# a swipe's options (which a --trajectory does not take) and their defaults, as add_render_options gives them
SWIPE_DEFAULTS = {"path": "straight", "speed_mm_s": 100.0, "direction_deg": 0.0, "start": None, "duration_s": 5.0,
                  "radius_mm": 15.0, "zigzag_width_mm": 40.0}


def add_render_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("texture", metavar="TEXTURE", help="a texture file, an image, or a library name")
    path = parser.add_argument_group("the finger's path (a swipe, unless --trajectory)")
    path.add_argument("--trajectory", metavar="FILE.csv",
                      help="a touch log with columns t_s,x_mm,y_mm[,force_n], at any rate")
    path.add_argument("--path", choices=["straight", "circle", "zigzag"], default="straight")
    path.add_argument("--speed-mm-s", type=SPEED_MM_S, default=100.0, help="finger speed (default: 100)")
    path.add_argument("--direction-deg", type=ANGLE_DEG, default=0.0, help="0 = left to right (default: 0)")
    path.add_argument("--start", type=point_mm, metavar="X,Y", help="start point in mm (default: left of centre)")
    path.add_argument("--duration-s", type=DURATION_S, default=5.0, help="length of the swipe (default: 5)")
    path.add_argument("--radius-mm", type=LENGTH_MM, default=15.0, help="circle radius (default: 15)")
    path.add_argument("--zigzag-width-mm", type=LENGTH_MM, default=40.0, help="zig-zag pass length (default: 40)")
    path.add_argument("--force", type=FORCE_N, metavar="N",
                      help="normal force of the swipe, or of a --trajectory without a force_n column, N "
                           "(default: 0.5, or the log's force_n column)")
    signal = parser.add_argument_group("the signal")
    signal.add_argument("--model", default=DEFAULT_MODEL, metavar="MODEL",
                        help=f"{MODEL_HELP} (default: {DEFAULT_MODEL}, the stretched law with the published "
                             "friction dynamics: force-aware, its force law the paper's detachment law "
                             "W_c ∝ F^(1/3), assumed; floor 0.10)")
    add_plate_options(signal, parser, device_default=None)
    signal.add_argument("--carrier-hz", type=CARRIER_HZ, help="carrier frequency (default: the plate's resonance)")
    signal.add_argument("--rate", type=AUDIO_RATE_HZ, default=96000, help="audio sample rate, Hz (default: 96000)")
    signal.add_argument("--lookahead-ms", type=LOOKAHEAD_MS, default=0.0,
                        help="predict the finger this far ahead, cancelling the panel's latency (default: 0)")
    signal.add_argument("--no-precompensation", action="store_true",
                        help="do not pre-compensate the plate's slow response")
    signal.add_argument("--no-planning", action="store_true",
                        help="with a model that has the finger's friction dynamics (the default), command "
                             "the texture's ratio each instant instead of planning the friction felt")
    effects = signal.add_mutually_exclusive_group()
    effects.add_argument("--effects", metavar="EFFECTS",
                         help="play these temporal effects instead of those saved with the texture: ultraglide's "
                              "JSON description (docs/effects.md), or a designer's .ahap, .haptic, .hjif or .haps "
                              "(docs/formats.md)")
    effects.add_argument("--no-effects", action="store_true",
                         help="leave out the temporal effects saved with the texture")


def model_words(spec: str, model, planned: bool) -> str:
    """The model a command renders with and whether it plans, in one line.

    Parameters
    ----------
    spec : str
        The model as given (``--model``).
    model : FrictionModel
        It, loaded.
    planned : bool
        Whether the renderer plans (:func:`planning_asked`).

    Returns
    -------
    str

    Examples
    --------
    >>> from ultraglide.render.physics.calibration import load_model
    >>> model_words("stretched", load_model("stretched"), False)
    "model: stretched (static): each instant's ratio asked for"
    >>> model_words("dynamic", load_model("dynamic"), True)
    'model: dynamic (with the published friction dynamics): the friction felt is planned'
    """
    dynamics = getattr(model, "dynamics", None)
    if dynamics is None:
        return f"model: {spec} (static): each instant's ratio asked for"
    whose = "the published friction dynamics" if dynamics.published else "its own friction dynamics"
    how = "the friction felt is planned" if planned else "each instant's ratio asked for (--no-planning)"
    return f"model: {spec} (with {whose}): {how}"


def planning_asked(args, model) -> bool:
    """Whether the renderer plans the friction felt: yes unless ``--no-planning``, which a model without friction
    dynamics refuses (there is nothing to plan against)."""
    if not getattr(args, "no_planning", False):
        return True
    if getattr(model, "dynamics", None) is None:
        raise UsageError(f"--no-planning turns off planning against the finger's friction dynamics, and the model "
                         f"{args.model!r} has none: leave it out, or use --model dynamic[:NAME]")
    return False
