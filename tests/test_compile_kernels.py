"""``python -m ultraglide.compile_kernels`` (what ``./run`` calls after installing) leaves no kernel for a later
process to compile: checked in a fresh interpreter, which has compiled nothing before, and against the sources."""

import json
import re
import subprocess
import sys

from conftest import ROOT

from ultraglide.compile_kernels import KERNEL_MODULES


def test_every_module_that_defines_a_kernel_is_compiled_at_install():
    defining = set()
    for folder in ("render", "devices", "textures", "apps", "ultraglide"):
        for path in (ROOT / folder).rglob("*.py"):
            if re.search(r"^@(numba\.)?n?jit\b", path.read_text(encoding="utf-8"), re.MULTILINE):
                module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
                defining.add(module if module.startswith("ultraglide.") else f"ultraglide.{module}")
    assert defining == set(KERNEL_MODULES)


def test_after_compiling_every_kernel_called_from_python_has_its_compiled_version():
    script = ("import json; from ultraglide.compile_kernels import compile_all, kernels, uncompiled\n"
              "before = sum(bool(kernel.signatures) for kernel in kernels().values())\n"
              "count = compile_all()\n"
              "print(json.dumps({'before': before, 'count': count, 'uncompiled': uncompiled()}))")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["before"] == 0  # a fresh process: importing compiles nothing
    assert report["count"] >= 30 and report["uncompiled"] == []


def test_the_command_says_how_many_kernels_it_compiled():
    result = subprocess.run([sys.executable, "-m", "ultraglide.compile_kernels"], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    assert re.fullmatch(r"\d+ compiled kernels in numba's cache \(\d+\.\d s\)\n", result.stdout)
