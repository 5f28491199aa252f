"""``ultraglide experiment threshold|constant``: run, dry-run or resume a psychophysics session."""

from __future__ import annotations

import argparse
import warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.errors import UsageError, require
from ultraglide.apps.cli.options import MODEL_HELP, OneLineParser, output_option, refuse_ignored
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import (
    BOOTSTRAP_SAMPLES,
    FORCE_N,
    LEVEL,
    PARTICIPANT,
    REPEATS,
    SCREEN_WIDTH_MM,
    SEED,
    SPEED_MM_S,
    TRIALS_BETWEEN_BREAKS,
    ZONES,
    label,
)
from ultraglide.apps.cli.types import TRIALS as TRIALS_OPTION
from ultraglide.apps.commands.plate_choice import add_plate_options
from ultraglide.apps.experiment.log import RESULT, SESSION
from ultraglide.apps.figures import SESSION_FIGURES, both_formats
from ultraglide.render.physics.default_model import EXPERIMENT_MODEL

from ultraglide.errors import UltraglideError

if TYPE_CHECKING:
    from ultraglide.apps.experiment.session import SessionConfig

    from ultraglide.experiment.stimuli import StimulusDesign

PRESETS = {
    # Vezzoli et al. (2015), section III.D: 0, 2 and 4 µm at the actuator's resonance, in random order,
    # "more slippery?"; 0.4 N is the force at which the paper's model puts the glide threshold at 4 µm (the
    # participants' force was not measured). The paper gives no number of presentations: 10 each is our choice.
    "vezzoli2015": {"parameter": "amplitude", "levels": (0.0, 2.0, 4.0), "repeats": 10, "intervals": 1,
                    "force_n": 0.4, "question": "More slippery than the plate at rest? (yes / no)",
                    "zone_mm": (60.0, 40.0)},
}


# what a session writes whole into its folder (trials.csv grows as it goes; it is refused when it is not a file)
SESSION_FILES = (SESSION, RESULT, *both_formats(SESSION_FIGURES))

THRESHOLD_PRESETS = {
    # the common questions: TEXTURE, --vary, --range and --afc come from the preset unless given
    "grating-contrast": {"texture": "grating-1mm", "parameter": "contrast", "level_range": (0.005, 0.6),
                         "intervals": 3},
    "grating-period": {"texture": "grating-1mm", "parameter": "wavelength", "level_range": (0.01, 1.0),
                       "intervals": 3},
}


def _add_shared_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--vary", choices=["contrast", "wavelength", "amplitude"],
                        help="the parameter the procedure varies: the friction contrast of TEXTURE (default), "
                             "the wavelength of a grating (discrimination, mm), or a uniform vibration "
                             "amplitude (µm p-p)")
    parser.add_argument("--observer", metavar="sim:threshold=T,slope=S,lapse=L",
                        help="a simulated observer (dry run, offline through the renderer; default: a person "
                             "at the window)")
    output_option(parser, "--device", kind="device", metavar="URL",
                        help="output device: sim, serial:PORT, audio[...], wav:PATH or null "
                             "(default: sim; null with a simulated observer)")
    parser.add_argument("--seed", type=SEED, default=0, help="seed of every random choice (default: 0)")
    output_option(parser, "--out", kind="folder", also=SESSION_FILES, metavar="DIR",
                  help="where trials.csv, session.json, result.json and the figures go (a new directory)")
    output_option(parser, "--resume", kind="folder", also=SESSION_FILES, metavar="DIR",
                  help="continue the session in DIR (its options are kept)")
    parser.add_argument("--break-every", type=TRIALS_BETWEEN_BREAKS, default=0, metavar="N",
                        help="a pause screen every N trials (default: none)")
    parser.add_argument("--participant", type=PARTICIPANT, default="P01",
                        help="participant code for the log: letters, digits, '-', '_' or '.' (default: P01)")
    parser.add_argument("--session", type=label, default="1", help="session label for the log (default: 1)")
    parser.add_argument("--function", choices=["weibull", "logistic"], default="weibull",
                        help="psychometric function fitted (default: weibull)")
    parser.add_argument("--interval", choices=["posterior", "bootstrap"], default="posterior",
                        help="the threshold's 95 %% interval for staircases and constant stimuli: the grid "
                             "posterior's credible interval, or a parametric bootstrap of the ML fit "
                             "(default: posterior; QUEST+ always gives its posterior)")
    parser.add_argument("--bootstrap", type=BOOTSTRAP_SAMPLES, default=200, metavar="N",
                        help="bootstrap samples with --interval bootstrap (default: 200)")
    parser.add_argument("--model", default=EXPERIMENT_MODEL, metavar="MODEL",
                        help=f"{MODEL_HELP} (default: {EXPERIMENT_MODEL}, a static law; under a dynamic model the "
                             "stimulus check judges the friction felt)")
    add_plate_options(parser, parser, device_default=None)
    parser.add_argument("--force", type=FORCE_N, metavar="N", help="the finger's normal force, N (default: 0.5)")
    parser.add_argument("--speed-mm-s", type=SPEED_MM_S, default=100.0,
                        help="swipe speed of the simulated observer's finger (default: 100)")
    parser.add_argument("--screen-width-mm", type=SCREEN_WIDTH_MM, help="the display's width in mm (window)")
    parser.add_argument("--windowed", action="store_true", help="a window instead of full screen")
    parser.add_argument("--closed-loop", action="store_true",
                        help="make the friction the plate's force sensors measure follow each stimulus (a plate "
                             "driver with force sensors; on sim, a simulated finger); the log records the target and "
                             "measured friction and the amplitude of each trial")
    parser.add_argument("--no-figures", action="store_true",
                        help="leave out the track and psychometric figures (a batch of simulated sessions: "
                             "trials.csv and result.json hold what they show)")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    parser.add_argument("--accept-check", action="store_true",
                        help="run even if the stimulus check fails (the failures are recorded in session.json)")
    parser.add_argument("--print-design", action="store_true",
                        help="print the equivalent DESIGN.toml (for ultraglide experiment check|run) and stop")


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide experiment``: its kinds and their options."""
    experiment = commands.add_parser(
        "experiment", help="psychophysics: designs from TOML, staircases, QUEST+, constant stimuli, ratings",
        description="Psychophysics on the plate: experiment designs (check and run a DESIGN.toml), adaptive "
                    "thresholds and the method of constant stimuli, with a person at the touch panel or a simulated "
                    "observer (dry run).")
    kinds = experiment.add_subparsers(dest="experiment", metavar="KIND", required=True, parser_class=OneLineParser)
    threshold = kinds.add_parser(
        "threshold", help="an adaptive threshold: staircase or QUEST+, 2 or 3 zones (forced choice)",
        description="Find the level of one parameter a finger detects: zones side by side, one holds the "
                    "stimulus; the participant swipes each and taps the odd one.")
    threshold.add_argument("texture", nargs="?", metavar="TEXTURE", help="a texture file or a library name")
    threshold.add_argument("--method", choices=["staircase", "quest"], default="staircase")
    threshold.add_argument("--afc", type=ZONES, help="zones (forced-choice intervals) (default: 2)")
    threshold.add_argument("--rule", choices=["1u2d", "1u3d", "weighted"], default="1u2d",
                           help="staircase rule (default: 1u2d; weighted targets 75 %% correct)")
    threshold.add_argument("--trials", type=TRIALS_OPTION, metavar="N", help="number of trials")
    threshold.add_argument("--range", nargs=2, type=LEVEL, metavar=("LOW", "HIGH"),
                           help="levels the procedure may use (default: by parameter)")
    threshold.add_argument("--start-level", type=LEVEL, metavar="LEVEL", help="staircase start level")
    threshold.add_argument("--reference", metavar="TEXTURE",
                           help="what the other zones show (default: plain glass)")
    threshold.add_argument("--preset", choices=["grating-contrast", "grating-period"],
                           help="a common question: grating-contrast, the detection threshold of a 1 mm grating's "
                                "friction contrast; grating-period, the discrimination threshold of its period "
                                "(Δλ in mm against 1 mm); both 3 zones")
    _add_shared_options(threshold)
    threshold.set_defaults(run=run)
    constant = kinds.add_parser(
        "constant", help="the method of constant stimuli (preset: the paper's own assessment)",
        description="Fixed levels, each presented a set number of times in random order, a yes/no answer; "
                    "a psychometric function fitted by maximum likelihood. --preset vezzoli2015: 0, 2 and "
                    "4 µm p-p at the plate's resonance, 10 times each, \"more slippery?\".")
    constant.add_argument("texture", nargs="?", metavar="TEXTURE", help="a texture (not needed by the preset)")
    constant.add_argument("--preset", choices=["vezzoli2015"])
    constant.add_argument("--levels", nargs="+", type=LEVEL, metavar="L", help="the fixed levels")
    constant.add_argument("--repeats", type=REPEATS, metavar="N", help="presentations of each level")
    constant.add_argument("--afc", type=ZONES, help="forced choice instead of yes/no")
    _add_shared_options(constant)
    constant.set_defaults(run=run)
    from ultraglide.apps.commands.experiment_design import add_parsers

    add_parsers(kinds)


# what a session keeps in its session.json (--resume takes them from there), as the parsers give them
SESSION_DEFAULTS = {"method": "staircase", "afc": None, "rule": "1u2d", "range": None, "start_level": None,
                    "reference": None, "preset": None, "levels": None, "repeats": None, "vary": None, "device": None,
                    "seed": 0, "break_every": 0, "participant": "P01", "session": "1",
                    "function": "weibull", "interval": "posterior", "bootstrap": 200, "model": EXPERIMENT_MODEL,
                    "profile": "sim-plate", "force": None, "speed_mm_s": 100.0, "closed_loop": False,
                    "accept_check": False}


def _refuse_ignored_options(args) -> None:
    """Options this combination would take and ignore, refused in one line."""
    if args.resume:
        if args.texture:
            raise UsageError(f"--resume continues the session in {args.resume} on its own texture: leave out "
                             f"{args.texture}")
        if args.out:
            raise UsageError(f"--resume continues the session in {args.resume}, where its files stay: leave out "
                             "--out")
        refuse_ignored(args, SESSION_DEFAULTS, f"{{option}} is kept in the session --resume {args.resume} "
                                               "continues (its session.json): leave it out")
        return
    if getattr(args, "method", None) == "quest":
        refuse_ignored(args, {"rule": "1u2d", "start_level": None, "interval": "posterior", "bootstrap": 200},
                       "{option} is for a staircase; QUEST+ chooses its own levels and gives its posterior's interval: "
                       "leave it out, or use --method staircase")
    if not args.observer:
        refuse_ignored(args, {"speed_mm_s": 100.0}, "{option} is the simulated observer's swipe speed (a person "
                                                    "swipes at their own): add --observer, or leave it out")
    if args.interval != "bootstrap":
        refuse_ignored(args, {"bootstrap": 200}, "{option} is the samples of --interval bootstrap: add --interval "
                                                 "bootstrap, or leave it out")
    if args.observer:
        refuse_ignored(args, {"screen_width_mm": None, "windowed": False},
                       "{option} is for the participant's window, and a simulated observer has none: leave it out")


def _check_counts(args) -> None:
    if args.break_every < 0:
        raise UsageError(f"--break-every must be 0 (no breaks) or more, got {args.break_every}")
    if args.bootstrap < 20:
        raise UsageError(f"--bootstrap needs at least 20 samples for a 95 % interval, got {args.bootstrap}")
    if getattr(args, "repeats", None) is not None and args.repeats < 1:
        raise UsageError(f"--repeats must be at least 1, got {args.repeats}")


def _config_from_args(args, kind: str) -> SessionConfig:
    from ultraglide.apps.experiment.session import SessionConfig

    _check_counts(args)
    common = {"seed": args.seed, "model": args.model, "profile": args.profile, "observer": args.observer,
              "participant": args.participant, "session": args.session, "break_every": args.break_every,
              "speed_mm_s": args.speed_mm_s, "function": args.function, "bootstrap": args.bootstrap,
              "interval": args.interval, "closed_loop": args.closed_loop}
    if args.observer and args.closed_loop:
        raise UsageError("a simulated observer renders offline, with no plate to measure: leave out --closed-loop")
    if args.observer:
        common["device"] = args.device or "null"
        if common["device"] != "null":
            raise UsageError("a simulated observer renders offline: use --device null (or leave --device out)")
    else:
        common["device"] = args.device or "sim"
    if args.force is not None:
        common["force_n"] = args.force
    if kind == "constant":
        preset = dict(PRESETS[args.preset]) if args.preset else {}
        if not preset and (not args.texture or not args.levels):
            raise UsageError("constant needs --preset vezzoli2015, or TEXTURE with --levels L1 L2 ...")
        if args.levels:
            preset["levels"] = tuple(args.levels)
        if args.repeats:
            preset["repeats"] = args.repeats
        if args.vary:
            preset["parameter"] = args.vary
        if args.afc:
            preset["intervals"] = args.afc
        if args.force is not None:
            preset["force_n"] = args.force
        texture = args.texture or "grating-1mm"
        config = SessionConfig(texture=texture, method="constant", preset=args.preset, **{**common, **preset})
        if any(level < 0 for level in config.levels):
            raise UsageError("--levels must not be negative")
        return config
    preset = THRESHOLD_PRESETS.get(args.preset, {}) if args.preset else {}
    if preset:
        args.texture = args.texture or preset["texture"]
        args.vary = args.vary or preset["parameter"]
        args.range = args.range or list(preset["level_range"])
        args.afc = args.afc or preset["intervals"]
    if not args.texture:
        raise UsageError("threshold needs a TEXTURE (a library name or a texture file), a --preset, or --resume DIR")
    if args.trials is None or args.trials < 1:
        raise UsageError("--trials N is needed, N ≥ 1")
    level_range = tuple(args.range) if args.range else None
    if level_range and not 0 < level_range[0] < level_range[1]:
        raise UsageError(f"--range needs 0 < LOW < HIGH, got {level_range[0]:g} {level_range[1]:g}")
    if (args.vary or "contrast") == "contrast" and level_range and level_range[1] > 1:
        raise UsageError("a friction contrast is at most 1: --range HIGH must be ≤ 1")
    question = "Which zone felt different? (tap it, or press its number)"
    return SessionConfig(texture=args.texture, method=args.method, parameter=args.vary or "contrast",
                         intervals=args.afc or 2, rule=args.rule, trials=args.trials, level_range=level_range,
                         start_level=args.start_level, reference=args.reference, question=question,
                         preset=args.preset, **common)


def design_for(config: SessionConfig) -> StimulusDesign:
    """Load what the config names (texture, reference, model, profile): one-line errors for mistakes."""
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.textures.library import resolve_texture

    from ultraglide.experiment.stimuli import Layout, StimulusDesign

    with warnings.catch_warnings():
        warnings.simplefilter("default")
        texture = resolve_texture(config.texture)
        reference = resolve_texture(config.reference) if config.reference else None
    model = load_model(config.model)
    layout = Layout(config.intervals, tuple(config.zone_mm), config.gap_mm)
    design = StimulusDesign(texture, config.parameter, layout, reference, model, config.force_n)
    low, high = config.range
    if config.parameter == "wavelength" and config.method != "constant" and design.base_wavelength_mm + low <= 0:
        raise UsageError("the wavelength range must keep the target's wavelength positive")
    return design


def _prepare_directory(args) -> Path:
    from ultraglide.apps.experiment.log import TRIALS as TRIALS_FILE

    if not args.out:
        raise UsageError("--out DIR is needed (where the log, results and figures go)")
    directory = Path(args.out)
    if (directory / TRIALS_FILE).exists():
        raise UsageError(f"{directory} already holds a session; continue it with --resume {directory} "
                         "or choose another --out")
    if directory.exists() and not directory.is_dir():
        raise UsageError(f"--out {directory} is a file, not a directory")
    return directory


def _responder(config: SessionConfig, design: StimulusDesign, args):
    from ultraglide.devices.rig import load_plate

    if config.observer:
        from ultraglide.experiment.dryrun import SimResponder
        from ultraglide.experiment.observer import SimObserver

        observer = SimObserver.parse(config.observer, config.seed)
        return SimResponder(observer, design.model, load_plate(config.profile), config.speed_mm_s, config.force_n)
    from ultraglide.apps.commands.plate_choice import display_width_mm
    from ultraglide.apps.experiment.window import WindowResponder

    return WindowResponder(config, design, screen_width_mm=display_width_mm(args),
                           windowed=getattr(args, "windowed", False))


def run(args) -> int:
    if not args.no_figures:
        require("matplotlib")  # the figures are drawn at the end: said now, not after the trials
    from ultraglide.apps.experiment.log import read_session
    from ultraglide.apps.experiment.session import check_levels, resumed_config, run_session

    kind = args.experiment
    _refuse_ignored_options(args)
    if args.resume:
        directory = Path(args.resume)
        saved = read_session(directory)
        config = resumed_config(saved, getattr(args, "trials", None), str(directory / "session.json"))
        if args.observer:
            config = replace(config, observer=args.observer)
        resume = True
    else:
        config = _config_from_args(args, kind)
        if args.print_design:
            return _print_design(config)
        directory = _prepare_directory(args)
        resume = False
    if args.print_design:
        return _print_design(config)
    check_levels(config, str(directory / "session.json") if resume else "--start-level and --range")
    if config.observer:
        from ultraglide.experiment.observer import SimObserver

        SimObserver.parse(config.observer, config.seed)  # a bad spec fails before any file is written
    design = design_for(config)
    from ultraglide.devices.rig import load_plate

    load_plate(config.profile)
    recorded = {} if resume else _stimulus_check(config, args.accept_check)
    if recorded is None:
        return 2
    responder = _responder(config, design, args)
    directory.mkdir(parents=True, exist_ok=True)
    try:
        outcome = run_session(config, design, responder, directory, resume, figures=not args.no_figures,
                              recorded=recorded)
    finally:
        close = getattr(responder, "close", None)
        if close:
            close()
    result = outcome.result
    if args.json:
        print_json({**result, "directory": str(directory), "figures": [str(p) for p in outcome.figures]})
    else:
        print(summary(config, result, directory, outcome))
    return 0


def _stimulus_check(config: SessionConfig, accept: bool) -> dict | None:
    """The stimulus check of the session's design (ultraglide.experiment.check), before a window opens or a file is
    written: None (after one line on stderr) if it fails and is not accepted, else what session.json records."""
    import sys

    from ultraglide.apps.cli.output import one_line
    from ultraglide.apps.commands.experiment_design import design_from_config

    from ultraglide.experiment import check_stimuli
    from ultraglide.experiment.check import refuse

    report = check_stimuli(design_from_config(config))
    warnings_ = [f"stimulus check accepted despite: {failure}" for failure in report.failures]
    if not accept:
        try:
            refuse(report)
        except UltraglideError as error:
            print(f"ultraglide experiment: error: {one_line(str(error))}", file=sys.stderr)
            return None
    for warning in warnings_:
        print(f"ultraglide experiment: warning: {one_line(warning)}", file=sys.stderr)
    return {"stimulus_check": report.as_dict(), "warnings": warnings_}


def _print_design(config: SessionConfig) -> int:
    """The DESIGN.toml ``experiment run`` runs to the same trial plan (given the seed), on standard output."""
    from ultraglide.apps.commands.experiment_design import design_from_config

    from ultraglide.experiment import ExperimentError, to_toml

    design_for(config)  # what the config names loads (one line if not)
    try:
        print(to_toml(design_from_config(config)), end="")
    except ExperimentError as error:
        raise UsageError(f"--print-design: {error}") from None
    return 0


def summary(config: SessionConfig, result: dict, directory: Path, outcome) -> str:
    state = "complete" if outcome.complete else f"stopped after {len(outcome.rows)} trials (resume with --resume)"
    lines = [f"{config.condition}: {len(outcome.rows)} trials, {state}"]
    if result.get("threshold") is not None:
        low, high = result["ci"]
        lines.append(f"threshold {result['threshold']:.4g} {result['unit']} (95 % CI {low:.4g} to {high:.4g}; "
                     f"{result['ci_kind']})")
    else:
        lines.append(f"no threshold: {result.get('note', 'not enough trials')}")
    for item in result.get("proportions", []):
        lines.append(f"  level {item['level']:g} {result['unit']}: {item['positive']}/{item['n']} "
                     f"{'yes' if config.intervals == 1 else 'correct'} ({100 * item['p']:.0f} %)")
    if result.get("rt_s_median") is not None:
        lines.append(f"median reaction time {result['rt_s_median']:.2f} s (of {result['rt_s_count']} trials)")
    else:
        lines.append("no reaction times logged")
    lines.append(f"files in {directory}: " + ", ".join(["trials.csv", "session.json", "result.json",
                                                         *(p.name for p in outcome.figures)]))
    return "\n".join(lines)
