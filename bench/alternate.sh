#!/usr/bin/env bash
# Compares core libraries in alternating runs of one bench binary (this machine's speed drifts by tens of percent
# over minutes: runs side by side meet the same minutes). Each LIBDIR holds a libkinect_pipeline_core.so, e.g. a
# copy of build/devel/lib/libkinect_pipeline_core.so made at another commit; the bench's RUNPATH gives way to
# LD_LIBRARY_PATH. A LIBDIR that also holds a kinect_pipeline_bench runs that one: a bench binary is compiled
# against its library's headers, and a library whose classes changed layout (e.g. Pipeline's members) needs the
# bench built with it (the same bench_core.cpp; the times it prints are measured inside the library).
#   bench/alternate.sh ROUNDS LIBDIR...      env: ENC (8UC1), THR (1), FRAMES (400), SIMD (native: one target),
#                                             ROLL (0 [rad]), BENCH (the built bench)
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 ROUNDS LIBDIR... (ROUNDS >= 1; each LIBDIR holds a libkinect_pipeline_core.so)" >&2
  exit 2
fi
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BENCH=${BENCH:-$ROOT/build/devel/lib/kinect_pipeline/kinect_pipeline_bench}
ENC=${ENC:-8UC1} THR=${THR:-1} FRAMES=${FRAMES:-400} SIMD=${SIMD:-native} ROLL=${ROLL:-0}
[[ "$ENC" =~ ^(8UC1|16UC1|32FC1)$ && "$THR" =~ ^[1-9][0-9]*$ && "$SIMD" != *,* ]] ||
  { echo "$0: ENC '$ENC', THR '$THR', SIMD '$SIMD': expected one encoding, one thread count, one target" >&2; exit 2; }
EXTRA=()  # only where asked: benches built before --simd and --roll existed run as before
[ "$SIMD" = native ] || EXTRA+=(--simd "$SIMD")
[ "$ROLL" = 0 ] || EXTRA+=(--roll "$ROLL")
ROUNDS=$1
shift
[[ "$ROUNDS" =~ ^[1-9][0-9]*$ ]] || { echo "$0: ROUNDS '$ROUNDS': expected a whole number >= 1" >&2; exit 2; }
[ -x "$BENCH" ] || { echo "$0: bench '$BENCH' not found: build first (bash scripts/quickstart.sh build)" >&2; exit 2; }
for d in "$@"; do
  [ -f "$d/libkinect_pipeline_core.so" ] || { echo "$0: '$d' holds no libkinect_pipeline_core.so" >&2; exit 2; }
done
for i in $(seq "$ROUNDS"); do
  echo "round $i/$ROUNDS" >&2
  for d in "$@"; do
    bench=$BENCH
    [ -x "$d/kinect_pipeline_bench" ] && bench=$d/kinect_pipeline_bench
    # The markdown table's columns by their names (the plain table's position of a column moves when one is added).
    LD_LIBRARY_PATH=$d "$bench" --frames "$FRAMES" --threads "$THR" --encodings "$ENC" "${EXTRA[@]}" --markdown |
      awk -F' *[|] *' -v d="$d" '
        $2 == "encoding" { for (i = 1; i <= NF; i++) { if ($i == "frame [ms]") f = i; if ($i == "frame / memcpy") x = i } }
        $2 ~ /^(8UC1|16UC1|32FC1)$/ { if (!f || !x) { print "alternate.sh: no frame columns in the bench output" > "/dev/stderr"; exit 1 }
                                      print d, $f, $x }'
  done
done | /usr/bin/python3 -c '
import collections, statistics, sys
t, r = collections.defaultdict(list), collections.defaultdict(list)
for line in sys.stdin:
    d, f, x = line.split()
    t[d].append(float(f))
    r[d].append(float(x))
for d in t:
    print("%s: frame median %.4f ms (runs %.4f-%.4f), x memcpy median %.1f, %d runs"
          % (d, statistics.median(t[d]), min(t[d]), max(t[d]), statistics.median(r[d]), len(t[d])))
'
