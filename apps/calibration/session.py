"""``ultraglide calibrate --device URL``: one participant calibrated on the plate.

The plate plays the plan (:mod:`.plan`) with its amplitude loop on, where it has one; its SENSORS are summed
step by step (:mod:`.recording`) while the guide (:mod:`.guide`) asks for each press and shows the press now.
The points (each reduced step's friction over the friction at rest beside it, at its measured amplitude and
force) are fitted as ``calibrate`` fits a CSV (``render.physics.calibration.fit_model``, cross-validated), and
written as a calibration file with the participant's id, with the points beside it (``CAL.csv``: refit them
with ``ultraglide calibrate CAL.csv``). On the in-process simulator the finger is simulated and its press
follows the plan (unless ``--finger-force`` says otherwise).

The plate is rested (zero, disabled) on every way out, stop signals included.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.commands.plate_choice import plate_of

FRAME_S = 0.1  # the guide's pace: ten frames a second are enough to follow a press
CONTROL_RATE_HZ = 12000
MIN_POINTS = 6


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
    profile = plate_of(args)
    plan = CalibrationPlan(tuple(args.forces), profile.max_amplitude_um_pp, passes=args.passes,
                           step_s=args.step_ms / 1000.0, settle_s=min(0.12, 0.4 * args.step_ms / 1000.0))
    kind = parse_device_url(args.device).kind
    if kind not in ("sim", "serial"):
        raise UsageError(f"an on-plate calibration needs a plate driver with force sensors (sim or serial:PORT), "
                         f"not {args.device}")
    extra = {"amplitude_loop": True}
    if kind == "sim":
        config = finger_config(args, wanted=True)
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
    return _fit_and_write(args, recorder, plan)


def _fit_and_write(args, recorder, plan) -> dict:
    from ultraglide.apps.cli.files import atomic_path
    from ultraglide.render.physics.calibration import calibration_toml, fit_model

    data, missing = recorder.measurements(f"on-plate calibration on {args.device}", args.participant)
    if len(data) < MIN_POINTS:
        raise UsageError(f"only {len(data)} steps were measured ({missing} left out: the finger did not slide at a "
                         f"steady press); calibrate again, sliding through every step")
    fit = fit_model(data, args.model, cross_validate=True, bootstrap=args.bootstrap)
    output = Path(args.output)
    points = output.with_suffix(".csv")
    with atomic_path(points) as temporary:
        rows = ["amplitude_um_pp,relative_friction,force_n,participant"]
        rows += [f"{a:.5f},{r:.5f},{f:.5f},{args.participant}" for a, r, f in
                 zip(data.amplitude_um_pp, data.relative_friction, data.force_n, strict=True)]
        temporary.write_text("\n".join(rows) + "\n")
    with atomic_path(output) as temporary:
        temporary.write_text(calibration_toml(fit, participant=args.participant, procedure=plan.words()))
    from ultraglide.apps.figures.calibration import write_calibration_figure

    figures = write_calibration_figure([fit], output.with_suffix(".png"), getattr(args, "figure_width", "column"))
    return {"fit": fit, "points": len(data), "missing_steps": missing, "written": [output, points, *figures]}
