#!/usr/bin/env bash
# Mutation testing of the signal path with mutmut (a periodic check, not run in CI).
#   scripts/mutation.sh [FILE ...]     default: the envelope, renderer, drive limiter and texture sampling
# Works on a copy of the repository in a temporary directory (mutmut 2 edits files in place), with the
# namespace laid out as one tree there (links in the copy's ultraglide/) so that the tests import the mutated copy; prints mutmut's
# results and the score (killed / total). Needs .venv (./run tests) and installs mutmut 2 into it.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
files=("$@")
[ ${#files[@]} -gt 0 ] || files=(render/envelope.py render/renderer.py devices/limiter.py textures/sampling.py)
tests=${MUTATION_TESTS:-"tests/test_renderer.py tests/test_blind_spots.py tests/test_limiter.py tests/test_textures.py"}
.venv/bin/python -c 'import mutmut' 2>/dev/null || .venv/bin/python -m pip install -q "mutmut>=2.5,<3"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
git ls-files -z | xargs -0 cp --parents -t "$work"
for folder in render textures devices apps; do ln -s "$work/$folder" "$work/ultraglide/$folder"; done
cd "$work"
export PYTHONPATH="$work"   # the copy's ultraglide/, now holding the whole namespace, comes before the editable install
export NUMBA_CACHE_DIR="$work/.numba-cache"
runner="$root/.venv/bin/python -m pytest -x -q -p no:cacheprovider -m 'not slow' $tests"
paths=$(IFS=,; echo "${files[*]}")
"$root/.venv/bin/python" -c 'import ultraglide.render.envelope as m, sys; sys.exit(not m.__file__.startswith(sys.argv[1]))' "$work" \
    || { echo "mutation.sh: the tests would import the original tree, not the copy" >&2; exit 1; }
"$root/.venv/bin/mutmut" run --paths-to-mutate "$paths" --runner "$runner" --tests-dir tests --no-progress || true
"$root/.venv/bin/mutmut" results || true
"$root/.venv/bin/python" - <<'PY'
import sqlite3
rows = dict(sqlite3.connect(".mutmut-cache").execute("select status, count(*) from Mutant group by status").fetchall())
killed = rows.get("ok_killed", 0) + rows.get("bad_timeout", 0)
total = sum(rows.values()) - rows.get("skipped", 0)
print(f"mutation score: {killed}/{total} killed ({100 * killed / max(total, 1):.0f} %); by status: {rows}")
PY
