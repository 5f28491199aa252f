"""Friction in time: the friction a finger with the published dynamics feels, instantaneous against planned renderer.

Run: .venv/bin/python bench/bench_dynamics.py [--figures DIR]
Issue 43's measurement: a 1 mm grating (the library's grating-1mm, ratios 0.41-1) at 50, 100 and 200 mm/s and a
step 1 -> 0.3 -> 1, rendered through the whole renderer (lookup, planning, model inverse, envelope and the plate's
own envelope model) for the default dynamic model (stretched, with onset 5 ms and recovery 70 ms at 22 mm/s), the
plate's amplitude then felt by the simulated plate's finger with the same published dynamics in its own code
(devices/sim/finger.py). Reported: the RMS error between the felt friction and the texture's target, the felt
contrast, and the planning's cost per block. Open loop only (the closed loop does not plan yet).
Aim: the planned renderer halves the instantaneous error at 100 mm/s where the limit allows. Beside each case, the
least error any plan reaches knowing the whole future (bench/finger_bound.py, on the same target and score: "bound",
the plate's envelope left out, no plan does better; "with plate", a plan found for the plate's envelope lag, which
exists), and the bound for a step with first-order dynamics computed by hand (settled ratios within 0.3-1).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from finger_bound import FORCE_N, BoundError, case_bounds
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.finger import FingerDynamics, FingerParams, ForceScript, SimulatedFinger
from ultraglide.devices.sim.force_sensors import ForceSensorParams
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.renderer import Renderer, RenderSettings
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.texture import Texture

RATE = 12000
SPEEDS_MM_S = (50.0, 100.0, 200.0)
BLOCK = 120  # 10 ms blocks
LIVE_BLOCK = 8  # the engine's live block at 12 kHz (64 frames at 96 kHz)


def step_texture() -> Texture:
    """1 before 10 mm, 0.3 from 10 to 30 mm, 1 after: a finger at v meets the fall at 10/v s and the rise at 30/v."""
    x = (np.arange(600) + 0.5) * 0.1
    row = np.where((x >= 10.0) & (x < 30.0), 0.3, 1.0).astype(np.float32)
    return Texture(np.tile(row, (50, 1)), 60.0, 5.0, outside="clamp", name="step 1-0.3-1")


def felt_error(texture: Texture, speed: float, plan: bool, start_mm: float = 0.0, length_mm: float | None = None):
    """(RMS error felt - target, felt contrast / target contrast, seconds of rendering per second of signal, the
    target per sample)."""
    model = load_model("dynamic")
    length = length_mm if length_mm is not None else min(speed * 1.0, 55.0)
    duration = length / speed
    path = RecordedTrajectory([0.0, duration], [start_mm, start_mm + length], [2.5, 2.5])
    renderer = Renderer(texture, model, load_profile("sim-plate"), RenderSettings(plan=plan), trajectory=path)
    finger = SimulatedFinger(model.static.relative_friction, ForceScript.constant(0.5, speed),
                             FingerParams(drift=0.0, moisture=0.0), ForceSensorParams(noise_n=0.0),
                             sample_rate_hz=RATE, dynamics=FingerDynamics())
    ratios, felt, spent = [], [], 0.0
    samples = int(duration * RATE)
    done = 0
    while done < samples:
        n = min(BLOCK, samples - done)
        start = time.perf_counter()
        block = renderer.control(n)
        spent += time.perf_counter() - start
        ratios.append(block.ratio.astype(float))
        felt.append(finger.truth((done + np.arange(n)) / RATE, block.plate_um_pp).relative_friction.copy())
        done += n
    target, felt = np.concatenate(ratios), np.concatenate(felt)
    settled = slice(int(0.05 * RATE), None)  # the first 50 ms: the finger lands
    error = float(np.sqrt(np.mean((felt[settled] - target[settled]) ** 2)))
    contrast = float(np.ptp(felt[settled]) / max(np.ptp(target[settled]), 1e-9))
    return error, contrast, spent / duration, target


def live_block_cost(plan: bool) -> float:
    """Median µs of one 8-sample live block (a finger pushed at 100 mm/s), planned or not."""
    renderer = Renderer(resolve_texture("grating-1mm"), load_model("dynamic"), load_profile("sim-plate"),
                        RenderSettings(plan=plan))
    buffers = renderer.control_buffers(256, always=True)
    t = 1000.0
    times = []
    for k in range(3000):
        if k % 15 == 0:
            renderer.push(t, 10.0 + 100.0 * (t - 1000.0), 25.0, 0.5)
        start = time.perf_counter()
        renderer.control(LIVE_BLOCK, t, buffers)
        times.append(time.perf_counter() - start)
        t += LIVE_BLOCK / RATE
    return float(np.median(times[500:]) * 1e6)


def step_bound(speed: float) -> tuple[float, float]:
    """The instantaneous renderer's RMS error on the bench's step and the least any plan can reach, by hand: a fall
    of 0.7 with tau_on and a rise of 0.7 with tau_rec; an instantaneous step costs 0.49 tau / 2 each, the best
    start of an exponential (ln 2 tau early) 0.49 tau (ln 2 - 1 + 3/8 + 1/8) = 0.49 tau 0.193."""
    dynamics = FingerDynamics()
    tau_rec = dynamics.recovery_s * (dynamics.reference_speed_mm_s / speed) ** dynamics.speed_exponent
    total = 55.0 / speed - 0.05
    best_share = math.log(2.0) - 1.0 + 0.375 + 0.125
    instant = 0.49 * (dynamics.onset_s + tau_rec) / 2.0
    best = 0.49 * (dynamics.onset_s + tau_rec) * best_share
    return math.sqrt(instant / total), math.sqrt(best / total)


def decision_cost() -> float:
    """The least µs of one planning decision (the compiled planner on a 24-sample block, a 100 mm/s finger's
    horizon, the felt ratio anywhere from 0.3 to 1 below an edge): its worst case is every candidate weighed."""
    from ultraglide.render.kernels import PLAN_ROWS, plan_friction
    from ultraglide.render.physics.dynamics import FrictionDynamics
    from ultraglide.render.planning import Planner

    planner = Planner(FrictionDynamics(), RATE)
    planner.set_speed(100.0)
    stride, steps = planner.stride, planner.steps
    target = np.full(stride, 0.3)
    ahead = np.r_[np.full(steps // 3, 0.3), np.ones(steps)].astype(np.float32)
    out, work = np.empty(stride), np.empty((PLAN_ROWS, steps + 1))
    times = []
    for felt in np.tile(np.linspace(0.3, 1.0, 200), 5):
        start = time.perf_counter_ns()
        plan_friction(target, ahead, stride, 0.1, 1.0, planner.k_onset, planner.k_recovery, stride, steps, 9, felt,
                      0, 0.3, 1, out, work)
        times.append(time.perf_counter_ns() - start)
    return min(times[1:]) / 1000.0  # the first call may load the compiled kernel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figures", metavar="DIR", help="also write friction-in-time and contrast-transfer here")
    args = parser.parse_args()
    grating = resolve_texture("grating-1mm")
    step = step_texture()
    profile = load_profile("sim-plate")
    law = load_model("dynamic").static.relative_friction
    print(f"{'case':28} {'instantaneous':>14} {'planned':>9} {'planned/inst.':>14} {'contrast inst.':>15} "
          f"{'planned':>8} {'render s/s':>11} {'bound':>7} {'bound/inst.':>12} {'with plate':>11} "
          f"{'planned/bound':>14}")
    for name, texture, start in (("1 mm grating", grating, 5.0), ("step 1 -> 0.3 -> 1", step, 0.0)):
        for speed in SPEEDS_MM_S:
            e_i, c_i, _, target = felt_error(texture, speed, False, start)
            e_p, c_p, cost, _ = felt_error(texture, speed, True, start)
            scored = np.arange(len(target)) >= int(0.05 * RATE)  # as felt_error scores
            try:
                bound, with_plate = case_bounds(target, scored, lambda a: law(a, FORCE_N), FingerDynamics(), speed,
                                                RATE, profile.max_amplitude_um_pp, profile.time_constant_s,
                                                profile.max_drive_um_pp)
            except BoundError as error:
                print(f"{name + f' {speed:g} mm/s':28} {e_i:14.3f} {e_p:9.3f} {e_p / e_i:14.2f} {c_i:15.2f} "
                      f"{c_p:8.2f} {cost:11.3f} {error}")
                continue
            print(f"{name + f' {speed:g} mm/s':28} {e_i:14.3f} {e_p:9.3f} {e_p / e_i:14.2f} {c_i:15.2f} {c_p:8.2f} "
                  f"{cost:11.3f} {bound.rms:7.3f} {bound.rms / e_i:12.2f} {with_plate.rms:11.3f} "
                  f"{e_p / bound.rms:14.2f}")
    for speed in SPEEDS_MM_S:
        instant, best = step_bound(speed)
        print(f"step at {speed:g} mm/s by hand, settled ratios within 0.3-1: instantaneous {instant:.3f}, the best "
              f"plan {best:.3f} ({best / instant:.2f} of it): halving is out of reach for first-order dynamics")
    print(f"live block of {LIVE_BLOCK} samples: {live_block_cost(False):.1f} µs instantaneous, "
          f"{live_block_cost(True):.1f} µs planned (median)")
    from ultraglide.render.planning import DECISION_S

    print(f"one planning decision (every {1000 * DECISION_S:g} ms): {decision_cost():.1f} µs (the least of 1000)")
    if args.figures:
        from ultraglide.apps.figures.dynamics import contrast_figure, friction_in_time
        from ultraglide.render.physics.dynamics import FrictionDynamics

        folder = Path(args.figures)
        folder.mkdir(parents=True, exist_ok=True)
        floor = float(load_model("stretched").floor_ratio(0.5, load_profile("sim-plate").max_amplitude_um_pp))
        for written in (friction_in_time(folder / "friction-in-time.png", FrictionDynamics(), floor),
                        contrast_figure(folder / "contrast-transfer.png", FrictionDynamics(), floor)):
            print("wrote", written[0])


if __name__ == "__main__":
    main()
