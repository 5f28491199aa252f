"""``ultraglide calibrate --device URL``: one participant calibrated on the plate.

The plate plays the plan (:mod:`.plan`) with its amplitude loop on, where it has one; its SENSORS are summed
step by step (:mod:`.recording`) while the guide (:mod:`.guide`) asks for each press and shows the press now.
The points (each reduced step's friction over the friction at rest beside it, at its measured amplitude and
force) are fitted as ``calibrate`` fits a CSV (``render.physics.calibration.fit_model``, cross-validated), and
written as a calibration file with the participant's id, with the points beside it (``CAL.csv``: refit them
with ``ultraglide calibrate CAL.csv``). The samples themselves are kept too (``CAL-recording.csv``,
:mod:`ultraglide.render.physics.dynamics_fit`): the friction's onset and recovery time constants are fitted
from each step's edges, written into the calibration where the data resolve them (a finger whose recovery
is resolved has its rests measured after four recovery time constants, and its points refitted), and
``calibrate --compare
CAL-recording.csv`` ranks static and dynamic models on them in time. On the in-process simulator the finger
is simulated and its press follows the plan (unless ``--finger-force`` says otherwise).

The plate is rested (zero, disabled) on every way out, stop signals included.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.commands.plate_choice import plate_of

FRAME_S = 0.1  # the guide's pace: ten frames a second are enough to follow a press
CONTROL_RATE_HZ = 12000
MIN_POINTS = 6
REST_SETTLE_TAUS = 4.0  # a lagging finger's rests are measured after this many recovery time constants ...
REST_SETTLE_S = 0.03  # ... rather than this (recording.SETTLE_S), where that is longer
MIN_REST_S = 0.06  # ... leaving at least this much of each rest to measure


def calibrate_on_plate(args) -> dict:
    """Run the session the options describe; returns what was fitted and written (``fit``, ``points``,
    ``written``, ``missing_steps``) for the command to print. UsageError/DeviceError in one line."""
    from ultraglide.apps.calibration.guide import TextGuide, WindowGuide
    from ultraglide.apps.calibration.plan import CalibrationPlan
    from ultraglide.apps.calibration.recording import PlanSource, StepRecorder
    from ultraglide.apps.cli.signals import held
    from ultraglide.apps.commands.finger_options import finger_config
    from ultraglide.devices import protocol as p
    from ultraglide.devices.errors import DeviceError
    from ultraglide.devices.urls import open_device, parse_device_url
    from ultraglide.render.engine.finger_setup import build_finger
    from ultraglide.render.engine.realtime import threads_started_in_real_time

    if args.participant is None:
        raise UsageError("an on-plate calibration needs --participant ID (written into the calibration)")
    if args.output is None or Path(args.output).suffix != ".toml":
        raise UsageError("an on-plate calibration needs -o CAL.toml")
    from ultraglide.atomic.targets import check_output

    check_output(recording_path(Path(args.output)), "-o (its recording beside it)")  # before the session, not after
    profile = plate_of(args)
    plan = CalibrationPlan(tuple(args.forces), profile.max_amplitude_um_pp, passes=args.passes,
                           step_s=args.step_ms / 1000.0, settle_s=min(0.12, 0.4 * args.step_ms / 1000.0))
    kind = parse_device_url(args.device).kind
    if kind not in ("sim", "serial"):
        raise UsageError(f"an on-plate calibration needs a plate driver with force sensors (sim or serial:PORT), "
                         f"not {args.device}")
    extra = {"amplitude_loop": True}
    sensors = _sensor_lag(args, kind)
    if kind == "sim":
        config = finger_config(args, wanted=True)
        sensors["bandwidth_hz"], sensors["delay_s"] = config.bandwidth_hz, config.delay_ms / 1000.0
        scripted = args.finger_force is not None and Path(args.finger_force).is_file()  # its own speeds, unrecorded
        sensors["stated"] = "the simulated finger's force sensors"
        sensors["speed_mm_s"] = math.nan if scripted else config.speed_mm_s
        if args.finger_force is None:  # the simulated participant presses as asked
            times, forces = plan.force_points()
            config = replace(config, force_points=(tuple(times), tuple(forces)))
        extra["finger"] = build_finger(config)
    elif getattr(args, "finger", None) is not None:
        raise UsageError("--finger is for the in-process simulator (--device sim); a plate-sim on a port takes "
                         "its own (plate-sim --finger)")
    guide = TextGuide(args.participant) if args.no_window else WindowGuide(args.participant, args.windowed)
    with threads_started_in_real_time():  # a simulated plate's threads, as the stream's below; this one (the
        device = open_device(args.device, profile, control_rate_hz=CONTROL_RATE_HZ, **extra)  # guide's) stays ordinary
    recorder = StepRecorder(plan, CONTROL_RATE_HZ)
    device.add_sensor_listener(recorder.take)
    source = PlanSource(plan, CONTROL_RATE_HZ)
    cancelled = False
    try:
        with threads_started_in_real_time():
            device.start(source)
        hello = device.hello()
        wanted = p.SENSOR_NORMAL_FORCE | p.SENSOR_LATERAL_FORCE
        if hello is None or (hello.sensors & wanted) != wanted:
            raise DeviceError(f"{args.device}: the plate driver declares no normal and lateral force sensors; "
                              "an on-plate calibration measures friction with them")
        recorder.sensor_rate_hz = float(hello.sensor_rate_hz)
        while not source.finished:
            level, done = recorder.progress(source.played_s)
            if not guide.show(level, len(plan.forces_n), plan.forces_n[level], recorder.force_n, recorder.sliding,
                              done):
                cancelled = True
                break
            time.sleep(FRAME_S)
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            source.request_stop()
            device.stop()
            guide.close()
            finger = extra.get("finger")
            if finger is not None:
                finger.close()
    if cancelled:
        raise UsageError("calibration cancelled: nothing written")
    return _fit_and_write(args, recorder, plan, sensors)


def _sensor_lag(args, kind: str) -> dict:
    """The force sensors' lag and the sliding speed as the options state them (the simulator's are its finger's:
    ``--finger-bandwidth-hz``, ``--finger-delay-ms``, ``--finger-speed-mm-s``)."""
    given = {"--sensor-bandwidth-hz": args.sensor_bandwidth_hz, "--sensor-delay-ms": args.sensor_delay_ms,
             "--slide-speed-mm-s": args.slide_speed_mm_s}
    if kind == "sim":
        for option, value in given.items():
            if value is not None:
                raise UsageError(f"{option} states a real plate's sensors or the participant's speed; the simulator's "
                                 "are its finger's (--finger-bandwidth-hz, --finger-delay-ms, --finger-speed-mm-s)")
        return {}
    stated = ("as given" if args.sensor_bandwidth_hz is not None and args.sensor_delay_ms is not None else
              "assumed where not given: 300 Hz and 1 ms, as the friction loop's nominal sensors")
    return {"bandwidth_hz": 300.0 if args.sensor_bandwidth_hz is None else args.sensor_bandwidth_hz,
            "delay_s": 0.001 if args.sensor_delay_ms is None else args.sensor_delay_ms / 1000.0, "stated": stated,
            "speed_mm_s": math.nan if args.slide_speed_mm_s is None else args.slide_speed_mm_s}


def recording_path(output: Path) -> Path:
    """Where a calibration's recording goes: ``CAL-recording.csv`` beside ``CAL.toml``."""
    return output.with_name(output.stem + "-recording.csv")


def _fit_and_write(args, recorder, plan, sensors: dict) -> dict:
    import warnings

    from ultraglide.apps.cli.files import atomic_path
    from ultraglide.render.physics.calibration import calibration_toml, fit_model
    from ultraglide.render.physics.dynamics_fit import SensorLag, find_steps, fit_dynamics

    data, missing = recorder.measurements(f"on-plate calibration on {args.device}", args.participant)
    if len(data) < MIN_POINTS:
        raise UsageError(f"only {len(data)} steps were measured ({missing} left out: the finger did not slide at a "
                         f"steady press); calibrate again, sliding through every step")
    fit = fit_model(data, args.model, cross_validate=True, bootstrap=args.bootstrap)
    output = Path(args.output)
    lag = SensorLag(recorder.sensor_rate_hz, sensors["bandwidth_hz"], sensors["delay_s"], sensors["stated"])
    recording = recorder.recording(lag, sensors["speed_mm_s"], args.participant,
                                   f"on-plate calibration on {args.device}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the fitted model at the steps' own presses: within its range or at its edge
        dynamics = fit_dynamics(recording, find_steps(recording), fit.model)
    recovery = dynamics.recovery
    if math.isfinite(recovery.fitted_s) and recovery.low_s > lag.resolution_s:
        # a finger still recovering at a rest's start lowers friction at rest, and so raises every ratio: the rests
        # are measured after four of its recovery time constants (as much as the rests allow), and refitted
        rest_settle_s = min(REST_SETTLE_TAUS * recovery.fitted_s, plan.step_s - MIN_REST_S)
        if rest_settle_s > REST_SETTLE_S:
            data, missing = recorder.measurements(f"on-plate calibration on {args.device}", args.participant,
                                                  rest_settle_s=rest_settle_s)
            if len(data) < MIN_POINTS:
                raise UsageError(f"only {len(data)} steps were measured once each rest's recovery was left out; "
                                 "calibrate again with longer steps (--step-ms)")
            fit = fit_model(data, args.model, cross_validate=True, bootstrap=args.bootstrap)
            dynamics.notes.append(f"friction at rest measured after the first {1000 * rest_settle_s:.0f} ms of each "
                                  f"rest ({REST_SETTLE_TAUS:g} recovery time constants, as the rests allow; "
                                  f"{1000 * REST_SETTLE_S:.0f} ms for a finger without dynamics), the points refitted")
    saved = recording_path(output)
    with atomic_path(saved) as temporary:
        recording.write(temporary)
    points = output.with_suffix(".csv")
    with atomic_path(points) as temporary:
        # the sliding speed where it is known, so sessions at several speeds, joined, fit the speed law
        speed = sensors["speed_mm_s"]
        known = math.isfinite(speed) and speed > 0.0
        rows = ["amplitude_um_pp,relative_friction,force_n," + ("speed_mm_s," if known else "") + "participant"]
        rows += [f"{a:.5f},{r:.5f},{f:.5f}," + (f"{speed:g}," if known else "") + str(args.participant)
                 for a, r, f in zip(data.amplitude_um_pp, data.relative_friction, data.force_n, strict=True)]
        temporary.write_text("\n".join(rows) + "\n")
    with atomic_path(output) as temporary:
        temporary.write_text(calibration_toml(fit, participant=args.participant, procedure=plan.words(),
                                              dynamics=dynamics, recording=saved.name))
    from ultraglide.apps.figures.calibration import write_calibration_figure

    figures = write_calibration_figure([fit], output.with_suffix(".png"), getattr(args, "figure_width", "column"))
    return {"fit": fit, "points": len(data), "missing_steps": missing, "dynamics": dynamics,
            "written": [output, points, saved, *figures]}
