"""A sampled mutation score: a random sample of each file's mutmut mutants, run as scripts/mutation.sh runs them.

Run through ``MUTATION_SAMPLE=N scripts/mutation.sh [FILE ...]`` (it works in the script's copy of the tree, where
the tests import the mutated files). mutmut 2 lists every mutant of each file (the same list ``mutmut run`` would
test); ``N`` of them per file are drawn at random (seed ``MUTATION_SEED``, default 0), each applied in turn to the
copy and run against its file's quick tests (``scripts/mutmut_config.py``, ``-x``); a survivor runs again against
every quick signal-path test unless ``MUTATION_QUICK=1``. Prints each file's killed / sampled with a 95 % Wilson
interval for its whole score, the survivors (line and mutated text), and the total. A whole run of the signal
path is ~1 200 mutants and hours on two cores; 30 a file is minutes, and its interval says how far to trust it.
"""

from __future__ import annotations

import math
import os
import random
import shlex
import subprocess
import sys
import time

import mutmut
import mutmut_config

Z_95 = 1.959964


def wilson(killed: int, total: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of a proportion (fractions)."""
    if total == 0:
        return 0.0, 1.0
    p = killed / total
    centre = (p + Z_95 ** 2 / (2 * total)) / (1 + Z_95 ** 2 / total)
    half = Z_95 * math.sqrt(p * (1 - p) / total + Z_95 ** 2 / (4 * total ** 2)) / (1 + Z_95 ** 2 / total)
    return max(0.0, centre - half), min(1.0, centre + half)


def stratified(strata: list[tuple[int, int, int]]) -> tuple[float, float]:
    """The whole score from per-file samples, each file weighted by its mutants, and the half-width of its 95 %
    interval (normal approximation, each file's variance from its Agresti-Coull proportion, (k + 2) / (m + 4), so a
    file whose sample all died still counts its doubt, with the finite-population correction).

    >>> stratified([(100, 9, 10), (300, 30, 30)])[0]
    0.975
    """
    everyone = sum(n for n, _, _ in strata)
    score = sum(n * k / m for n, k, m in strata if m) / everyone
    variance = sum((n / everyone) ** 2 * (k + 2) / (m + 4) * (m + 2 - k) / (m + 4) / m * (1 - (m - 1) / n)
                   for n, k, m in strata if m)
    return score, Z_95 * math.sqrt(variance)


def killed_by(command: list[str], timeout_s: float) -> bool:
    """Whether the tests fail with the mutant in place (a timeout counts as killed, as mutmut counts it)."""
    try:
        result = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return True
    if result.returncode == 5:  # pytest collected nothing: the command is wrong, not the mutant caught
        raise SystemExit(f"mutation_sample: no tests collected by {shlex.join(command)}")
    return result.returncode != 0


def baseline_s(command: list[str]) -> float:
    """How long the tests take without a mutant (s); a second try before giving up, as a loaded machine can fail
    a timing test once."""
    for _ in range(2):
        started = time.monotonic()
        if subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode == 0:
            return time.monotonic() - started
    raise SystemExit(f"mutation_sample: the tests fail without a mutant, twice: {shlex.join(command)}")


def main() -> int:
    per_file = int(os.environ.get("MUTATION_SAMPLE", "30"))
    rng = random.Random(int(os.environ.get("MUTATION_SEED", "0")))
    quick = os.environ.get("MUTATION_QUICK", "0") == "1"
    files, broad = sys.argv[1:], shlex.split(os.environ.get("MUTATION_RUNNER", ""))
    started = time.monotonic()
    strata = []  # (mutants, killed, sampled) per file
    for filename in files:
        with open(filename, encoding="utf-8") as handle:
            original = handle.read()
        everyone = mutmut.list_mutations(mutmut.Context(source=original, filename=filename))
        sample = rng.sample(everyone, min(per_file, len(everyone)))
        own = mutmut_config.PYTEST + mutmut_config.tests_for(filename)
        timeout_s = 10 * baseline_s(own) + 30
        killed, survivors = 0, []
        try:
            for mutation_id in sample:
                mutated, _ = mutmut.mutate(mutmut.Context(source=original, filename=filename,
                                                          mutation_id=mutation_id))
                with open(filename, "w", encoding="utf-8") as handle:
                    handle.write(mutated)
                caught = killed_by(own, timeout_s) or (not quick and broad and killed_by(broad, 10 * timeout_s))
                killed += caught
                if not caught:
                    line = mutated.split("\n")[mutation_id.line_number].strip()
                    survivors.append(f"  line {mutation_id.line_number + 1}: {mutation_id.line.strip()}  ->  {line}")
        finally:
            with open(filename, "w", encoding="utf-8") as handle:
                handle.write(original)
        low, high = wilson(killed, len(sample))
        print(f"{filename}: {killed}/{len(sample)} killed of {len(everyone)} mutants sampled "
              f"(score 95 % interval {100 * low:.0f}-{100 * high:.0f} %)")
        print("\n".join(survivors) if survivors else "  no survivor")
        strata.append((len(everyone), killed, len(sample)))
    score, half = stratified(strata)
    print(f"sampled mutation score of all {sum(n for n, _, _ in strata)} mutants: {100 * score:.1f} % "
          f"(95 % interval {100 * max(0.0, score - half):.1f}-{100 * min(1.0, score + half):.1f} %), "
          f"{sum(k for _, k, _ in strata)}/{sum(m for _, _, m in strata)} sampled killed; "
          f"{time.monotonic() - started:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
