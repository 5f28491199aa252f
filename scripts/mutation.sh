#!/usr/bin/env bash
# Mutation testing of the signal path with mutmut 2 (a periodic check, not run in CI).
#   scripts/mutation.sh [FILE ...]     default: the envelope, renderer, drive limiter, texture sampling, carrier and
#                                      friction models (the signal path in Python; the numba kernels only on request)
# Works on a copy of the repository (mutmut 2 edits files in place), with the namespace laid out as one
# tree there (links in the copy's ultraglide/) so that the tests import the mutated copy. Each mutant
# runs only the quick tests of its file (scripts/mutmut_config.py, `-x`, numba's cache warm); a mutant
# that survives them runs again against every quick signal-path test ($MUTATION_TESTS). Prints the
# survivors, the score per file and overall (killed / total) and the seconds per mutant.
# MUTATION_SAMPLE=N tests N mutants drawn at random from each file instead (scripts/mutation_sample.py).
# MUTATION_QUICK=1 skips that second run (about half an hour less; survivors may then be killed elsewhere).
# MUTATION_WORKDIR=DIR keeps the copy (and mutmut's cache) in DIR: run again after adding tests and
# only the survivors are tested again. Runs under `nice -n 19`; run one at a time, and run no other mutmut
# command (not even `mutmut show`) in DIR while it runs: that breaks its cache ("Mutant.line is required").
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
files=("$@")
[ ${#files[@]} -gt 0 ] || files=(render/envelope.py render/renderer.py devices/output/limiter.py textures/sampling.py devices/output/carrier.py
                                  render/physics/model_base.py
                                  render/physics/paper_model.py render/physics/empirical_models.py
                                  render/physics/table_model.py)
# the second run's tests: the quick signal-path ones, without the real-time device and engine tests, which a
# process at nice 19 on a loaded machine starves (a missed watchdog deadline fails the baseline)
tests=${MUTATION_TESTS:-"tests/test_carrier.py tests/test_envelope.py tests/test_sampling.py tests/test_renderer.py \
tests/test_limiter.py tests/test_textures.py tests/test_effects.py tests/test_friction_models.py tests/test_doctests.py \
tests/test_export_parallel.py tests/test_api.py tests/test_block_path.py tests/test_calibration.py \
tests/test_friction_planning.py"}
[ -x .venv/bin/python ] || { echo "mutation.sh: no .venv here; run ./run tests first" >&2; exit 1; }
.venv/bin/python -c 'import mutmut' 2>/dev/null || .venv/bin/python -m pip install -q -e ".[mutation]"

if [ -n "${MUTATION_WORKDIR:-}" ]; then
    work=$(mkdir -p "$MUTATION_WORKDIR" && cd "$MUTATION_WORKDIR" && pwd)
else
    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
fi
# the tree as git sees it (committed or added), over any earlier copy; mutmut's cache stays
git ls-files -z | xargs -0 cp -P --parents -t "$work"  # -P: the tracked links (ultraglide/apps ...) as links
cp scripts/mutmut_config.py scripts/mutation_sample.py "$work/"
cp devices/firmware/_sil*.so "$work/devices/firmware/"  # the firmware core's binding, built, not tracked
for folder in render textures devices apps; do ln -sfn "$work/$folder" "$work/ultraglide/$folder"; done
cd "$work"
export PYTHONPATH="$work"   # the copy's ultraglide/, now holding the whole namespace, comes before the editable install
export NUMBA_CACHE_DIR="$work/.numba-cache"
"$root/.venv/bin/python" -c 'import ultraglide.render.envelope as m, sys; sys.exit(not m.__file__.startswith(sys.argv[1]))' "$work" \
    || { echo "mutation.sh: the tests would import the original tree, not the copy" >&2; exit 1; }
shopt -s nullglob  # a glob of no test files adds nothing
# shellcheck disable=SC2086  # $tests is a list of paths and globs
runner="$root/.venv/bin/python -m pytest -x -q -p no:cacheprovider -m 'not slow' $(echo $tests)"
paths=$(IFS=,; echo "${files[*]}")
rerun_all=--rerun-all
[ "${MUTATION_QUICK:-0}" = 1 ] && rerun_all=  # survivors of the file's own tests are not run against the rest
if [ -n "${MUTATION_SAMPLE:-}" ]; then  # a random sample of each file's mutants (scripts/mutation_sample.py)
    MUTATION_RUNNER="$runner" exec nice -n 19 "$root/.venv/bin/python" mutation_sample.py "${files[@]}"
fi
started=$(date +%s)
nice -n 19 "$root/.venv/bin/mutmut" run --paths-to-mutate "$paths" --runner "$runner" --tests-dir tests \
    ${rerun_all} --simple-output --no-progress || true
elapsed=$(( $(date +%s) - started ))
"$root/.venv/bin/mutmut" results || true
"$root/.venv/bin/python" - "$elapsed" "${files[@]}" <<'PY'
import sqlite3
import sys

elapsed, files = int(sys.argv[1]), sys.argv[2:]
db = sqlite3.connect(".mutmut-cache")
rows = db.execute("select SourceFile.filename, Mutant.status, count(*) from Mutant join Line on Mutant.line = Line.id "
                  "join SourceFile on Line.sourcefile = SourceFile.id group by 1, 2").fetchall()
killed_states = {"ok_killed", "ok_suspicious", "bad_timeout"}
total_killed = total = 0
for name in files:
    counts = {status: n for filename, status, n in rows if filename == name}
    killed = sum(n for status, n in counts.items() if status in killed_states)
    tested = sum(n for status, n in counts.items() if status not in ("skipped", "untested"))
    total_killed, total = total_killed + killed, total + tested
    print(f"{name}: {killed}/{tested} killed; by status {counts}")
print(f"mutation score: {total_killed}/{total} killed ({100 * total_killed / max(total, 1):.1f} %); "
      f"this run took {elapsed} s")
PY
