"""The stimulus check on every library texture, along the default zone's swipe (40 × 40 mm zone, left to right
along its middle at 100 mm/s, 0.5 N, the stretched model on sim-plate): which textures cannot carry a friction
contrast along it.

Each texture is asked as it is (its map's own contrast) and at a contrast of 0.3; the figures are the map's own
contrast along the swipe (before rendering) and the contrast the plate model delivered (1st to 99th percentile of
the realised ratio), and the mean friction ratio asked and delivered.

Run: .venv/bin/python bench/bench_experiment_check.py   (a Markdown table for docs/experiments.md)
"""

from __future__ import annotations

import time

from ultraglide.textures.library import library_entries

from ultraglide.experiment import Block, Condition, Design, ExperimentError, Stimulus, check_stimuli


def main() -> None:
    started = time.perf_counter()
    print("| texture | asked contrast | on the swipe | delivered | mean asked / delivered | check |")
    print("|---|---|---|---|---|---|")
    for entry in library_entries():
        for contrast in (None, 0.3):
            stimulus = Stimulus("s", entry.name, contrast=contrast)
            design = Design(entry.name, {"s": stimulus}, {"c": Condition("c", "s")},
                            (Block("b", "rating", ("c",), repeats=1),))
            try:
                report = check_stimuli(design)
            except ExperimentError as error:
                print(f"| {entry.name} | | | | | not checked: {str(error).partition(': ')[2]} |")
                break
            f = report.figures["s"]
            verdict = "passes" if report.passed else "refused: " + (
                "mean off" if f.delivered_contrast >= 0.5 * f.asked_contrast else
                "too little contrast on the swipe" if "does not cross" in report.failures[0] else
                "contrast lost in rendering")
            asked = "its own" if contrast is None else f"{contrast:g}"
            print(f"| {entry.name} | {asked} ({f.asked_contrast:.3f}) | {f.path_contrast:.3f} | "
                  f"{f.delivered_contrast:.3f} | {f.asked_mean:.3f} / {f.delivered_mean:.3f} | {verdict} |")
    print(f"\n{len(library_entries())} textures in {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
