"""``ultraglide latency``: from a touch entering the engine to the first output sample that reflects it.

A finger rests on the sticky half of a two-region texture, then a touch report puts it on the
slippery half; each step is timed from the report (``Engine.touch``) in two parts:

* **engine**: until the block computed from it is handed to the device (waiting for the device's
  next pull, then rendering);
* **device**: the device's buffering from there to the plate: for audio, PortAudio's output latency;
  for the simulated plate, measured end to end on the plate model's amplitude (the serial writer's
  batch, the link and the firmware's jitter buffer); for null, nothing.

The engine uses the "hold" predictor here, so a report moves the finger at once (the predictor's own
smoothing is the fidelity benchmark's subject, not the pipeline's).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.options import MODEL_HELP, output_option
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import STEPS
from ultraglide.apps.commands.plate_choice import add_plate_options
from ultraglide.render.physics.default_model import DEFAULT_MODEL

if TYPE_CHECKING:
    from ultraglide.render.engine import Engine
from ultraglide.apps.cli.errors import UsageError

STICKY_MM = (20.0, 25.0)
SLIPPERY_MM = (60.0, 25.0)
STEP_TIMEOUT_S = 10.0
ENGINE_AIM_MS = 2.0

DEVICE_PART = {
    "sim": "serial writer batch, link and the plate's jitter buffer, measured on the simulated plate",
    "audio": "PortAudio's output latency",
    "null": "none (the null sink keeps nothing)",
    "wav": "none (the recorder writes what it pulls)",
    "serial": "the plate's jitter buffer as the host keeps it (its lead, moved for the depth the plate reports); "
              "the link's own latency is not measured",
}


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide latency``: its options."""
    latency = commands.add_parser(
        "latency", help="time from a touch to the first output sample that reflects it",
        description="Step a finger from a sticky to a slippery region many times and report the time from "
                    "each touch entering the real-time engine to the first output sample that reflects it: "
                    "the engine's part and the device's buffering part (end to end on the simulated plate).")
    output_option(latency, "--device", kind="device", metavar="URL",
                         help="sim, serial:PORT, audio[:NAME][?...], wav:PATH or null (default: sim)")
    latency.add_argument("--steps", type=STEPS, default=40, help="how many steps to time, 1 to 10000 (default: 40)")
    add_plate_options(latency, latency, device_default="sim")
    latency.add_argument("--model", default=DEFAULT_MODEL, metavar="MODEL",
                         help=f"{MODEL_HELP} (default: {DEFAULT_MODEL}, which plans the friction felt)")
    latency.add_argument("--json", action="store_true", help="print one JSON object")
    latency.set_defaults(run=run)


def _wait(condition, timeout_s: float = STEP_TIMEOUT_S, what: str = "the engine", engine=None) -> None:
    """Poll ``condition`` until it holds; UsageError after ``timeout_s``, EngineLost (exit 7) at once if ``engine`` was
    lost (its supervisor made the device safe)."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if engine is not None and engine.loss is not None:
            from ultraglide.render.engine import EngineLost

            raise EngineLost(engine.loss)
        if time.monotonic() > deadline:
            raise UsageError(f"{what} did not respond within {timeout_s:g} s; is the device running?")
        time.sleep(0.0005)


def measure(device: str, steps: int = 40, profile: str = "sim-plate", rate_hz: int = 96000,
            rest_s: float = 0.0, model: str = DEFAULT_MODEL) -> dict:
    """Step the finger ``steps`` times; returns the figures (ms) as a plain dict. ``rest_s``: how long the
    plate rests before each step beyond the few ms it needs (0.1 lets a serial link go idle, disabled); ``model``:
    the friction model the engine renders with."""
    import numpy as np
    from ultraglide.render.engine import Engine, EngineConfig
    from ultraglide.textures.fileformat import save_texture
    from ultraglide.textures.texture import Texture

    kind = device.partition(":")[0].partition("?")[0]
    with tempfile.TemporaryDirectory(prefix="ultraglide-latency-") as folder:
        texture = Texture(np.array([[1.0, 0.5]], dtype=np.float32), 80.0, 50.0, outside="clamp", name="step")
        path = save_texture(texture, Path(folder) / "step.png")
        config = EngineConfig(texture=str(path), device=device, profile=profile, predictor="hold", rate_hz=rate_hz,
                              probe_plate=kind == "sim", model=model)
        with Engine.start(config) as engine:
            engine.wait_ready()
            engine_s, device_s, total_s, woke = [], [], [], []
            for _ in range(steps):
                engine_s_, device_s_, total_s_, woke_ = _one_step(engine, kind, rest_s)
                engine_s.append(engine_s_)
                device_s.append(device_s_)
                total_s.append(total_s_)
                woke.append(woke_)
            status = engine.status()
    periods = np.diff(status.history.time_s)
    block_ms = float(np.median(periods) * 1e3) if len(periods) else None
    return {
        "device": status.device, "steps": steps, "model": model,
        "engine_ms": _percentiles(engine_s), "device_ms": _percentiles(device_s), "total_ms": _percentiles(total_s),
        # a plate driver that had rested its output (50 ms of zeros) is woken with its lead at once and plays on
        # arrival; one still streaming plays the step a buffer's depth later: the two apart
        "steps_from_rest": sum(woke),
        "device_streaming_ms": _percentiles([d for d, w in zip(device_s, woke, strict=True) if not w]),
        "device_from_rest_ms": _percentiles([d for d, w in zip(device_s, woke, strict=True) if w]),
        "device_part": DEVICE_PART.get(kind, ""), "block_ms": block_ms, "priority": status.priority,
        "engine_aim_ms": ENGINE_AIM_MS, "report": status.device_status.get("report"),
        # a plate driver's buffer that drifted from its depth moved the host's lead, and the device part with it
        "depth_corrections": status.device_status.get("depth_corrections", 0),
        # frames a starved host sent after the plate's buffer had run dry play on arrival, sooner than the lead says
        "late_frames": status.device_status.get("late_frames", 0),
    }


def _one_step(engine: Engine, kind: str, rest_s: float = 0.0) -> tuple[float, float, float, bool]:
    """One step, sticky to slippery: (engine part, device part, total) in s, and whether it woke a plate driver
    that had rested its output."""
    import numpy as np

    def at_rest() -> bool:
        history = engine.status(history_s=0.05).history
        resting = len(history.commanded_um_pp) > 0 and history.commanded_um_pp[-1] < 0.01
        if kind == "sim":
            resting = resting and engine.plate_probe()[0] < 0.01
        return resting

    engine.touch(time.perf_counter(), *STICKY_MM)
    _wait(at_rest, engine=engine)
    time.sleep(0.005 + rest_s + np.random.default_rng().uniform(0, 0.003))  # a random phase of the blocks
    wakes = engine.status().device_status.get("idle_wakes") if kind == "serial" else None
    touched = time.perf_counter()
    engine.touch(touched, *SLIPPERY_MM)

    def rendered():
        times, done, _ = engine.latencies()
        return np.any(times == touched)

    _wait(rendered, engine=engine)
    times, done, presented = engine.latencies()
    row = np.flatnonzero(times == touched)[-1]
    engine_part = done[row] - touched
    if kind == "sim":
        _wait(lambda: engine.plate_probe()[1] > touched, what="the simulated plate", engine=engine)
        total = engine.plate_probe()[1] - touched
        return engine_part, total - engine_part, total, False
    device_part = presented[row] - done[row]
    woke = False
    if wakes is not None:  # the step's frame has gone once the driver streams; it woke the plate if it counted a wake
        _wait(lambda: engine.status().device_status.get("output") != "idle (disabled)", what="the plate driver",
              engine=engine)
        woke = engine.status().device_status.get("idle_wakes", wakes) > wakes
    return engine_part, device_part, engine_part + device_part, woke


def _percentiles(values_s: list[float]) -> dict | None:
    import numpy as np

    if not values_s:
        return None
    values = np.asarray(values_s) * 1e3
    return {"p50": round(float(np.percentile(values, 50)), 3), "p99": round(float(np.percentile(values, 99)), 3)}


def describe(figures: dict) -> str:
    e, d, t = figures["engine_ms"], figures["device_ms"], figures["total_ms"]
    verdict = "within" if e["p99"] < figures["engine_aim_ms"] else "over"
    block = f" (the device pulls every {figures['block_ms']:.2f} ms)" if figures["block_ms"] else ""
    return (f"touch to first output sample on {figures['device']}, {figures['steps']} steps, model "
            f"{figures['model']}:\n"
            f"  engine  {e['p50']:.2f} ms median, {e['p99']:.2f} ms p99: waiting for the next pull and "
            f"rendering{block}; {verdict} the {figures['engine_aim_ms']:g} ms aim\n"
            f"  device  {d['p50']:.2f} ms median, {d['p99']:.2f} ms p99: {figures['device_part']}\n"
            f"{_split(figures)}"
            f"  total   {t['p50']:.2f} ms median, {t['p99']:.2f} ms p99 (engine priority: {figures['priority']})")


def _split(figures: dict) -> str:
    """The device part of the steps that found a plate driver streaming and of those that woke it, where both."""
    woke = figures.get("steps_from_rest", 0)
    if not woke:
        return ""
    lines = []
    for key, which in (("device_streaming_ms", "steps while it streamed"), ("device_from_rest_ms", "steps that "
                                                                           "woke it from rest (plays on arrival)")):
        part = figures[key]
        count = woke if key == "device_from_rest_ms" else figures["steps"] - woke
        if part is not None:
            lines.append(f"          {part['p50']:.2f} ms median, {part['p99']:.2f} ms p99: the {count} {which}\n")
    return "".join(lines)


def run(args) -> int:
    if args.steps < 2:
        raise UsageError("--steps must be at least 2")
    from ultraglide.devices.serial.run_report import RunReport
    from ultraglide.render.physics.calibration import load_model

    load_model(args.model)  # a bad model is one line before the engine starts
    figures = measure(args.device, args.steps, args.profile, model=args.model)
    print_json(figures) if args.json else print(describe(figures))
    report = RunReport.from_dict(figures["report"])
    if report.exit_status:  # the plate was lost, cut its output or faulted: the figures are not to be trusted
        if not args.json:
            for line in report.lines:
                print(line)
        print(f"ultraglide latency: {report.verdict}", file=sys.stderr)
    return report.exit_status
