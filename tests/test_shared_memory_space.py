"""The engine's shared memory on a /dev/shm that refuses it: one line naming it, the size asked and what to do;
exit 1, nothing left in /dev/shm, no resource tracker's warnings, no SIGBUS.

A real small tmpfs (or a read-only one) is mounted over /dev/shm in a private mount namespace (``unshare -m``, as
root), for the command alone; where the machine does not allow one the tests say so and skip.
"""

import subprocess
import sys

import pytest
from conftest import ROOT
from ultraglide.render.engine.shm import LAYOUT

SEGMENT_BYTES = LAYOUT.size * 8  # what the engine asks of /dev/shm (581,872 bytes), far over a 64 KiB tmpfs


def _namespaces_allowed() -> bool:
    try:
        return subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c",
                               "mount -t tmpfs -o size=64k tmpfs /dev/shm"], capture_output=True,
                              timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


pytestmark = pytest.mark.skipif(not _namespaces_allowed(),
                                reason="needs a private mount namespace (unshare -m as root) to mount a small tmpfs "
                                       "over /dev/shm for one command")


def play_with_shm(options: str) -> tuple[subprocess.CompletedProcess, list[str]]:
    """``ultraglide play`` with a tmpfs of ``options`` over /dev/shm; its result and what /dev/shm held after."""
    script = (f"mount -t tmpfs -o {options} tmpfs /dev/shm || exit 99; "
              f"{sys.executable} -m ultraglide play grating-1mm --device null --duration-s 1 2>&1 >/dev/null; "
              "status=$?; echo '-- left:'; ls -A /dev/shm; exit $status")
    result = subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c", script], capture_output=True,
                            text=True, timeout=300, cwd=ROOT)
    said, _, left = result.stdout.partition("-- left:\n")
    return subprocess.CompletedProcess(result.args, result.returncode, said, result.stderr), left.split()


def test_a_full_dev_shm_is_one_line_naming_the_size_and_what_to_do():
    result, left = play_with_shm("size=64k")
    assert result.returncode == 1, result
    assert result.stdout.splitlines() == [result.stdout.strip()], result.stdout  # one line: no tracker, no traceback
    assert f"the engine's shared memory ({SEGMENT_BYTES:,} bytes) could not be made: no space left on device; " \
           "free space in /dev/shm" in result.stdout
    assert left == []


def test_a_read_only_dev_shm_is_one_line_and_no_resource_tracker_warnings():
    result, left = play_with_shm("ro,size=1m")
    assert result.returncode == 1, result
    assert result.stdout.splitlines() == [result.stdout.strip()], result.stdout
    assert "could not be made: read-only file system; /dev/shm is read-only: mount it writable" in result.stdout
    assert left == []
