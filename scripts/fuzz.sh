#!/usr/bin/env bash
# libFuzzer over the C++ core (test/fuzz/fuzz_pipeline.cpp; ASan + UBSan; clang):
#   bash scripts/fuzz.sh [RUNS]        RUNS mutated inputs after the corpus (default 100000)
# Builds build/fuzz, keeps the growing corpus in build/fuzz/corpus (seeded with random inputs made here), and
# writes a crashing, leaking, out-of-memory or slow input to build/fuzz/artifacts/ (then exits non-zero).
# Reproduce one:  build/fuzz/fuzz_pipeline build/fuzz/artifacts/crash-...
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
RUNS=${1:-100000}
case "$RUNS" in
  '' | *[!0-9]*)
    echo "usage: bash scripts/fuzz.sh [RUNS]: RUNS = '$RUNS' is not a whole number of inputs" >&2
    exit 2
    ;;
esac
for tool in clang clang++; do
  command -v "$tool" >/dev/null || { echo "fuzz.sh: $tool not found: apt-get install clang libclang-rt-14-dev libomp-14-dev" >&2; exit 2; }
done
if [ ! -f build/fuzz/Makefile ]; then
  CC=clang CXX=clang++ cmake -S test/fuzz -B build/fuzz >build/fuzz_configure.log 2>&1 ||
    { cat build/fuzz_configure.log; exit 1; }
fi
cmake --build build/fuzz -j"$(nproc)" >build/fuzz_build.log 2>&1 || { tail -30 build/fuzz_build.log; exit 1; }
mkdir -p build/fuzz/corpus build/fuzz/artifacts build/fuzz/seeds
if [ -z "$(ls -A build/fuzz/seeds)" ]; then
  # Random seeds of a few sizes: the decoder reads integers from the end and image rows from the start.
  /usr/bin/python3 - <<'PY'
import random
r = random.Random(20261122)
for i in range(64):
    n = r.choice([64, 256, 1024, 4096])
    with open(f"build/fuzz/seeds/seed{i:02d}", "wb") as f:
        f.write(bytes(r.getrandbits(8) for _ in range(n)))
PY
fi
# OpenMP threads that sleep at once when idle: the machine is shared.
export OMP_WAIT_POLICY=passive KMP_BLOCKTIME=0
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1} UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}
status=0
build/fuzz/fuzz_pipeline -runs="$RUNS" -seed=1 -max_len=4096 -len_control=0 -timeout=20 -rss_limit_mb=2048 \
  -print_final_stats=1 -artifact_prefix=build/fuzz/artifacts/ build/fuzz/corpus build/fuzz/seeds \
  >build/fuzz_run.log 2>&1 || status=$?
executed=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' build/fuzz_run.log | grep -oE '[0-9]+$' || echo "?")
if [ "$status" -ne 0 ]; then
  grep -E "FINDING|ERROR|SUMMARY|runtime error|Test unit written" build/fuzz_run.log | head -20
  echo "fuzz: FAILED after $executed inputs (exit $status); log build/fuzz_run.log, input in build/fuzz/artifacts/"
  exit 1
fi
echo "fuzz: $executed inputs, no finding ($(grep -oE 'cov: [0-9]+' build/fuzz_run.log | tail -1), corpus" \
  "$(find build/fuzz/corpus -type f | wc -l) files)"
