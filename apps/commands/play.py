"""``ultraglide play``: render a swipe or a touch log to a device in real time, through the engine.

The swipe or log is replayed as touch reports, at their own times, into the real-time engine
(:mod:`render.engine`, its own process), exactly as the demo's touch panel feeds it.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import threading
import time
from dataclasses import dataclass
from types import SimpleNamespace
from typing import TYPE_CHECKING

from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.commands.finger_options import add_finger_options, finger_config
from ultraglide.apps.commands.render_options import add_render_options, model_words, planning_asked

if TYPE_CHECKING:
    from ultraglide.render.engine import EngineConfig
from ultraglide.apps.cli.signals import held

REPORT_HZ = 120.0  # a synthetic swipe is reported like a 120 Hz touch panel


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide play``: its options."""
    play = commands.add_parser(
        "play", help="render a swipe or a touch log to a device in real time",
        description="Feed a swipe (as 120 Hz touch reports) or a touch log (at its own times) to the live "
                    "renderer and play it on a device.")
    add_render_options(play)
    output_option(play, "--device", kind="device", metavar="URL",
                      help="sim, serial:PORT[?baud=N], audio[:NAME_OR_INDEX][?rate=N&latency=S&blocksize=N], "
                           "wav:PATH (a recording; stopped by a signal, it keeps what played, whole) or null "
                           "(default: the rig's device, else sim); audio and serial need --rig or --profile")
    play.set_defaults(plate_device_default="sim")
    play.add_argument("--track-resonance", action="store_true",
                      help="follow the plate's drifting resonance from its telemetry (a small dither of the "
                           "carrier, stepping toward more amplitude per unit drive); plate drivers only")
    output_option(play, "--save-profile", metavar="PROFILE.toml",
                      help="with --track-resonance: write the profile with the resonance it ended on, for the next "
                           "run's --profile")
    play.add_argument("--closed-loop", action="store_true",
                      help="make the friction the plate's force sensors measure follow the texture (a plate driver "
                           "with normal and lateral force sensors; its amplitude loop too); on sim, a simulated "
                           "finger (the default one unless --finger)")
    output_option(play, "--envelope-csv", kind="log", metavar="FILE.csv",
                      help="record the envelope as it plays: t_s (perf_counter s: when the value plays, by a plate "
                           "driver's SENSORS; else the renderer's plan), index, x_mm, y_mm, down, target_ratio, "
                           "target_um_pp, commanded_um_pp (what the device was given), plan_s (the renderer's plan), "
                           "planned_ratio (the ratio the model's inverse was asked for: the planner's command)")
    output_option(play, "--sensors-csv", kind="log", metavar="FILE.csv",
                      help="record the plate's sensor samples as they come: sample, setpoint_index (the stream index "
                           "playing: the envelope CSV's index), received_s, amplitude_um_pp, normal_force_n, "
                           "lateral_force_n (a plate driver with sensors)")
    play.add_argument("--json", action="store_true", help="print the final status as JSON")
    add_finger_options(play, "--device sim")
    play.set_defaults(run=run)


def report_chunks(trajectory):
    """The touch reports to replay, in chunks of ``(t_s, x_mm, y_mm, force_n)`` arrays: a log's own
    rows as they stream from its file, or every 1/120 s along a swipe. Force is NaN where unknown."""
    import numpy as np
    from ultraglide.render.trajectory import RecordedTrajectory

    if isinstance(trajectory, RecordedTrajectory):
        for t, x, y, force in trajectory.chunks():
            yield t, x, y, np.full(len(t), np.nan) if force is None else force
        return
    per_chunk = int(REPORT_HZ * 10)
    for first in itertools.count(0, per_chunk):
        times = trajectory.start_s + (first + np.arange(per_chunk)) / REPORT_HZ
        times = times[times < trajectory.end_s]
        if not len(times):
            return
        states = trajectory.state(times)
        yield times, states.x_mm, states.y_mm, np.broadcast_to(states.force_n, times.shape)


@dataclass
class Replayed:
    """What :func:`replay` did: the last position (mm), the reports sent, and those skipped because a newer one
    was due by the time this process ran (a log denser than this loop, or a machine too busy to keep time)."""

    last: tuple[float, float] | None
    sent: int
    skipped: int


def replay(touch, chunks, started: float, sleep=time.sleep, replayed: Replayed | None = None) -> Replayed:
    """Call ``touch(t, x, y, force)`` for each report when its time comes (the first at ``started``,
    perf_counter seconds); when several are due at once, only the newest, as a touch panel's late reader gets
    the newest touch. ``sleep(s)`` waits (the engine's raises when the engine is lost); ``replayed``, if given, is
    kept up to date as reports go (what was sent when ``sleep`` raised)."""
    import numpy as np

    done = replayed if replayed is not None else Replayed(None, 0, 0)
    origin = None
    for times, xs, ys, forces in chunks:
        origin = times[0] if origin is None else origin
        due = times - origin
        k = 0
        while k < len(due):
            now = time.perf_counter() - started
            if due[k] > now:
                sleep(due[k] - now)
                continue
            newest = int(np.searchsorted(due, now, side="right")) - 1  # the newest report already due
            done.skipped += newest - k
            force = float(forces[newest])
            touch(time.perf_counter(), float(xs[newest]), float(ys[newest]), None if math.isnan(force) else force)
            done.sent += 1
            done.last = (float(xs[newest]), float(ys[newest]))
            k = newest + 1
        done.last = (xs[-1], ys[-1])
    return done


class made_meanwhile:  # noqa: N801 - read as a verb: first = made_meanwhile(...); first.result()
    """``make()`` on a thread of its own while the caller does other work; :meth:`result` waits for it in the
    engine's sleeps, so an engine lost meanwhile raises :class:`~ultraglide.render.engine.EngineLost` at once
    rather than when ``make`` is done (under load, compiling a path can take seconds). The thread is a daemon: a
    run that ends on a lost engine does not wait for it."""

    def __init__(self, make, engine):
        self._engine, self._done = engine, threading.Event()
        self._value, self._error = None, None
        threading.Thread(target=self._run, args=(make,), name="ultraglide-first-chunk", daemon=True).start()

    def _run(self, make) -> None:
        try:
            self._value = make()
        except BaseException as error:  # noqa: BLE001 - raised again in the caller's thread
            self._error = error
        finally:
            self._done.set()

    def result(self):
        while not self._done.is_set():
            self._engine.sleep(0.01)
        if self._error is not None:
            raise self._error
        return self._value


def engine_config(args) -> EngineConfig:
    from ultraglide.render.engine import EngineConfig
    from ultraglide.render.physics.calibration import load_model

    return EngineConfig(texture=args.texture, model=args.model, profile=args.profile, device=args.device,
                        carrier_hz=args.carrier_hz, rate_hz=args.rate, lookahead_s=args.lookahead_ms / 1000.0,
                        precompensate=not args.no_precompensation,
                        plan=planning_asked(args, load_model(args.model)),
                        track_resonance=getattr(args, "track_resonance", False),
                        default_force_n=0.5 if args.force is None else args.force,
                        closed_loop=getattr(args, "closed_loop", False),
                        finger=finger_config(args) if hasattr(args, "finger") else None,
                        envelope_csv=getattr(args, "envelope_csv", None),
                        sensors_csv=getattr(args, "sensors_csv", None))


def run(args) -> int:
    from ultraglide.apps.cli.files import refuse_overlaps, render_inputs
    from ultraglide.apps.commands.output_report import force_words, share_words
    from ultraglide.apps.commands.plate_choice import plate_words
    from ultraglide.apps.commands.render_setup import load_inputs
    from ultraglide.devices.serial.run_report import EXIT_CLEAN, RunReport
    from ultraglide.devices.urls import parse_device_url
    from ultraglide.render.engine import Engine, EngineLost

    device = parse_device_url(args.device)
    refuse_overlaps({"--device": device.target if device.kind == "wav" else None, "--save-profile": args.save_profile,
                     "--envelope-csv": getattr(args, "envelope_csv", None),
                     "--sensors-csv": getattr(args, "sensors_csv", None)}, render_inputs(args))
    inputs = load_inputs(args)  # every mistake in the options surfaces before a device is touched
    effects = None
    if args.effects or args.no_effects:
        from ultraglide.textures.effects import load_effects, to_json

        effects = to_json(load_effects(args.effects) if args.effects else ())
    save_to = None
    if args.save_profile:
        from pathlib import Path

        from ultraglide.apps.cli.errors import UsageError
        from ultraglide.apps.commands.plate import check_profile_path

        if not args.track_resonance:
            raise UsageError("--save-profile saves the resonance that --track-resonance found; give both")
        save_to = check_profile_path(Path(args.save_profile), "--save-profile")
    trajectory = inputs.trajectory
    for recorded in (args.envelope_csv, args.sensors_csv):
        if recorded:
            from pathlib import Path

            from ultraglide.apps.cli.errors import UsageError

            if not Path(recorded).parent.is_dir():
                raise UsageError(f"{recorded}: no directory {Path(recorded).parent} to write it in")
    engine = Engine.start(engine_config(args))
    started = time.perf_counter()
    replayed = Replayed(None, 0, 0)
    try:
        if effects is not None:
            engine.set_effects(effects)  # instead of the texture's own
        chunks = report_chunks(trajectory)
        # the first chunk is made before the clock starts, while the engine gets ready (its work, loading a compiled
        # path, must not make the first reports late), and on a thread: an engine lost meanwhile ends the run now
        first = made_meanwhile(lambda: list(itertools.islice(chunks, 1)), engine)
        engine.wait_ready()
        first = first.result()
        if not args.json:
            for note in (engine.ready_info.get("device_status") or {}).get("notes") or []:
                print(note, flush=True)  # where the device's own limits bind, said once before playing
            print(plate_words(inputs.profile, args.profile), flush=True)  # which plate, chosen by whom
            print(model_words(args.model, inputs.model, planning_asked(args, inputs.model)), flush=True)
        started = time.perf_counter()
        replay(engine.touch, itertools.chain(first, chunks), started, engine.sleep, replayed)
        engine.touch(time.perf_counter(), float(replayed.last[0]), float(replayed.last[1]), down=False)
        engine.sleep(engine.ready_info["tail_s"])
    except EngineLost:  # its process died or froze: the device is safe already (its supervisor); said below
        pass
    except BaseException:  # a stop signal or an error: the engine lost meanwhile (even while it stopped) is said
        with held():
            engine.stop()
        for line in (engine.loss.lines(started) if engine.loss is not None else ()):
            print(line, file=sys.stderr)
        raise
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            final = engine.stop()  # ramps down, rests the plate and ends the engine, on every way out
    played_s = round(time.perf_counter() - started, 3)
    figures = final.summary()
    figures["fault_words"] = figures.pop("faults")
    device_status = figures.pop("device_status")
    report = RunReport.from_dict(device_status.get("report"))
    loss = engine.loss
    if loss is not None:  # the device's own report stops where its process did
        report = report.with_lines(loss.lines(started), loss.exit_status)
    counts = device_status.pop("fault_counts", None)
    limiter = device_status.pop("limiter", "")
    clipped = final.clipped_samples / final.control_samples if final.control_samples else 0.0
    status = {**device_status, **figures, "clipped_fraction": round(clipped, 6), "faults": counts or {},
              "played_s": played_s, "touch_reports_sent": replayed.sent, "touch_reports_skipped": replayed.skipped,
              "engine_lost": None if loss is None else loss.lines(started)}
    if final.clipped_samples:
        force = force_words(trajectory, SimpleNamespace(default_force_n=engine.config.default_force_n))
        print(f"warning: {share_words(clipped)} of the time the texture asked for less friction than model "
              f"{args.model} reaches at {force} within "
              f"{inputs.profile.max_amplitude_um_pp:g} µm p-p; held at the limit", file=sys.stderr)
    tracking = device_status.get("tracking")
    if save_to is not None and tracking is not None:
        save_tracked_profile(save_to, inputs.profile, tracking)
    if args.json:
        print_json(status)
    else:
        effects_started = device_status.get("effects_started", 0)
        played = f"; {effects_started} effect{'s' if effects_started != 1 else ''} played" if effects_started else ""
        print(f"played {played_s:.2f} s on {final.device}: {final.blocks} blocks rendered, {final.late_blocks} late, "
              f"{final.underruns} device underruns; block time {final.block_p50_us:.0f} µs median, "
              f"{final.block_p99_us:.0f} µs p99; {final.clipped_samples} samples held at the plate's limit{played}; "
              f"engine priority {final.priority}")
        if replayed.skipped:
            print(f"{replayed.skipped} of {replayed.sent + replayed.skipped} touch reports skipped: this process ran "
                  f"too late for them (a busy machine) and sent the newest one due instead")
        from ultraglide.devices.sinks.audio import pacing_words  # not at import: it brings the output stage

        paced = pacing_words(device_status)
        if paced:
            print(paced)
        print(limiter)
        for line in report.lines:  # what happened to the plate, and when
            print(line)
        print(describe_faults(counts or {}, lost=loss is not None,
                              found=loss is None and report.exit_status != EXIT_CLEAN))
        if tracking is not None:
            print(tracking_words(tracking))
        if "loop" in device_status:
            print(loop_words(device_status))
        if save_to is not None and tracking is not None:
            print(f"profile with the tracked resonance written to {save_to}: use --profile {save_to} next time")
    if report.exit_status:
        print(f"ultraglide play: {report.verdict}", file=sys.stderr)
    return report.exit_status


def loop_words(status: dict) -> str:
    """The friction loop over the run, in one line: its state at the end, the error the plate's sensors measured
    (against the texture and, with a model that has friction dynamics, against the friction the plan means felt),
    what it adapted."""
    error, from_plan = status.get("friction_error_rms"), status.get("friction_error_plan_rms")
    measured = "no friction measured (the finger never slid)" if error is None else \
        f"ratio error {error:.3f} rms as the plate's sensors measured it" + (
            "" if from_plan is None else f" ({from_plan:.3f} from the friction the plan means felt)")
    return (f"friction loop: {measured}; at the end {status['loop']}; mu0 {status['mu0']:.3g}, model scale "
            f"x{status['adapted_scale']:.3g}, correction {status['correction']:+.3f}; "
            f"{status['loop_fallbacks']} fallbacks to open loop")


def tracking_words(tracking: dict) -> str:
    """What ``--track-resonance`` followed, from the tracker's summary, in one line."""
    if not tracking["steps"]:
        return (f"resonance tracking: no step taken (the drive was too low or too short to measure); still at "
                f"{tracking['start_hz']:.1f} Hz")
    return (f"resonance tracked from {tracking['start_hz']:.1f} Hz to {tracking['resonance_hz']:.1f} Hz "
            f"(drift {tracking['drift_hz']:+.1f} Hz, {tracking['rate_hz_per_s']:+.2f} Hz/s at the end; "
            f"{tracking['steps']} steps, {tracking['discarded_steps']} discarded)")


def save_tracked_profile(path, profile, tracking: dict) -> None:
    """The profile played with, its resonance replaced by the one tracking ended on."""
    from dataclasses import replace

    from ultraglide.apps.commands.plate import save_profile

    found = replace(profile, name=path.stem, resonance_hz=tracking["resonance_hz"],
                    description=f"{profile.name} with the resonance tracked by ultraglide play")
    save_profile(path, found, "written by `ultraglide play --track-resonance`", tracking_words(tracking))


def describe_faults(counts: dict[str, int], lost: bool = False, found: bool = False) -> str:
    """The run's device faults in words, e.g. ``device faults: 2 × watchdog trip (...)``; ``lost``: the engine was
    lost, so the counts are those its last status had; ``found``: the host found the device at fault (values it
    could not believe, an amplitude it did not follow, refusals, a lost link), said in the report's lines above:
    then a device that raised no fault of its own is not summed up as "none"."""
    from ultraglide.devices.protocol import FAULT_WORDS

    happened = [f"{count} × {FAULT_WORDS.get(name, name)}" for name, count in counts.items() if count]
    heading = "device faults until the engine was lost" if lost else "device faults"
    if happened:
        return f"{heading}: " + "; ".join(happened)
    own = "this device reports none" if not counts else "none"
    if found:
        return (f"{heading}: {'the device reports none' if not counts else 'none raised by the device'}; "
                "what went wrong is said above")
    return f"{heading}: {own}"
