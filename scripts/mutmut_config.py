"""mutmut 2's hook for scripts/mutation.sh: each mutant runs only the quick tests that exercise its file.

mutmut imports this module from the directory it runs in (the temporary copy). Before each mutant,
``pre_mutation`` swaps the test command for the file's own tests, the quickest killers first, with
``-x`` so the first failure ends the run; a mutant that survives them is run again against the
broader default command (``--rerun-all``), so a survivor is one the whole signal-path suite misses.
"""

from __future__ import annotations

import os
import shlex
import sys

PYTEST = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-m", "not slow"]

# per mutated file: the tests that exercise it, quickest and most telling first
TESTS = {
    "render/envelope.py": ["tests/test_envelope.py", "tests/test_renderer.py"],
    "render/renderer.py": ["tests/test_renderer.py", "tests/test_envelope.py",
                           "tests/test_doctests.py::test_docstring_examples[ultraglide.render.renderer]",
                           "tests/test_effects.py", "tests/test_friction_planning.py"],
    "devices/output/limiter.py": ["tests/test_limiter.py",
                           "tests/test_doctests.py::test_docstring_examples[ultraglide.devices.output.limiter]"],
    "textures/sampling.py": ["tests/test_sampling.py",
                             "tests/test_doctests.py::test_docstring_examples[ultraglide.textures.sampling]",
                             "tests/test_textures.py"],
    "devices/output/carrier.py": ["tests/test_carrier.py", "tests/test_renderer.py",
                                  "tests/test_block_path.py"],
    "render/physics/model_base.py": ["tests/test_friction_models.py",
                                     "tests/test_doctests.py::test_docstring_examples[ultraglide.render.physics.friction_models]",
                                     "tests/test_calibration.py"],
    "render/physics/paper_model.py": ["tests/test_friction_models.py",
                                      "tests/test_doctests.py::test_docstring_examples[ultraglide.render.physics.friction_models]",
                                      "tests/test_calibration.py"],
    "render/physics/empirical_models.py": ["tests/test_friction_models.py",
                                           "tests/test_doctests.py::test_docstring_examples[ultraglide.render.physics.friction_models]",
                                           "tests/test_calibration.py"],
    "render/physics/table_model.py": ["tests/test_friction_models.py",
                                      "tests/test_doctests.py::test_docstring_examples[ultraglide.render.physics.friction_models]",
                                      "tests/test_calibration.py"],
    "devices/counter_check.py": ["tests/test_counter_check.py",
                                 "tests/test_doctests.py::test_docstring_examples[ultraglide.devices.counter_check]"],
}


def tests_for(filename: str) -> list[str]:
    """The test files (or node ids) for a mutated file; ones not (yet) in the tree are left out, since
    pytest fails on a missing file and the mutant would count as killed."""
    chosen = TESTS.get(os.path.relpath(filename), [])
    return [test for test in chosen if os.path.exists(test.split("::")[0])]


def pre_mutation(context) -> None:
    tests = tests_for(context.filename)
    if tests:
        context.config.test_command = shlex.join(PYTEST + tests)
