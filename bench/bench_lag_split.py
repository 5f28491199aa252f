"""Where a lagging finger's real-time closed-loop error against the plan comes from (issue 43).

Run: .venv/bin/python bench/bench_closed_loop.py --only-real-time --keep DIR, then
     .venv/bin/python bench/bench_lag_split.py DIR [--open]

Reads the kept logs of the lagging two-force table finger's real-time run (closed loop; ``--open``: open loop):
the finger's log (its truth, the plate's amplitude and the force, on the host's clock), the envelope record
(the amplitude the model or loop chose, what was sent, the planner's command ``planned_ratio``) and the sensors
record (which stream value played when). Against the friction the plan means felt (the planner's command through
the published dynamics: ``bench_closed_loop.played_felt``), after the first 2 s where the limit allows the target:

* **truth**: RMS and mean of the finger's ratio against the plan as played, and against the plan rebuilt afterwards
  at the finger's median floor (``bench_closed_loop.planned_felt``, the figure of the table before), and how far
  two rebuilds differ when the floor moves by 0.01 or the targets by one sample (what the rebuilt figure cannot
  tell apart);
* **shares**, each through the published dynamics and the finger's own law (its table, drift and force): the plate
  (the law at the plate's amplitude against at the amplitude sent), the envelope (sent against chosen), the loop (at
  the amplitude chosen against the plan). They add up to the truth's error within the closure (the finger's ratio
  against the law at the plate's amplitude: what the finger's dynamics and the log's sampling leave);
* **by force**: the error against the plan as played where the finger pressed below 0.5 N and at 0.5 N or more.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_closed_loop import (  # noqa: E402
    CONTROL_HZ,
    LEARN_S,
    finger_floor,
    lined_up,
    planned_felt,
    played_felt,
    read,
)
from ultraglide.render.engine.finger_setup import FingerConfig, finger_law  # noqa: E402
from ultraglide.render.physics.dynamics import FrictionDynamics  # noqa: E402
from ultraglide.render.planning import felt_over  # noqa: E402

SPEED_MM_S = 100.0


def split(folder: Path, closed: bool = True) -> dict:
    """The figures of the module docstring for the kept run in ``folder``."""
    name = f"real-100-two-force-finger-lagging-{'closed' if closed else 'open'}"
    log, envelope = read(folder / f"{name}-finger.csv"), read(folder / f"{name}-envelope.csv")
    line = lined_up(envelope, read(folder / f"{name}-sensors.csv"), log)
    spec = f"table:{folder / 'two-force-finger.csv'}"
    t = line["t"]
    swiped = line["down"] & (log["sliding"] > 0.5) & np.isfinite(line["target"])
    pick = swiped & (t >= t[swiped][0] + LEARN_S) & (t < t[swiped][-1] - 0.05)
    floor = finger_floor(log, t, spec)
    pick &= line["target"] >= floor
    rows = np.clip(line["index"], 0, None).astype(int)

    def per_row(felt: np.ndarray) -> np.ndarray:
        return np.where(line["index"] >= 0, felt[np.clip(rows, 0, len(felt) - 1)], np.nan)

    meant = per_row(played_felt(envelope, SPEED_MM_S))
    rebuilt = per_row(planned_felt(envelope, SPEED_MM_S, float(np.median(floor[pick]))))
    judged = pick & np.isfinite(meant) & np.isfinite(rebuilt)
    truth = log["relative_friction"]

    def rms_mean(a, b, where=judged) -> tuple[float, float]:
        d = (a - b)[where]
        return float(np.sqrt(np.mean(d ** 2))), float(np.mean(d))

    config = FingerConfig(law=spec)
    law = finger_law(config)
    scale = 1.0 + config.drift * np.sin(2 * math.pi * t / config.drift_period_s)
    force = np.maximum(log["normal_force_n"], 0.01)
    rate = 1.0 / float(np.median(np.diff(log["t_s"])))
    at = np.clip(np.searchsorted(envelope["index"], line["index"]), 0, len(envelope) - 1)
    chosen = np.where(line["index"] >= 0, envelope["target_um_pp"][at], 0.0)
    sent = np.where(line["index"] >= 0, envelope["commanded_um_pp"][at], 0.0)
    dynamics = FrictionDynamics()
    at_chosen, at_sent, at_plate = (dynamics.respond(law(a / scale, force), rate, SPEED_MM_S)
                                    for a in (chosen, sent, log["amplitude_um_pp"]))
    down = np.flatnonzero(envelope["down"] > 0)
    targets = envelope["target_ratio"][down[0]:down[-1] + 1]
    n = len(targets) - int(CONTROL_HZ) // 5
    median_floor = float(np.median(floor[pick]))
    base = felt_over(dynamics, targets, n, SPEED_MM_S, median_floor)[1][int(CONTROL_HZ):]
    moved = {"floor +0.01": felt_over(dynamics, targets, n, SPEED_MM_S, median_floor + 0.01)[1][int(CONTROL_HZ):],
             "one sample later": felt_over(dynamics, targets[1:], n, SPEED_MM_S, median_floor)[1][int(CONTROL_HZ):]}
    light = judged & (log["normal_force_n"] < 0.5)
    return {"played": rms_mean(truth, meant), "rebuilt": rms_mean(truth, rebuilt),
            "rebuilds differ": {k: float(np.sqrt(np.mean((v[:len(base) - 1] - base[:len(v) - 1]) ** 2)))
                                for k, v in moved.items()},
            "plate": rms_mean(at_plate, at_sent), "envelope": rms_mean(at_sent, at_chosen),
            "loop": rms_mean(at_chosen, meant), "closure": rms_mean(truth, at_plate),
            "below 0.5 N": rms_mean(truth, meant, light), "0.5 N or more": rms_mean(truth, meant, judged & ~light),
            "share at 0.5 N or more": float((judged & ~light).sum() / judged.sum())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="bench_closed_loop.py --keep's folder")
    parser.add_argument("--open", action="store_true", help="the open-loop run instead of the closed one")
    args = parser.parse_args()
    figures = split(args.folder, closed=not args.open)
    for key, value in figures.items():
        if isinstance(value, tuple):
            print(f"{key:>22}: rms {value[0]:.3f}, mean {value[1]:+.3f}")
        elif isinstance(value, dict):
            print(f"{key:>22}: " + ", ".join(f"{k} {v:.3f} rms" for k, v in value.items()))
        else:
            print(f"{key:>22}: {value:.2f}")


if __name__ == "__main__":
    main()
