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
before the play clock). And each is placed against the plate's sample clock, value by value: the run's
``--sensors-csv`` names the index playing at each sensor sample (1 kHz), whose time is the finger log's origin (the
plate's sample 0) plus its number; where the index advanced evenly (12 a sample, none of the 20 samples before or
after uneven), index k plays ``(k - setpoint_index) / 12 kHz`` after it. The error's median and largest say how late
each column is (negative: early), stalls and all.

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
import time
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

LAGS_S = np.arange(-20e-3, 20e-3, 0.05e-3)  # the shifts tried, s
EDGE_S = 0.2  # the run's first and last 0.2 s are left out (the swipe's start and its tail)
SENSOR_RATE_HZ = 1000.0  # the simulated plate's sensor samples a second


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


def against_sample_clock(envelope: dict, sensors: dict, log: dict, column: str, rate_hz: float,
                         sensor_rate_hz: float) -> tuple[float, float]:
    """How late ``column`` places each value (s; median, largest by magnitude) by the plate's sample clock."""
    index = sensors["setpoint_index"]
    start_s = log["t_s"][0] + sensors["sample"] / sensor_rate_hz
    per = round(rate_hz / sensor_rate_hz)  # values a sensor sample
    step = np.diff(index)
    even = np.flatnonzero((step == per) & (index[:-1] >= 0))
    uneven = np.flatnonzero(step != per)
    k = envelope["index"]
    at = np.searchsorted(index[even], k, side="right") - 1
    rows = np.flatnonzero((at >= 0) & (k < index[even[np.clip(at, 0, None)]] + per))
    sample = even[at[rows]]
    if len(uneven):  # where it stalled the frames say only between which samples: 20 samples either side are left out
        place = np.searchsorted(uneven, sample)
        since = sample - uneven[np.clip(place - 1, 0, None)]
        until = uneven[np.clip(place, None, len(uneven) - 1)] - sample
        clear = ((since > 20) | (place == 0)) & ((until > 20) | (place == len(uneven)))
        rows, sample = rows[clear], sample[clear]
    late = envelope[column][rows] - (start_s[sample] + (k[rows] - index[sample]) / rate_hz)
    return float(np.median(late)), float(late[np.argmax(np.abs(late))])


def one_run(folder: Path, run: int, device: str, tau_s: float) -> dict:
    envelope, log, sensors = folder / f"envelope-{run}.csv", folder / f"finger-{run}.csv", folder / f"sensors-{run}.csv"
    result = subprocess.run([sys.executable, "-m", "ultraglide", "play", "grating-1mm", "--device", device,
                             "--duration-s", "3", "--envelope-csv", str(envelope), "--finger-log", str(log),
                             "--sensors-csv", str(sensors)],
                            capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        raise SystemExit(f"play failed: {result.stderr.strip().splitlines()[-1]}")
    envelope, log, sensors = read_columns(envelope), read_columns(log), read_columns(sensors)
    rate_hz = float(round(1.0 / float(np.median(np.diff(envelope["plan_s"])))))  # the stream's values a second
    index = sensors["setpoint_index"]
    playing = (index[:-1] >= 0) & (index[1:] >= 0)
    figures = {"stalls": int(np.sum(playing & (np.diff(index) != round(rate_hz / SENSOR_RATE_HZ))))}
    for name, column in (("plan", "plan_s"), ("played", "t_s")):
        lag_s, rms = best_lag(envelope, log, tau_s, column)
        median_s, largest_s = against_sample_clock(envelope, sensors, log, column, rate_hz, SENSOR_RATE_HZ)
        figures[name] = {"lag_ms": round(1000 * lag_s, 2), "fit_rms_um_pp": round(rms, 4),
                         "late_median_ms": round(1000 * median_s, 3), "late_largest_ms": round(1000 * largest_s, 3)}
    return figures


def placing_cost_ms() -> float:
    """What the record's writer spends placing one 0.2 s piece (2400 values at 12 kHz) with the play clock's ring
    full (4096 frames: 41 s of 10 ms frames), ms: the median of 20."""
    from ultraglide.render.engine.play_clock import KEPT, PlayClock

    clock = PlayClock(12000.0)
    rng = np.random.default_rng(0)
    for frame in range(KEPT):
        clock.take(120 * frame, 10, 50.0 + (10 * frame + 10) / 1000.0 + rng.uniform(0.0, 3e-3), 10 * frame)
    index = np.arange(2400.0) + 120 * (KEPT - 200)
    costs = []
    for _ in range(20):
        start = time.perf_counter()
        clock.times_s(index, 50.0 + (KEPT - 200) / 100.0)
        costs.append(time.perf_counter() - start)
    return 1000.0 * float(np.median(costs))


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
    cost_ms = placing_cost_ms()
    if args.json:
        print(json.dumps({"runs": runs, "tau_ms": round(1000 * tau_s, 3), "load": load,
                          "placing_ms_per_piece": round(cost_ms, 2)}, indent=2))
        return 0
    print(f"{load}; the plate's envelope time constant {1000 * tau_s:.2f} ms; the record's writer places a 0.2 s "
          f"piece in {cost_ms:.1f} ms (the play clock's ring full)")
    for run, figures in enumerate(runs):
        plan, played = figures["plan"], figures["played"]
        print(f"run {run + 1} ({figures['stalls']} stalls or skips of the index playing): the values play "
              f"{played['lag_ms']:+.2f} ms after the record's t_s (fit RMS {1000 * played['fit_rms_um_pp']:.0f} nm "
              f"p-p), {plan['lag_ms']:+.2f} ms after the renderer's plan, plan_s (fit RMS "
              f"{1000 * plan['fit_rms_um_pp']:.0f} nm p-p); by the plate's sample clock, t_s is "
              f"{played['late_median_ms']:+.3f} ms late (median; largest {played['late_largest_ms']:+.3f}), plan_s "
              f"{plan['late_median_ms']:+.3f} ms (largest {plan['late_largest_ms']:+.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
