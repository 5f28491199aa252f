"""When each recorded value plays: the envelope record's ``t_s`` against the plate's own clock (issue 43).

Run: .venv/bin/python bench/bench_record_timing.py [--runs 3] [--device sim] [--json]

``play grating-1mm --envelope-csv E --finger-log F`` on the simulated plate, as a user runs it. The finger log is
the plate's truth on the host's clock (the simulated plate knows when it plays each value); its amplitude is the
plate's, which follows the drive through the resonator's first-order envelope response, tau = Q / (pi f0) at
resonance (2.55 ms for sim-plate's Q 200 at 25 kHz). The record's commanded amplitude is put through that response
and slid along the log's time axis: the shift that fits best is how much later than ``t_s`` the values play (a
positive lag: the record is early). The fit's RMS residual says whether one shift explains the run (a few nm) or
the run was disturbed (underruns, a re-anchored clock: tenths of a µm).

Each run is fitted twice: by ``t_s`` (when the value plays: the plate's own SENSORS place it, the play clock,
render/engine/play_clock.py) and by ``plan_s`` (when the renderer meant it to reach the plate: what ``t_s`` was
before the play clock).

Aim (issue 43): ``t_s`` is when each value plays, so |lag| <= 0.5 ms in every run, with the fit's residual as
small as the plan's.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

LAGS_S = np.arange(-20e-3, 20e-3, 0.05e-3)  # the shifts tried, s
EDGE_S = 0.2  # the run's first and last 0.2 s are left out (the swipe's start and its tail)


def read_columns(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}


def plate_amplitude(commanded_um_pp: np.ndarray, rate_hz: float, tau_s: float) -> np.ndarray:
    """The plate's amplitude under a drive held over each sample: a first-order response, one sample at a time."""
    decay = np.exp(-1.0 / (rate_hz * tau_s))
    response = lfilter([1.0 - decay], [1.0, -decay], commanded_um_pp)
    return np.concatenate(([0.0], response[:-1]))  # a value's effect begins as it plays


def best_lag(envelope: dict, log: dict, tau_s: float, column: str = "t_s") -> tuple[float, float]:
    """The shift (s) of the record's times (``column``) that best explains the logged amplitude, and the fit's RMS
    (µm p-p)."""
    t_s = envelope[column]
    rate_hz = 1.0 / float(np.median(np.diff(t_s)))
    predicted = plate_amplitude(envelope["commanded_um_pp"], rate_hz, tau_s)
    kept = (log["t_s"] > t_s[0] + EDGE_S) & (log["t_s"] < t_s[-1] - EDGE_S)
    times, amplitude = log["t_s"][kept], log["amplitude_um_pp"][kept]
    errors = [float(np.sqrt(np.mean((np.interp(times - lag, t_s, predicted) - amplitude) ** 2))) for lag in LAGS_S]
    best = int(np.argmin(errors))
    return float(LAGS_S[best]), errors[best]


def one_run(folder: Path, run: int, device: str, tau_s: float) -> dict:
    envelope, log = folder / f"envelope-{run}.csv", folder / f"finger-{run}.csv"
    result = subprocess.run([sys.executable, "-m", "ultraglide", "play", "grating-1mm", "--device", device,
                             "--duration-s", "3", "--envelope-csv", str(envelope), "--finger-log", str(log)],
                            capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        raise SystemExit(f"play failed: {result.stderr.strip().splitlines()[-1]}")
    envelope, log = read_columns(envelope), read_columns(log)
    figures = {}
    for name, column in (("plan", "plan_s"), ("played", "t_s")):
        lag_s, rms = best_lag(envelope, log, tau_s, column)
        figures[name] = {"lag_ms": round(1000 * lag_s, 2), "fit_rms_um_pp": round(rms, 4)}
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--device", default="sim", help="a device whose plate logs its finger (sim)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    from ultraglide.devices.profiles import load_profile

    plate = load_profile("sim-plate")
    tau_s = plate.q / (np.pi * plate.resonance_hz)
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="ultraglide-bench-record-") as folder:
        runs = [one_run(Path(folder), run, args.device, tau_s) for run in range(args.runs)]
    load = f"load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after, {os.cpu_count()} cores"
    if args.json:
        print(json.dumps({"runs": runs, "tau_ms": round(1000 * tau_s, 3), "load": load}, indent=2))
        return 0
    print(f"{load}; the plate's envelope time constant {1000 * tau_s:.2f} ms")
    for run, figures in enumerate(runs):
        plan, played = figures["plan"], figures["played"]
        print(f"run {run + 1}: the values play {played['lag_ms']:+.2f} ms after the record's t_s "
              f"(fit RMS {1000 * played['fit_rms_um_pp']:.0f} nm p-p); {plan['lag_ms']:+.2f} ms after the "
              f"renderer's plan, plan_s (fit RMS {1000 * plan['fit_rms_um_pp']:.0f} nm p-p)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
