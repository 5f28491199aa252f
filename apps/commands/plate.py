"""``ultraglide plate sweep``: measure a plate's resonance, Q and gain, and write its profile.

The measurement is :mod:`ultraglide.devices.characterisation.sweep`'s; this command checks the options, opens the
device, rests the plate (zero, disable) on every way out, stop signals included, and writes the profile, the
figure and the summary.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.options import OneLineParser, add_figure_width_option, output_option, refuse_ignored
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import CARRIER_HZ, SENSITIVITY, SWEEP_STEPS
from ultraglide.apps.commands.plate_choice import add_plate_options

if TYPE_CHECKING:
    from ultraglide.devices.characterisation.resonance import ResonanceFit
    from ultraglide.devices.profiles import PlateProfile
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import atomic_path, profile_file, refuse_overlaps
from ultraglide.apps.cli.signals import held
from ultraglide.apps.commands.plate_check import add_check_parser
from ultraglide.apps.commands.plate_choice import plate_of


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide plate``: its actions and their options."""
    plate = commands.add_parser("plate", help="characterise a plate (resonance sweep), check its driver",
                                description="Measure a plate before trusting its profile; check that its driver "
                                            "speaks the protocol.")
    actions = plate.add_subparsers(dest="plate_command", metavar="ACTION", required=True, parser_class=OneLineParser)
    sweep_parser = actions.add_parser(
        "sweep", help="find the resonance, Q and gain; write a profile",
        description="Step the carrier across the profile's range (or --from-hz..--to-hz) driving 15 % of the "
                    "plate's limit, read the settled amplitude from telemetry at each step, fit "
                    "A(f) = A0 / sqrt(1 + (2Q(f - f0)/f0)^2), refine around the peak, and write a profile with "
                    "the measured resonance, Q and full scale (the limit is kept, never raised). The plate is "
                    "rested (zero, disable) on every way out.")
    sweep_parser.add_argument("--device", metavar="URL",
                              help="sim or serial:PORT[?baud=N]; audio[:NAME] needs --sensor; audio and serial need "
                                   "--rig or --profile (default: the rig's device, else sim)")
    sweep_parser.add_argument("--sensor", metavar="audio:NAME",
                              help="for an audio output: the input wired to a vibration sensor (one pass over the "
                                   "grid, 0.1 s a carrier, amplitude by a single-bin DFT)")
    sweep_parser.add_argument("--sensor-um-per-unit", type=SENSITIVITY, metavar="K",
                              help="the sensor's sensitivity: µm p-p of vibration per unit of input amplitude (peak, "
                                   "full scale 1); without it an audio sweep keeps the profile's full scale")
    add_plate_options(sweep_parser, sweep_parser, device_default="sim",
                      profile_help="the plate's present profile: its range, limit and gain")
    sweep_parser.add_argument("--from-hz", type=CARRIER_HZ, metavar="A",
                              help="lowest carrier, Hz (default: the profile's)")
    sweep_parser.add_argument("--to-hz", type=CARRIER_HZ, metavar="B",
                              help="highest carrier, Hz (default: the profile's)")
    sweep_parser.add_argument("--steps", type=SWEEP_STEPS, default=41, metavar="N", help="coarse steps (default: 41)")
    output_option(sweep_parser, "-o", "--output", required=True, metavar="PROFILE.toml", help="the measured profile")
    output_option(sweep_parser, "--plot", metavar="FILE.png|pdf|svg", help="also draw the response and the fit")
    add_figure_width_option(sweep_parser)
    sweep_parser.add_argument("--json", action="store_true", help="print one JSON object")
    sweep_parser.set_defaults(run=run_sweep)
    add_check_parser(actions)


def _audio_device(target: str):
    """sounddevice's name for an audio URL's target: an index, a name, or None for the default."""
    return int(target) if target.isdigit() else (target or None)


def run_audio_sweep(args, profile: PlateProfile, low: float, high: float, output: Path) -> int:
    """One pass over a fixed grid (no refinement: the audio path has no telemetry to settle on); the sensor
    gives f0 and Q, and the full scale too when ``--sensor-um-per-unit`` calibrates it."""
    from ultraglide.devices.characterisation.resonance import ResonanceFit
    from ultraglide.devices.characterisation.sweep import (
        SWEEP_LEVEL,
        SweepPoint,
        audio_sweep,
        fit_sweep,
        measured_profile,
        sweep_grid,
    )
    from ultraglide.devices.urls import parse_device_url

    device = parse_device_url(args.device)
    sensor = parse_device_url(args.sensor)
    if sensor.kind != "audio" or not sensor.target:
        raise UsageError(f"--sensor {args.sensor}: give the input as audio:NAME_OR_INDEX")
    rate = int(device.options.get("rate", 96000))
    if rate < high / 0.4:
        raise UsageError(f"{rate} Hz cannot carry {high:g} Hz; use ?rate=96000 or 192000")
    level = SWEEP_LEVEL * profile.max_amplitude_um_pp / profile.full_scale_um_pp
    carriers = sweep_grid(low, high, args.steps)
    amplitudes = audio_sweep(_audio_device(device.target), _audio_device(sensor.target), carriers, level, rate,
                             hold=held)
    fit = fit_sweep([SweepPoint(float(f), float(a), 1.0, True) for f, a in zip(carriers, amplitudes, strict=True)],
               low, high)
    if args.sensor_um_per_unit:
        full_scale = fit.peak_um_pp * args.sensor_um_per_unit / level
        fit = ResonanceFit(fit.resonance_hz, fit.q, full_scale, fit.resonance_sigma_hz, fit.q_sigma,
                           fit.peak_sigma_um_pp * args.sensor_um_per_unit / level, fit.rms_residual_um_pp)
    else:
        fit = ResonanceFit(fit.resonance_hz, fit.q, profile.full_scale_um_pp, fit.resonance_sigma_hz, fit.q_sigma,
                           0.0, fit.rms_residual_um_pp)
    found = measured_profile(profile, fit, output.stem)
    write_profile(output, found, fit)
    summary = {"resonance_hz": round(fit.resonance_hz, 3), "resonance_sigma_hz": float(f"{fit.resonance_sigma_hz:.4g}"),
               "q": round(fit.q, 3), "q_sigma": float(f"{fit.q_sigma:.4g}"), "bandwidth_hz": round(fit.bandwidth_hz, 3),
               "full_scale_um_pp": found.full_scale_um_pp, "full_scale_measured": bool(args.sensor_um_per_unit),
               "max_amplitude_um_pp": found.max_amplitude_um_pp, "max_drive_um_pp": found.max_drive_um_pp,
               "points": len(carriers), "from_hz": low,
               "to_hz": high, "drive_fraction": round(level, 5), "profile": str(output)}
    if args.json:
        print_json(summary)
    else:
        print(f"resonance {fit.resonance_hz:.1f} ± {fit.resonance_sigma_hz:.1f} Hz, Q {fit.q:.1f} ± {fit.q_sigma:.1f} "
              f"from the sensor, {len(carriers)} carriers at {level:.1%} of full-scale drive")
        if not args.sensor_um_per_unit:
            print("full scale kept from the profile: give --sensor-um-per-unit to measure it")
        print(overdrive_words(profile, found))
        print(f"profile written to {output}")
    return 0


def overdrive_words(old: PlateProfile, found: PlateProfile) -> str:
    """What became of the profile's overdrive headroom for pre-compensation (``max_drive_um_pp``)."""
    if old.max_drive_um_pp <= old.max_amplitude_um_pp:
        return "no overdrive in the profile: the drive stays within the limit"
    if found.max_drive_um_pp < old.max_drive_um_pp:
        return (f"overdrive lowered from {old.max_drive_um_pp:g} to {found.max_drive_um_pp:g} µm p-p: the plate's full "
                "scale")
    return f"overdrive kept: the drive may reach {found.max_drive_um_pp:g} µm p-p to pre-compensate"


def write_profile(path: Path, profile: PlateProfile, fit: ResonanceFit) -> None:
    """The sweep's profile, with the fit and its uncertainties in a comment."""
    save_profile(path, profile, "measured by `ultraglide plate sweep`",
                 f"resonance {fit.resonance_hz:.2f} ± {fit.resonance_sigma_hz:.2f} Hz, "
                 f"Q {fit.q:.2f} ± {fit.q_sigma:.2f}, "
                 f"full scale {fit.peak_um_pp:.4f} ± {fit.peak_sigma_um_pp:.4f} µm p-p (one sigma)")


def save_profile(path: Path, profile: PlateProfile, made_by: str, *notes: str) -> None:
    """A profile as TOML that ``--profile`` loads, written atomically, with comment lines saying where it came
    from."""
    import tomli_w
    from ultraglide.devices.profiles import PlateProfile

    document = {key: getattr(profile, key) for key in PlateProfile.__dataclass_fields__}
    header = "".join(f"# {line}\n" for line in (f"Plate profile {made_by} (load with --profile {path.name}).", *notes))
    with atomic_path(path) as temporary:
        temporary.write_text(header + tomli_w.dumps(document), encoding="utf-8")


def check_profile_path(path: Path, option: str) -> Path:
    """Refuse, before anything runs, a profile path that cannot be written as asked."""
    if path.suffix.lower() != ".toml":
        raise UsageError(f"{option} {path}: the profile is written as TOML; name it PROFILE.toml")
    if not path.resolve().parent.is_dir():
        raise UsageError(f"{option} {path}: its folder does not exist")
    return path


def run_sweep(args) -> int:
    from ultraglide.devices.characterisation.sweep import (
        MAX_FRAMES_PER_STEP,
        SWEEP_LEVEL,
        TelemetrySweeper,
        measured_profile,
        sweep,
    )
    from ultraglide.devices.errors import DeviceError, describe
    from ultraglide.devices.urls import open_device, parse_device_url
    from ultraglide.render.engine.realtime import threads_started_in_real_time

    profile = plate_of(args)
    low = args.from_hz if args.from_hz is not None else profile.carrier_min_hz
    high = args.to_hz if args.to_hz is not None else profile.carrier_max_hz
    if not low < high:
        raise UsageError(f"--from-hz {low:g} must be below --to-hz {high:g}")
    profile.check_carrier(low)
    profile.check_carrier(high)
    if args.steps < 5:
        raise UsageError("--steps must be at least 5")
    output = check_profile_path(Path(args.output), "-o")
    refuse_overlaps({"-o": output, "--plot": args.plot}, {"--profile": profile_file(args.profile)})
    if args.plot and Path(args.plot).suffix.lower() not in (".png", ".pdf", ".svg"):
        raise UsageError(f"{args.plot}: the plot is drawn as PNG, PDF or SVG; name it so")
    for path in filter(None, (output, args.plot and Path(args.plot))):
        if not path.resolve().parent.is_dir():
            raise UsageError(f"{path}: its folder does not exist")
    kind = parse_device_url(args.device).kind
    if kind != "audio":
        refuse_ignored(args, {"sensor": None, "sensor_um_per_unit": None},
                       "{option} is for sweeping an audio output (--device audio:NAME), which reports no amplitude: "
                       "leave it out")
    elif not args.sensor:
        refuse_ignored(args, {"sensor_um_per_unit": None}, "{option} is the sensitivity of --sensor: add --sensor "
                                                            "audio:NAME")
    if not args.plot:
        refuse_ignored(args, {"figure_width": "column"}, "{option} lays out --plot's figure: add --plot, or leave "
                                                         "it out")
    if kind == "audio":
        if not args.sensor:
            raise UsageError("an audio output reports no amplitude: sweeping it needs a vibration sensor on an audio "
                             "input, given as --sensor audio:NAME")
        return run_audio_sweep(args, profile, low, high, output)  # a stop signal ends the stream, writes nothing
    if kind not in ("sim", "serial"):
        raise UsageError(f"{kind} measures nothing: sweep a plate driver (sim or serial:PORT), or audio with --sensor")
    say = (lambda message: None) if args.json else print

    with threads_started_in_real_time():  # the plate's threads (a simulated plate's), as the stream's below
        device = open_device(args.device, profile, carrier_hz=low)
    sweeper = TelemetrySweeper(device, profile)
    try:  # a stop signal (Ctrl-C, SIGTERM, SIGHUP: apps/cli/signals.py) leaves through the finally
        with threads_started_in_real_time() as priority:  # the stream's writer and reader; this thread stays
            sweeper.start(low)  # ordinary
        for note in getattr(sweeper.driver, "notes", []):  # where the device's own limits bind
            say(note)
        say(f"sweeping {low:g}-{high:g} Hz in {args.steps} steps at {sweeper.level_um_pp:.2f} µm p-p "
            f"({SWEEP_LEVEL:.0%} of the {sweeper.limit_um_pp:g} µm p-p limit); the stream's threads at {priority}")
        points, fit = sweep(sweeper, low, high, args.steps, say)
    except DeviceError as error:  # the plate went away or cut its output mid-sweep: what happened, and when
        with held():
            sweeper.stop()
        report = sweeper.driver.report()
        for line in report.lines:
            say(line)
        print(f"ultraglide plate: error: {describe(error)}", file=sys.stderr)
        return report.exit_status or 1
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            sweeper.stop()  # ramp to rest, zero, disable (once: a second call finds it stopped)
    report = sweeper.driver.report()
    found = measured_profile(profile, fit, output.stem)
    level_fraction = points[0].drive_fraction
    if args.plot:
        from ultraglide.apps.figures.sweep import plot_sweep

        plot_sweep(Path(args.plot), points, fit, level_fraction, args.figure_width)
    write_profile(output, found, fit)
    faults = {name: count for name, count in sweeper.fault_counts().items() if count}
    summary = {
        "resonance_hz": round(fit.resonance_hz, 3), "resonance_sigma_hz": float(f"{fit.resonance_sigma_hz:.4g}"),
        "q": round(fit.q, 3), "q_sigma": float(f"{fit.q_sigma:.4g}"), "bandwidth_hz": round(fit.bandwidth_hz, 3),
        "full_scale_um_pp": round(fit.peak_um_pp, 5), "full_scale_sigma_um_pp": float(f"{fit.peak_sigma_um_pp:.4g}"),
        "max_amplitude_um_pp": found.max_amplitude_um_pp, "max_drive_um_pp": found.max_drive_um_pp,
        "rms_residual_um_pp": round(fit.rms_residual_um_pp, 5),
        "points": len(points), "unsettled_points": sweeper.unsettled, "from_hz": low, "to_hz": high,
        "drive_um_pp": round(level_fraction * profile.full_scale_um_pp, 4), "profile": str(output),
        "plot": args.plot, "faults": faults, "notes": list(getattr(sweeper.driver, "notes", [])),
        "stream_threads": priority,
        "report": report.as_dict(),
    }
    if args.json:
        print_json(summary)
        return report.exit_status
    print(f"resonance {fit.resonance_hz:.1f} ± {fit.resonance_sigma_hz:.1f} Hz, Q {fit.q:.1f} ± {fit.q_sigma:.1f} "
          f"(half-power width {fit.bandwidth_hz:.1f} Hz), {fit.peak_um_pp:.3f} ± {fit.peak_sigma_um_pp:.3f} µm p-p "
          f"at full-scale drive; {len(points)} points")
    if found.max_amplitude_um_pp < profile.max_amplitude_um_pp:
        print(f"limit lowered from {profile.max_amplitude_um_pp:g} to {found.max_amplitude_um_pp:g} µm p-p: the plate "
              "cannot reach more at full-scale drive")
    else:
        print(f"limit kept at {found.max_amplitude_um_pp:g} µm p-p (a sweep never raises it)")
    print(overdrive_words(profile, found))
    if sweeper.unsettled:
        print(f"warning: {sweeper.unsettled} points did not settle within {MAX_FRAMES_PER_STEP} telemetry frames")
    if faults:
        print("device faults during the sweep: " + ", ".join(f"{count} {name}" for name, count in faults.items()))
    print(f"profile written to {output}" + (f"; response drawn in {args.plot}" if args.plot else ""))
    for line in report.lines:
        print(line)
    if report.exit_status:  # the plate faulted or was lost during the sweep: the profile may be off
        print(f"ultraglide plate: {report.verdict}", file=sys.stderr)
    return report.exit_status
