"""How fast a dry run goes: 120 trials of a 3-zone staircase, each swipe rendered offline (96 kHz carrier).

Run: .venv/bin/python bench/bench_experiment.py
Prints the time per trial (texture, render) and for the whole session with its analysis and figures.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from ultraglide.apps.commands.experiment import design_for
from ultraglide.apps.experiment.session import SessionConfig, run_session
from ultraglide.devices.profiles import load_profile

from ultraglide.experiment.dryrun import SimResponder
from ultraglide.experiment.observer import SimObserver


def main() -> None:
    for method, intervals in (("staircase", 3), ("quest", 2)):
        config = SessionConfig(texture="grating-1mm", method=method, intervals=intervals, trials=120, seed=1,
                               observer="sim:threshold=0.08,slope=3,lapse=0.02")
        design = design_for(config)
        responder = SimResponder(SimObserver.parse(config.observer, 1), design.model, load_profile("sim-plate"),
                                 config.speed_mm_s, config.force_n)
        with tempfile.TemporaryDirectory() as folder:
            started = time.perf_counter()
            outcome = run_session(config, design, responder, Path(folder))
            elapsed = time.perf_counter() - started
        seconds = responder.rendered_frames / 96000
        print(f"{method} {intervals}AFC: 120 trials in {elapsed:.1f} s wall ({elapsed / 120 * 1000:.0f} ms a trial), "
              f"{seconds:.0f} s of 96 kHz signal rendered ({seconds / elapsed:.0f}x real time); "
              f"threshold {outcome.result['threshold']:.4f} (true 0.08), CI {outcome.result['ci']}")


if __name__ == "__main__":
    main()
