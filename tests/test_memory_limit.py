"""Memory refused says memory: under an address-space limit (``ulimit -v``), export and play end in one line that
says memory ran out, the limit and what to do, not a library's misleading words (numba's llvmlite "literally cannot
be found"), with nothing written."""

import resource
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error

from ultraglide.errors import describe, out_of_memory

LIMIT_KIB = 300000


def limited(*args, cwd=ROOT):
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (LIMIT_KIB * 1024, LIMIT_KIB * 1024))

    return subprocess.run([sys.executable, "-m", "ultraglide", *map(str, args)], capture_output=True, text=True,
                          timeout=300, cwd=cwd, preexec_fn=limit)


@pytest.mark.parametrize("command", ["export", "play"])
def test_a_command_under_a_memory_limit_says_memory_ran_out(tmp_path, command):
    out = tmp_path / "out.wav"
    args = ("export", "grating-1mm", "-o", out, "--duration-s", "1") if command == "export" else \
        ("play", "grating-1mm", "--device", f"wav:{out}", "--duration-s", "1")
    result = limited(*args)
    line = assert_one_line_error(result)
    assert result.returncode == 1
    assert line.startswith(f"ultraglide {command}: error: out of memory: "), line
    assert f"(ulimit -v {LIMIT_KIB}): raise the limit or free memory" in line, line
    assert "literally" not in line
    assert list(tmp_path.iterdir()) == []


def test_numpys_memory_error_is_said_with_its_size():
    with pytest.raises(MemoryError) as caught:
        np.empty(2 ** 62, dtype=np.uint8)
    words = describe(caught.value)
    assert words.startswith("out of memory: Unable to allocate 4.00 EiB"), words
    assert out_of_memory(ValueError("a texture's width must be positive")) is None


def test_memory_refused_under_another_error_is_found_in_its_chain():
    try:
        try:
            raise OSError(12, "Cannot allocate memory")
        except OSError:
            raise RuntimeError("the kernel could not be compiled") from None
    except RuntimeError as error:
        assert out_of_memory(error) is None  # from None: nothing under it
    try:
        try:
            raise OSError(12, "Cannot allocate memory")
        except OSError as error:
            raise RuntimeError("the kernel could not be compiled") from error
    except RuntimeError as error:
        assert out_of_memory(error).startswith("out of memory: [Errno 12] Cannot allocate memory")
