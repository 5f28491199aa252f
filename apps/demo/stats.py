"""``demo --stats FILE.json``: the engine's figures over the run, written at exit."""

from __future__ import annotations

from pathlib import Path


def run_stats(app, final=None) -> dict:
    """The engine's figures over the run (``final``: its last status, after stop), and the demo's touch counts."""
    driver = app.driver
    if app.link is None:
        return {"started": False, "touches_not_felt_before_ready": driver.unfelt}
    s = final if final is not None else app.link.status(0.0).engine
    return {"started": True, "device": s.device, "blocks_rendered": s.blocks, "late_blocks": s.late_blocks,
            "resting_blocks": s.resting_blocks,
            "underruns": s.underruns, "underruns_at_first_touch": driver.underruns_at_first_touch,
            "block_p50_us": _rounded(s.run_block_p50_us), "block_p99_us": _rounded(s.run_block_p99_us),
            "block_times": "over every block rendered in the run (not the resting ones), ±1 % (a histogram)",
            "limited_samples": s.clipped_samples, "faults": list(s.faults), "priority": s.priority,
            "touches": driver.pushed, "touches_received_by_engine": s.touches,
            "touches_dropped_by_engine": s.touches_dropped, "touches_not_felt_before_ready": driver.unfelt,
            "report": (s.device_status or {}).get("report")}


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(value, 2)


def write_stats(path: str, stats: dict) -> None:
    from ultraglide.apps.cli.files import atomic_path
    from ultraglide.apps.cli.output import json_text

    with atomic_path(Path(path)) as temporary:
        temporary.write_text(json_text(stats, indent=2) + "\n")  # strict: NaN is null
