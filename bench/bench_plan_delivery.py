"""Where a lagging finger's closed-loop error against the plan goes: the plate's delivery or the loop's model.

Run: .venv/bin/python bench/bench_plan_delivery.py [--seconds 6]

Issue 43's case in simulated time (tests/test_friction_loop_dynamics.py's lagging table finger): a 1 mm grating
(ratio 0.4-1) at 100 mm/s on the firmware core and the simulated plate (bench/closed_loop_rig.py), the host playing
``--model dynamic``, the finger given as a table at two forces (bench_closed_loop.table_fingers, its force walking
in 0.2-1 N) with the published dynamics, open and closed loop; and the same on the default finger with the
dynamics. After the first 2 s, per case:

* **texture**: RMS of the finger's true ratio against the texture's target;
* **plan**: against the friction the plan means felt (``RigRun.planned_felt``: the planner's commands through the
  published dynamics, as if the plate played at once what the host intends: the test's figure, aim 0.05);
* **plate**: what the plate's delivery costs: the finger's law at the plate's amplitude against its law at the
  amplitude the host intended, each through the published dynamics (RMS and mean: + is less friction reduction
  than intended);
* **loop**: what the loop's model costs: the finger's law at the intended amplitude, through the dynamics,
  against the plan (RMS and mean). Plate and loop add up to the finger against the plan (the finger's own
  dynamics are the published ones: **closure** is what is left, RMS);
* **pulses**: the plate's mean amplitude against the intended one 0.5, 1 and 2 ms after the intended amplitude
  rises from rest above 1 µm p-p (the plan's pulses), and how many.

The figure of a planner is the one in the tree; to measure another, put its ``render/kernels.py`` and
``render/planning.py`` in place first (the exact planner: ``git checkout planfix -- render/kernels.py
render/planning.py``; ``git checkout HEAD -- ...`` after).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_closed_loop import table_fingers  # noqa: E402
from closed_loop_rig import ClosedLoopRig  # noqa: E402
from ultraglide.render.engine.finger_setup import FingerConfig, finger_law  # noqa: E402
from ultraglide.render.physics.dynamics import FrictionDynamics  # noqa: E402
from ultraglide.textures.procedural import grating  # noqa: E402

SPEED_MM_S = 100.0
AFTER_S = 2.0


def decompose(rig: ClosedLoopRig, run) -> dict:
    """The case's figures (see the module docstring) from a finished run."""
    law = finger_law(rig.config)
    scale = 1.0 + rig.config.drift * np.sin(2 * math.pi * run.t / rig.config.drift_period_s)
    force = np.maximum(run.force, 0.01)
    rate = 1.0 / float(np.median(np.diff(run.t)))
    dynamics = FrictionDynamics()
    intended = np.nan_to_num(run.intended)
    at_intended = dynamics.respond(law(intended / scale, force), rate, SPEED_MM_S)
    at_plate = dynamics.respond(law(run.amplitude / scale, force), rate, SPEED_MM_S)
    meant = run.planned_felt()
    pick = run.pick(AFTER_S) & np.isfinite(meant)

    def rms(a, b):
        return float(np.sqrt(np.mean((a[pick] - b[pick]) ** 2)))

    def mean(a, b):
        return float(np.mean(a[pick] - b[pick]))

    rises = np.flatnonzero((intended[1:] > 1.0) & (intended[:-1] < 0.2)) + 1
    rises = rises[(run.t[rises] > run.t[pick][0]) & (rises < len(run.t) - int(0.003 * rate))]
    pulses = {ms: (float(np.mean(run.amplitude[rises + round(ms * 1e-3 * rate)])),
                   float(np.mean(intended[rises + round(ms * 1e-3 * rate)]))) if len(rises) else (math.nan, math.nan)
              for ms in (0.5, 1.0, 2.0)}
    return {"texture": run.rms_error(AFTER_S), "plan": rms(run.ratio, meant),
            "plate": (rms(at_plate, at_intended), mean(at_plate, at_intended)),
            "loop": (rms(at_intended, meant), mean(at_intended, meant)), "closure": rms(at_plate, run.ratio),
            "pulses": pulses, "rises": len(rises)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=6.0, help="simulated seconds a case (default 6)")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp())
    fingers = {"two forces, lagging": FingerConfig(law=table_fingers(folder)["two forces"], dynamics=True),
               "default, lagging": FingerConfig(dynamics=True)}
    texture = grating(1.0, size_mm=(80.0, 50.0), ratio_range=(0.4, 1.0))
    print(f"{'finger':22} {'loop':6} {'texture':>8} {'plan':>6} {'plate rms/mean':>15} {'loop rms/mean':>15} "
          f"{'closure':>8}  pulses: plate/intended µm p-p at 0.5, 1, 2 ms (count)")
    for name, finger in fingers.items():
        for closed in (True, False):
            rig = ClosedLoopRig(texture, SPEED_MM_S, closed, finger=finger, model="dynamic", seconds=args.seconds)
            f = decompose(rig, rig.run(args.seconds))
            pulses = "  ".join(f"{a:.2f}/{b:.2f}" for a, b in f["pulses"].values())
            print(f"{name:22} {'closed' if closed else 'open':6} {f['texture']:8.3f} {f['plan']:6.3f} "
                  f"{f['plate'][0]:7.3f}/{f['plate'][1]:+.3f} {f['loop'][0]:7.3f}/{f['loop'][1]:+.3f} "
                  f"{f['closure']:8.3f}  {pulses} ({f['rises']})", flush=True)


if __name__ == "__main__":
    main()
