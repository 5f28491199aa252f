"""Peak memory of commands given a small PNG of 99 million pixels (issue 26).

A texture file may hold up to 100 million pixels; a PNG of one gray level, or of a fine grating, compresses to a
few hundred KB. Each command runs in its own process under ``/usr/bin/time``; the figure is the largest
resident set of the process and its children (the export's writer, play's engine), with the wall time.

    .venv/bin/python bench/bench_texture_memory.py [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin

SIDE = 9950  # 99.0 M pixels
ROOT = Path(__file__).resolve().parent.parent


def make_pngs(directory: Path) -> dict[str, Path]:
    """An 8-bit and a 16-bit texture file of 80 × 80 mm (124 pixels per mm), a 1.6 mm grating."""
    info = PngImagePlugin.PngInfo()
    info.add_itxt("ultraglide", json.dumps({"format_version": 1, "width_mm": 80.0, "height_mm": 80.0}))
    row = (np.arange(SIDE) % 20 < 10)
    files = {}
    for name, values in (("8-bit", row.astype(np.uint8) * 255), ("16-bit", row.astype(np.uint16) * 65535)):
        path = directory / f"big-{name}.png"
        Image.fromarray(np.broadcast_to(values, (SIDE, SIDE)).copy()).save(path, pnginfo=info)
        files[name] = path
    return files


def measure(args: list[str]) -> tuple[float, float, str]:
    """Peak resident memory (MB) and wall time (s) of ``ultraglide ARGS``, and its last line of output."""
    result = subprocess.run(["/usr/bin/time", "-f", "PEAK %M %e", sys.executable, "-m", "ultraglide", *args],
                            capture_output=True, text=True, cwd=ROOT)
    found = re.search(r"PEAK (\d+) ([\d.]+)", result.stderr)
    if found is None:
        raise SystemExit(f"ultraglide {' '.join(args)} gave no figures:\n{result.stderr}")
    last = (result.stdout.strip().splitlines() or result.stderr.strip().splitlines() or [""])[-1]
    return int(found[1]) / 1000.0, float(found[2]), last


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", metavar="DIR", help="make the PNGs in DIR and keep them")
    options = parser.parse_args()
    directory = Path(options.keep or tempfile.mkdtemp(prefix="bench-texture-"))
    directory.mkdir(parents=True, exist_ok=True)
    files = make_pngs(directory)
    for name, path in files.items():
        print(f"{name}: {path.stat().st_size / 1000:.0f} KB, {SIDE} × {SIDE} pixels, 80 × 80 mm "
              f"(load average {os.getloadavg()[0]:.1f})")
        for label, args in (("texture info", ["texture", "info", str(path)]),
                            ("export 1 s", ["export", str(path), "-o", str(directory / "out.wav"),
                                            "--duration-s", "1"]),
                            ("play 1 s (wav)", ["play", str(path), "--device", f"wav:{directory / 'live.wav'}",
                                                "--duration-s", "1"])):
            peak_mb, wall_s, last = measure(args)
            print(f"  {label:15} peak {peak_mb:7.0f} MB  {wall_s:6.1f} s   {last[:100]}")
    if not options.keep:
        for path in directory.iterdir():
            path.unlink()
        directory.rmdir()


if __name__ == "__main__":
    main()
