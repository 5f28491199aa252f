"""How long `import ultraglide` and `ultraglide --help` take, each in a fresh interpreter (aim: --help < 0.3 s).

Run: .venv/bin/python bench/bench_import.py [RUNS]
Prints the median and the fastest of RUNS runs (default 15) and the modules `import ultraglide` loads.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time

RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 15
AIM_S = 0.3


def timed(arguments: list[str]) -> float:
    started = time.perf_counter()
    subprocess.run(arguments, check=True, capture_output=True)
    return time.perf_counter() - started


def main() -> None:
    cases = {
        "python -c pass (the interpreter alone)": [sys.executable, "-c", "pass"],
        "import ultraglide": [sys.executable, "-c", "import ultraglide"],
        "ultraglide --help": [sys.executable, "-m", "ultraglide", "--help"],
        "ultraglide export --help": [sys.executable, "-m", "ultraglide", "export", "--help"],
    }
    for name, arguments in cases.items():
        times = [timed(arguments) for _ in range(RUNS)]
        verdict = ""
        if name == "ultraglide --help":
            verdict = "  (aim < 300 ms: " + ("met)" if statistics.median(times) < AIM_S else "MISSED)")
        print(f"{name:40s} median {statistics.median(times) * 1e3:6.0f} ms, fastest {min(times) * 1e3:6.0f} ms"
              + verdict)
    loaded = subprocess.run([sys.executable, "-c", "import sys, ultraglide; print(sorted(m for m in sys.modules "
                             "if m.startswith('ultraglide') or m in ('numpy', 'scipy', 'numba')))"],
                            check=True, capture_output=True, text=True).stdout.strip()
    print(f"modules of ours or heavy ones loaded by `import ultraglide`: {loaded}")


if __name__ == "__main__":
    main()
