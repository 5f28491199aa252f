#!/usr/bin/env bash
# Fuzz the firmware core with libFuzzer (a periodic check, not part of ./run tests):
#   scripts/fuzz_firmware.sh [SECONDS]      (default 600)
# Installs clang if it is missing, builds devices/firmware/fuzz/fuzz_core.c with
# -fsanitize=fuzzer,address,undefined into build/fuzz/, runs it for SECONDS on the corpus kept in
# build/fuzz/corpus (seeded from devices/firmware/fuzz/seeds), and prints one summary line: executions,
# coverage (libFuzzer's edges and features, and the core's lines the whole corpus runs, by llvm-cov), corpus
# size, crashes. A crash leaves its input in build/fuzz/ and exits 1.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
if ! command -v clang >/dev/null; then
    echo "fuzz_firmware: installing clang" >&2
    if [ "$(id -u)" -eq 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq clang >/dev/null
    else sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq clang >/dev/null; fi
fi
firmware=devices/firmware
out=build/fuzz
mkdir -p "$out/corpus"
cp -n "$firmware"/fuzz/seeds/* "$out/corpus/" 2>/dev/null || true
clang -std=c11 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
    -DUG_CONFORMANCE_BREAKS=0 -I"$firmware/include" -I"$firmware/core" -I"$firmware/ports/sim" \
    "$firmware"/core/ug_*.c "$firmware/ports/sim/ug_sim.c" "$firmware/fuzz/fuzz_core.c" -lm -o "$out/fuzz_core"
set +e
"$out/fuzz_core" -max_total_time="$seconds" -max_len=4096 -print_final_stats=1 -artifact_prefix="$out/" \
    "$out/corpus" > "$out/log.txt" 2>&1
status=$?
set -e
runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$out/log.txt" | grep -o '[0-9]*$' || echo 0)
last=$(grep -E '^#[0-9]+' "$out/log.txt" | tail -1)
cov=$(sed -n 's/.*cov: \([0-9]*\).*/\1/p' <<<"$last")
ft=$(sed -n 's/.*ft: \([0-9]*\).*/\1/p' <<<"$last")
corpus=$(find "$out/corpus" -type f | wc -l)
# the core's lines that the corpus runs (a build with clang's source-based coverage, the corpus replayed once)
clang -std=c11 -O1 -g -fsanitize=fuzzer -fprofile-instr-generate -fcoverage-mapping -DUG_CONFORMANCE_BREAKS=0 \
    -I"$firmware/include" -I"$firmware/core" -I"$firmware/ports/sim" \
    "$firmware"/core/ug_*.c "$firmware/ports/sim/ug_sim.c" "$firmware/fuzz/fuzz_core.c" -lm -o "$out/fuzz_coverage"
rm -f "$out/coverage.profraw"
LLVM_PROFILE_FILE="$out/coverage.profraw" "$out/fuzz_coverage" -runs=0 "$out/corpus" >/dev/null 2>&1 || true
llvm-profdata merge -sparse "$out/coverage.profraw" -o "$out/coverage.profdata"
lines=$(llvm-cov report "$out/fuzz_coverage" -instr-profile="$out/coverage.profdata" "$firmware"/core/*.c \
        | awk '/^TOTAL/ {print $(NF-3)}')
crashes=$(find "$out" -maxdepth 1 \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' \) | wc -l)
echo "fuzz_firmware: ${seconds} s, ${runs} executions, coverage ${cov} edges ${ft} features, the core's lines" \
     "${lines} run by the corpus of ${corpus} inputs, ${crashes} crashes (log: $out/log.txt)"
[ "$status" -eq 0 ] && [ "$crashes" -eq 0 ]
