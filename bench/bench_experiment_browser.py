"""How long a participant in a browser waits between an answer and the next trial (``experiment run --serve``),
and how soon a level set in the method of adjustment is played (``--adjust N``).

Run: .venv/bin/python bench/bench_experiment_browser.py [--trials 40] [--device sim]
     .venv/bin/python bench/bench_experiment_browser.py --adjust 100 [--device sim]
     .venv/bin/python bench/bench_experiment_browser.py --texture-at 100

A real ``ultraglide experiment run DESIGN.toml --serve`` process (the engine on the device, the service listening)
and a page's messages from a real WebSocket client in this process, which answers each trial as soon as it is shown.
For each trial after the first: the time from the answer sent to the next ``participant.trial`` received (the
runner logs the row, builds the next trial's texture, hands it to the engine, and the page is told), in ms. The
design: the tutorial's two gratings (1 mm and 2 mm, contrast 0.3) in 2-AFC, 40 mm zones.

With ``--adjust N``: one adjustment trial (the 2 mm grating matched to the 1 mm one, contrast 0.02-0.6, 40 mm
zones); the client sets N levels one after another, each 1 dB from the last (up, then down at the range's top), and
times each ``participant.adjust`` from sent to answered: the session has composed the trial's texture with the
adjusted zone at that level and handed it to the engine, which plays it (what a finger on the zone waits for).

With ``--texture-at N``: the same adjustment trial's textures built in this process, N levels 1 dB apart, by the
presentation's ``texture_at`` (the stimulus loaded and sampled once) and afresh (loaded, sampled and composed for
every level, as each step was built before), in ms a level; the two give the same arrays.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

DESIGN = """
[experiment]
name = "bench"
seed = 1

[stimuli.fine]
texture = "grating-1mm"
contrast = 0.3

[stimuli.coarse]
texture = "grating-2mm"
contrast = 0.3

[[conditions]]
name = "pair"
a = "fine"
b = "coarse"

[[blocks]]
name = "main"
task = "afc"
conditions = ["pair"]
intervals = 2
repeats = {repeats}
"""


ADJUST_DESIGN = DESIGN.split("[[conditions]]")[0] + """
[[conditions]]
name = "match"
stimulus = "coarse"
reference = "fine"
range = [0.02, 0.6]

[[blocks]]
name = "main"
task = "adjustment"
conditions = ["match"]
repeats = 1
"""


def adjust(args) -> None:
    from websockets.sync.client import connect

    with tempfile.TemporaryDirectory() as folder:
        design = pathlib.Path(folder) / "design.toml"
        design.write_text(ADJUST_DESIGN, encoding="utf-8")
        process = subprocess.Popen([sys.executable, "-m", "ultraglide", "experiment", "run", str(design),
                                    "--participant", "P01", "--out", str(pathlib.Path(folder) / "out"), "--serve",
                                    "--port", "0", "--device", args.device, "--json", "--accept-check"],
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            address = json.loads(process.stdout.readline())
            origin = address["page"].split("?")[0].rstrip("/")
            times = []
            with connect(address["url"], proxy=None, origin=origin, open_timeout=60) as ws:
                ws.send(json.dumps({"type": "hello", "id": 0, "protocol": 1}))
                while True:
                    screen = json.loads(ws.recv(timeout=120))
                    if screen.get("type") == "participant.trial":
                        break
                level, (low, high), direction = screen["level"], screen["range"], 1
                for number in range(1, args.adjust + 1):
                    stepped = level * 10 ** (direction / 20)
                    if not low <= stepped <= high:
                        direction = -direction
                        stepped = level * 10 ** (direction / 20)
                    level = stepped
                    sent = time.perf_counter()
                    ws.send(json.dumps({"type": "participant.adjust", "id": number, "trial": screen["trial"],
                                        "level": level}))
                    while True:
                        reply = json.loads(ws.recv(timeout=120))
                        if reply.get("id") == number:
                            break
                    assert reply["type"] == "ok" and reply["level"] == level, reply
                    times.append((time.perf_counter() - sent) * 1e3)
                ws.send(json.dumps({"type": "participant.answer", "id": 0, "trial": screen["trial"], "value": level,
                                    "rt_s": 1.0}))
                status = process.wait(120)
        finally:
            if process.poll() is None:
                process.kill()
    ms = np.asarray(times)
    print(f"{args.adjust} levels set on {args.device}, exit {status}: from participant.adjust sent to the level "
          f"played p50 {np.percentile(ms, 50):.1f} ms, p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms")


def texture_at(args) -> None:
    from ultraglide.textures.compose import Placement, compose

    from ultraglide.experiment import design_from_toml, run, zone_texture
    from ultraglide.experiment.responders import Answer

    design = design_from_toml(ADJUST_DESIGN)
    shown = []

    class Keep:  # the participant's interface: keeps the trial presented
        def present(self, presentation):
            shown.append(presentation)
            return Answer(presentation.level, 1.0)

        def take_break(self, trial, message=""):
            return True

    run(design, responder=Keep(), check=False)
    presentation, layout = shown[0], shown[0].layout
    condition = design.conditions["match"]
    low, high = condition.range
    levels = [min(max(presentation.level * 10 ** (i / 20), low), high) for i in range(args.texture_at)]

    def afresh(level):
        reference = zone_texture(design.stimuli[condition.reference], design.zone_mm)
        adjusted = zone_texture(design.stimuli[condition.stimulus], design.zone_mm, level)
        placements = [Placement(reference, layout.zone_left_mm(0), layout.gap_mm),
                      Placement(adjusted, layout.zone_left_mm(1), layout.gap_mm)]
        px = max(10.0, max(1.0 / min(p.texture.pixel_mm) for p in placements))
        return compose(layout.size_mm, placements, 1.0, px_per_mm=min(px, 40.0), name="afresh")

    times = {"texture_at": [], "afresh": []}
    for level in levels:
        for name, build in (("texture_at", presentation.texture_at), ("afresh", afresh)):
            started = time.perf_counter()
            texture = build(level)
            times[name].append((time.perf_counter() - started) * 1e3)
            if name == "texture_at":
                kept = texture.values
            else:
                assert np.array_equal(kept, texture.values)
    for name, ms in times.items():
        ms = np.asarray(ms)
        print(f"{name}: {len(ms)} levels, p50 {np.percentile(ms, 50):.1f} ms, p99 {np.percentile(ms, 99):.1f} ms, "
              f"max {ms.max():.1f} ms a level")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=40)
    parser.add_argument("--adjust", type=int, default=0, metavar="N",
                        help="time N levels set in one adjustment trial instead")
    parser.add_argument("--texture-at", type=int, default=0, metavar="N",
                        help="time N adjustment textures built in this process, by texture_at and afresh, instead")
    parser.add_argument("--device", default="sim")
    args = parser.parse_args()
    if args.texture_at:
        texture_at(args)
        return
    if args.adjust:
        adjust(args)
        return
    from websockets.sync.client import connect

    with tempfile.TemporaryDirectory() as folder:
        design = pathlib.Path(folder) / "design.toml"
        design.write_text(DESIGN.format(repeats=args.trials), encoding="utf-8")
        process = subprocess.Popen([sys.executable, "-m", "ultraglide", "experiment", "run", str(design),
                                    "--participant", "P01", "--out", str(pathlib.Path(folder) / "out"), "--serve",
                                    "--port", "0", "--device", args.device, "--json"],
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            address = json.loads(process.stdout.readline())
            origin = address["page"].split("?")[0].rstrip("/")
            gaps = []
            with connect(address["url"], proxy=None, origin=origin, open_timeout=60) as ws:
                ws.send(json.dumps({"type": "hello", "id": 0, "protocol": 1}))
                answered_s = None
                done = 0
                while done < args.trials:
                    message = json.loads(ws.recv(timeout=120))
                    if message.get("type") != "participant.trial":
                        continue
                    if answered_s is not None:
                        gaps.append((time.perf_counter() - answered_s) * 1e3)
                    answered_s = time.perf_counter()
                    ws.send(json.dumps({"type": "participant.answer", "id": message["trial"],
                                        "trial": message["trial"], "button": 0, "rt_s": 0.5}))
                    done += 1
            status = process.wait(120)
        finally:
            if process.poll() is None:
                process.kill()
    gaps_ms = np.asarray(gaps)
    print(f"{args.trials} trials on {args.device}, exit {status}: answer to the next trial shown "
          f"p50 {np.percentile(gaps_ms, 50):.1f} ms, p99 {np.percentile(gaps_ms, 99):.1f} ms, "
          f"max {gaps_ms.max():.1f} ms (n = {len(gaps_ms)})")


if __name__ == "__main__":
    main()
