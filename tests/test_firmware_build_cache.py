"""The firmware build's cache (``devices/firmware/boards.py``, ``~/.cache/ultraglide/firmware/BOARD-DIGEST``) when
several processes build the same board at once, as the suite's workers and ``plate-sim`` do after a source changed:
each gets its image, and no image a build returned goes missing while another build finishes (each built file is
moved into the entry on its own; the entry was once swapped whole, and two of three processes building at once saw
their image gone for a while after ``build_images`` returned). Real processes, real builds, a cache in tmp_path."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None,
                       reason="needs gcc-arm-none-eabi and libnewlib-arm-none-eabi"),
]

# One process: build, then look at the image it was handed for 3 s (while the others finish theirs); prints the
# image's path and how many looks found no file there.
BUILD_AND_WATCH = """
import json, os, sys, time
from ultraglide.devices.firmware.boards import build_images
image = build_images(sys.argv[1], ["qemu"])[0]
missing = looks = 0
end = time.monotonic() + 3.0
while time.monotonic() < end:
    looks += 1
    missing += not os.path.isfile(image.elf_path)
print(json.dumps({"elf": image.elf_path, "looks": looks, "missing": missing}))
"""


@pytest.mark.parametrize("board", ["mps2-an386", "netduinoplus2"])
def test_three_builds_at_once_each_keep_the_image_they_were_given(tmp_path, board):
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    builds = [subprocess.Popen([sys.executable, "-c", BUILD_AND_WATCH, board], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env) for _ in range(3)]
    results = []
    for build in builds:
        out, err = build.communicate(timeout=600)
        assert build.returncode == 0, err[-2000:]
        results.append(json.loads(out))
    assert len({r["elf"] for r in results}) == 1  # one cache entry for the one set of sources
    assert all(r["looks"] > 0 and r["missing"] == 0 for r in results), results
    entry = os.path.dirname(results[0]["elf"])
    assert os.path.isfile(results[0]["elf"]) and os.path.getsize(results[0]["elf"]) > 0
    # nothing left beside the entry: the scratch folders the builds made are gone
    assert os.listdir(os.path.dirname(entry)) == [os.path.basename(entry)]
