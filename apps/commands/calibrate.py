"""``ultraglide calibrate``: fit a model (or every model) to measured points, report each parameter
with its uncertainty and the cross-validated error, and write a calibration file and its figure."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.options import add_figure_width_option, output_option, refuse_ignored
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import PARTICIPANT, Bounded
from ultraglide.apps.commands.finger_options import add_finger_options, finger_asked
from ultraglide.apps.commands.plate_choice import add_plate_options

if TYPE_CHECKING:
    from ultraglide.render.physics.calibration import Fit
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import atomic_path, refuse_overlaps

POOR_FIT_RMS = 0.05
PRESS_N = Bounded(0.05, 10.0, "N")
PASSES = Bounded(1, 10, whole=True)
STEP_MS = Bounded(100.0, 5000.0, "ms")
SENSOR_BANDWIDTH_HZ = Bounded(0.0, 20000.0, "Hz")
SENSOR_DELAY_MS = Bounded(0.0, 100.0, "ms")
SLIDE_SPEED = Bounded(1.0, 2000.0, "mm/s")
BOOTSTRAP_RESAMPLES = Bounded(0, 10_000, whole=True)
BOOTSTRAP_WORDS = {"points": "points resampled", "force": "forces resampled", "participant": "participants resampled"}
CV_NAMES = {"k_fold": "k-fold", "leave_one_force_out": "leave-one-force-out",
            "leave_one_participant_out": "leave-one-participant-out"}


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide calibrate``: its options."""
    calibrate = commands.add_parser(
        "calibrate", help="fit a friction model to measured points, or measure a participant on the plate",
        description="Fit a model's free parameters to a CSV of amplitude_um_pp,relative_friction"
                    "[,force_n][,participant] by least squares; report each parameter with its standard "
                    "error (from JᵀJ and by bootstrap) and the cross-validated error (k-fold within each force; "
                    "leave-one-force-out with three forces or more); write a calibration file usable as --model "
                    "and a figure beside it (CAL.png at 300 dpi and CAL.pdf). Ratios down to -0.05 are taken as "
                    "noise: clipped to 0 and counted. With --device instead of DATA.csv, measure the points on "
                    "the plate: a window guides the participant (slide at a steady press, lighter or heavier as "
                    "asked, the press shown live) while the plate steps its amplitude, the plate's force sensors "
                    "measure the friction, and the fit is written with the participant's id (the points beside it as "
                    "CAL.csv, its figure as CAL.png and CAL.pdf, the sensor samples as CAL-recording.csv); the "
                    "friction's onset and recovery time constants are fitted from the steps' edges and kept in the "
                    "calibration where the data resolve them. --compare CAL-recording.csv ranks static against "
                    "dynamic models by held-out error in time.")
    calibrate.add_argument("data", metavar="DATA.csv", nargs="?",
                           help="measured points, or a calibration's recording with --compare (or --device)")
    calibrate.add_argument("--model", default="stretched",
                           choices=["stretched", "exponential", "squeeze-film", "paper", "paper-uniform", "table"],
                           help="the model to fit (default: stretched)")
    calibrate.add_argument("--compare", action="store_true",
                           help="fit every model and rank them by cross-validated error; -o keeps the best. On a "
                                "calibration's recording (CAL-recording.csv): static models against the same with "
                                "the fitted dynamics, by held-out error of the ratio in time")
    calibrate.add_argument("--participant", type=PARTICIPANT, metavar="ID",
                           help="use only this participant's points (the participant column); with --device, whose "
                                "finger is measured: an id as experiments take it, e.g. P01, written into the "
                                "calibration and its points as text)")
    calibrate.add_argument("--json", action="store_true", help="print one JSON object")
    calibrate.add_argument("--bootstrap", type=BOOTSTRAP_RESAMPLES, default=200, metavar="N",
                           help="bootstrap resamples for the uncertainties (points; forces and participants when "
                                "there are three or more), 0 to skip (default: 200)")
    output_option(calibrate, "-o", "--output", also=(".png", ".pdf"), metavar="CAL.toml",
                           help="write the calibration here, and its figure as CAL.png and CAL.pdf")
    add_figure_width_option(calibrate)
    plate = calibrate.add_argument_group("on the plate (--device)")
    plate.add_argument("--device", metavar="URL",
                       help="measure on this plate driver, which must have normal and lateral force sensors: sim (the "
                            "simulator with a simulated finger) or serial:PORT[?baud=N]")
    add_plate_options(plate, calibrate, device_default=None,
                      profile_help="the plate's profile: its limit bounds the amplitudes stepped to")
    plate.add_argument("--forces", type=_forces, default=(0.25, 0.5, 0.9), metavar="N,N,...",
                       help="the presses asked for, in N (default: 0.25,0.5,0.9)")
    plate.add_argument("--passes", type=PASSES, default=2, metavar="N",
                       help="passes through the amplitudes at each press, alternately up and down (default: 2)")
    plate.add_argument("--step-ms", type=STEP_MS, default=300.0, metavar="MS",
                       help="each amplitude held this long (default: 300)")
    plate.add_argument("--sensor-bandwidth-hz", type=SENSOR_BANDWIDTH_HZ, metavar="HZ",
                       help="the plate's force sensors' bandwidth, for fitting the finger's friction dynamics "
                            "(serial; default: 300, assumed; the simulator's are its finger's)")
    plate.add_argument("--sensor-delay-ms", type=SENSOR_DELAY_MS, metavar="MS",
                       help="the force sensors' delay (serial; default: 1, assumed)")
    plate.add_argument("--slide-speed-mm-s", type=SLIDE_SPEED, metavar="V",
                       help="the participant's sliding speed, which sets the friction's recovery (serial; default: "
                            "unknown: the recovery is reported but not used; the simulator's is its finger's)")
    plate.add_argument("--no-window", action="store_true",
                       help="no window: the steps run on their own (scripts, the simulated finger)")
    plate.add_argument("--windowed", action="store_true", help="a window rather than the full screen")
    add_finger_options(calibrate, "--device sim: the participant; the press follows the plan unless --finger-force")
    calibrate.set_defaults(run=run)


ON_PLATE_DEFAULTS = {"rig": None, "profile": "sim-plate", "forces": (0.25, 0.5, 0.9), "passes": 2, "step_ms": 300.0,
                     "no_window": False, "windowed": False, "sensor_bandwidth_hz": None, "sensor_delay_ms": None,
                     "slide_speed_mm_s": None}  # the options of --device, as add_parser gives them


def _forces(text: str) -> tuple[float, ...]:
    parts = [part for part in text.split(",") if part.strip()]
    if not 1 <= len(parts) <= 10:
        raise argparse.ArgumentTypeError(f"give 1 to 10 forces in N, comma-separated, got {text!r}")
    return tuple(PRESS_N(part) for part in parts)


def _run_on_plate(args) -> int:
    from ultraglide.apps.calibration.session import calibrate_on_plate
    from ultraglide.render.physics.calibration import fit_summary

    if args.compare:
        raise UsageError("--compare ranks models on a CSV: calibrate on the plate, then compare on its CAL.csv (in "
                         "amplitude) or its CAL-recording.csv (in time)")
    result = calibrate_on_plate(args)
    fit = result["fit"]
    dynamics = result["dynamics"]
    written = [str(path) for path in result["written"]]
    if args.json:
        print_json({"fit": fit_summary(fit), "participant": args.participant, "points": result["points"],
                    "missing_steps": result["missing_steps"], "dynamics": dynamics.summary(), "written": written})
        return 0
    print(f"participant {args.participant}: {result['points']} points measured on {args.device}"
          + (f", {result['missing_steps']} steps left out (the finger not sliding)" if result["missing_steps"] else ""))
    for line in _fit_lines(fit):
        print(line)
    for warning in fit.warnings():
        print(f"warning: {warning}")
    print("friction in time:" + (f" {dynamics.dynamics.describe()}" if dynamics.dynamics is not None else ""))
    for line in dynamics.words():
        print(f"  {line}")
    print(f"wrote {', '.join(written)}")
    return 0


def _run_in_time(args) -> int:
    """``calibrate --compare CAL-recording.csv``: static models against the same with the finger's dynamics, ranked
    by held-out error of the ratio in time."""
    import warnings

    from ultraglide.render.physics.dynamics_fit import compare_in_time, read_recording

    if not args.compare:
        raise UsageError(f"{args.data} is a calibration's recording: rank models on it in time with --compare (its "
                         "points, to fit one model, are the CAL.csv beside it)")
    if args.output:
        raise UsageError("-o keeps a calibration; --compare on a recording ranks models in time and writes nothing: "
                         "the calibration written with it holds the fitted dynamics")
    refuse_ignored(args, {"model": "stretched", "participant": None, "bootstrap": 200, "figure_width": "column"},
                   "{option} does not apply to a recording (one participant, every model compared): leave it out")
    recording = read_recording(args.data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # models fitted on part of the steps, used at their presses
        ranking, dynamics, steps = compare_in_time(recording)
    if args.json:
        print_json({"recording": str(args.data), "steps": len(steps), "participant": recording.participant,
                    "ranking": [{"model": r.name, "held_out_rms": r.held_out_rms, "in_sample_rms": r.in_sample_rms,
                                 "samples": r.samples} for r in ranking],
                    "best": ranking[0].name, "dynamics": dynamics.summary()})
        return 0
    print(f"{len(steps)} reduced steps of {args.data}, each with its onset and recovery; models ranked by held-out "
          f"error in time (the ratio's course over steps held out, {len(steps)} steps in folds):")
    for rank, r in enumerate(ranking, 1):
        print(f"  {rank}. {r.name:22} held-out rms {r.held_out_rms:.4f}; in-sample {r.in_sample_rms:.4f} "
              f"(relative friction, {r.samples} samples at {recording.lag.rate_hz:g} samples/s)")
    best = ranking[0].name
    print("the finger's friction lags: the dynamic model predicts its course best" if best.startswith("dynamic:")
           else "an instantaneous finger predicts the course best: no dynamics are told apart on these data")
    print("friction in time, fitted on every step:")
    for line in dynamics.words():
        print(f"  {line}")
    return 0


def _select_participant(data, participant):
    import numpy as np

    if participant is None:
        return data
    if data.participant is None:
        raise UsageError(f"{data.source}: --participant needs a participant column")
    pick = data.participant == participant
    if not pick.any():
        known = ", ".join(str(p) for p in np.unique(data.participant))
        raise UsageError(f"{data.source}: no points of participant {participant}; the file has {known}")
    return data.subset(pick)


def _cv_text(fit: Fit) -> str:
    if not fit.cross_validation:
        return "not available (too few points)"
    return ", ".join(f"{CV_NAMES[k]} {v:.4f}" for k, v in fit.cross_validation.items())


def _fit_lines(fit: Fit) -> list[str]:
    forces = sorted({float(f) for f in (fit.data.force_n if fit.data.force_n is not None else [0.5])})
    lines = [f"fitted {fit.model.describe()}"]
    for p in fit.parameters:
        allowed = f"allowed [{p.spec.low:g}, {p.spec.high:g}]{p.spec.unit}"
        if p.fixed:
            why = ("the data did not support a force law" if p.spec.needs_forces and len(forces) >= 2
                   else "one force cannot fix it" if p.spec.needs_forces and p.spec.fitted else "not fitted")
            lines.append(f"  {p.spec.key} = {p.value:.6g}  held: {why} ({allowed})")
            continue
        boot = "; ".join(f"{values[p.spec.key]:.2g} with {BOOTSTRAP_WORDS[scheme]}"
                         for scheme, values in fit.bootstrap.items() if p.spec.key in values)
        lines.append(f"  {p.spec.key} = {p.value:.6g} ± {p.stderr:.2g} from JᵀJ" + (f", ± {boot}" if boot else "")
                     + f"  (1 standard error; {allowed})")
    lines.append(f"  {len(fit.data)} points at {', '.join(f'{f:g}' for f in forces)} N; rms residual "
                 f"{fit.rms_residual:.4f}, largest {fit.max_abs_residual:.4f} (relative friction)")
    if fit.data.noise_words():
        lines.append(f"  noise: {fit.data.noise_words()}")
    lines.append(f"  force law: {fit.model.force_law()}")
    lines.append(f"  cross-validated rms: {_cv_text(fit)}")
    return lines


def _residual_table(fit: Fit, speed=None) -> list[str]:
    data = fit.data
    at = f" (at {speed.reference_speed_mm_s:g} mm/s under the speed law)" if speed is not None and speed.kept else ""
    lines = [f"  amplitude µm p-p   force N   measured   model    residual{at}"]
    forces = data.force_n if data.force_n is not None else [None] * len(data)
    for a, r, f, e in zip(data.amplitude_um_pp, data.relative_friction, forces, fit.residuals, strict=True):
        force = f"{f:7.3g}" if f is not None else "      -"
        lines.append(f"  {a:16.2f}   {force}   {r:8.4f}   {r - e:7.4f}   {e:+8.4f}")
    return lines


def _write(fit: Fit, fits: list[Fit], output: Path, width: str = "column", speed=None) -> list[Path]:
    from ultraglide.apps.figures.calibration import write_calibration_figure
    from ultraglide.render.physics.calibration import calibration_toml

    with atomic_path(output) as temporary:
        temporary.write_text(calibration_toml(fit, speed_law=speed.law() if speed is not None else None))
    return [output, *write_calibration_figure(fits, output.with_suffix(".png"), width)]


def _speed_law(data, kind: str):
    """The speed law fitted for ``kind`` where the points carry sliding speeds (:func:`fit_speed_law`), else None."""
    if data.speed_mm_s is None or kind == "table":
        return None
    from ultraglide.render.physics.speed_fit import fit_speed_law

    return fit_speed_law(data, kind)


def _at_speed_law(data, speed):
    """The points as the static model sees them: under a kept speed law, at its reference speed; where speeds were
    given but no law is kept (the speed cannot be told), as at one speed."""
    if speed is None:
        return data
    from ultraglide.render.physics.speed_fit import at_exponent

    return at_exponent(data, speed.exponent if speed.kept else 0.0, speed.reference_speed_mm_s)


def run(args) -> int:
    from ultraglide.render.physics.calibration import (
        FORCE_LAW_PARAMETER,
        choose_force_law,
        compare_models,
        fit_model,
        fit_summary,
        rank_fits,
        selection_note,
    )
    from ultraglide.render.physics.measurements import read_measurements

    if (args.data is None) == (args.device is None):
        raise UsageError("give either DATA.csv (measured points) or --device URL (measure them on the plate)")
    if args.device is not None:
        return _run_on_plate(args)

    refuse_ignored(args, ON_PLATE_DEFAULTS, "{option} is for a calibration on the plate: add --device URL, or leave "
                                            "it out")
    if finger_asked(args):
        raise UsageError("the --finger options are a simulated finger on the plate: add --device sim, or leave them "
                         "out")
    if args.compare:
        refuse_ignored(args, {"model": "stretched"}, "{option} names the one model to fit, and --compare fits every "
                                                     "model: give one of them")
    if not args.output:
        refuse_ignored(args, {"figure_width": "column"}, "{option} lays out the calibration's figure, written with -o "
                                                         "CAL.toml: add -o, or leave it out")
    output = Path(args.output) if args.output else None
    if output is not None and output.suffix != ".toml":
        raise UsageError(f"{output}: a calibration file must end in .toml")
    if output is not None:  # the figure goes beside it, as PNG and PDF
        refuse_overlaps({"-o": output, "its figure": output.with_suffix(".png"),
                         "its vector figure": output.with_suffix(".pdf")}, {"the data": args.data})
    from ultraglide.render.physics.dynamics_fit import is_recording

    if is_recording(args.data):
        return _run_in_time(args)
    data = _select_participant(read_measurements(args.data), args.participant)
    if args.compare:
        # points at several speeds: every model is ranked on them as the stretched law's speed exponent reads them
        # (fitting each model's own exponent first would take minutes for the paper's); the chosen one fits its own
        ranked_at = _speed_law(data, "stretched")
        fits = compare_models(_at_speed_law(data, ranked_at))
        if not fits:
            raise UsageError(f"{data.source}: no model can be fitted to these points")
        # a model with a force law competes with the law the data support: refitted force-free where predicting
        # each force from the others does not support it, and ranked again, before the best is chosen
        force_law = None
        lawful = next((f for f in fits if f.kind in FORCE_LAW_PARAMETER), None)
        if lawful is not None:
            force_law = choose_force_law(data, lawful.kind)
            if force_law.hold:
                held = fit_model(_at_speed_law(data, ranked_at), lawful.kind, cross_validate=True,
                                 hold=force_law.hold)
                fits = rank_fits([held if f is lawful else f for f in fits], data)
        chosen = next((f for f in fits if f.kind != "table"), None)
        if chosen is None or force_law is None or chosen.kind != force_law.kind:
            force_law = None  # the file's model has no force law to choose
        speed = (ranked_at if chosen.kind == "stretched" else _speed_law(data, chosen.kind)) \
            if chosen is not None else None
        if chosen is not None and (args.bootstrap or (speed is not None and speed.kept)):
            chosen = fit_model(_at_speed_law(data, speed), chosen.kind, cross_validate=True, bootstrap=args.bootstrap,
                               hold=force_law.hold if force_law is not None else None)
            fits = [chosen if f.kind == chosen.kind else f for f in fits]
        written = _write(chosen, fits, output, args.figure_width, speed) \
            if output is not None and chosen is not None else []
        note = selection_note(data)
        if ranked_at is not None and ranked_at.kept:
            note += f"; ranked at the stretched law's speed exponent {ranked_at.exponent:.2f}"
        result = {"ranking": [fit_summary(f) for f in fits], "selection": note, "written": [str(p) for p in written]}
        if force_law is not None:
            result["force_law"] = {"model": force_law.kind, "forces": force_law.forces, "kept": force_law.keeps_law,
                                   "held_out_rms_with_law": force_law.held_out_with_law,
                                   "held_out_rms_force_free": force_law.held_out_force_free, "note": force_law.note}
        if speed is not None:
            result["speed_law"] = speed.summary()
        if args.json:
            print_json(result)
            return 0
        print(f"{len(data)} points from {data.source}; {note}:")
        for rank, fit in enumerate(fits, 1):
            print(f"  {rank}. {fit.kind:14} {_cv_text(fit)}; in-sample {fit.rms_residual:.4f}")
        if force_law is not None:
            print(f"force law of {force_law.kind}: {force_law.note}")
        if speed is not None:
            print(f"speed law of {speed.kind}: {speed.note}")
        print()
        for line in _fit_lines(chosen if chosen is not None else fits[0]):
            print(line)
        for fit in fits:
            for warning in fit.warnings():
                print(f"warning: {warning}")
        if written:
            if chosen is not fits[0]:
                print(f"the table model ranks first; a table is its CSV (--model table:{data.source}); "
                      f"the calibration file holds the best fitted model, {chosen.kind}")
            print(f"wrote {', '.join(map(str, written))}")
        return 0

    speed = _speed_law(data, args.model)
    fit = fit_model(_at_speed_law(data, speed), args.model, cross_validate=True, bootstrap=args.bootstrap)
    if fit.kind == "table" and output is not None:
        raise UsageError("a table model is its CSV: use --model table:FILE.csv rather than a calibration file")
    written = _write(fit, [fit], output, args.figure_width, speed) if output is not None else []
    if args.json:
        print_json({"fit": fit_summary(fit), "written": [str(p) for p in written]}
                   | ({"speed_law": speed.summary()} if speed is not None else {}))
        return 0
    print(f"{selection_note(data)}")
    if speed is not None:
        print(f"speed law: {speed.note}")
    for line in _fit_lines(fit) + _residual_table(fit, speed):
        print(line)
    for warning in fit.warnings():
        print(f"warning: {warning}; --compare ranks every model on these data")
    cv = fit.cv_rms
    if not fit.warnings() and (fit.rms_residual > POOR_FIT_RMS or (not math.isnan(cv) and cv > POOR_FIT_RMS)):
        print(f"warning: the {fit.kind} model follows these data poorly (rms {fit.rms_residual:.3f}, "
              f"cross-validated {cv:.3f}); --compare ranks every model on them")
    if written:
        print(f"wrote {', '.join(map(str, written))}")
    else:
        print("no file written (give -o CAL.toml to keep the calibration)")
    return 0
