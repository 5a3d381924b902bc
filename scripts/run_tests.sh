#!/usr/bin/env bash
# Runs every test of the package: C++ gtest (and rostest) through catkin, the core under ASan + UBSan, its
# threaded paths under TSan, a short libFuzzer run of the C++ entry point, the core's gtests cross-built for
# aarch64 under qemu (scripts/cross_aarch64.sh; the every-target tests on SVE and SVE2 too), then pytest.
# Expects the build from scripts/quickstart.sh; use 'bash scripts/quickstart.sh test' on a fresh machine.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
# shellcheck disable=SC1091
. ./env.sh
ROS_HOME=$(mktemp -d /tmp/kp-ros-home.XXXXXX)
export ROS_HOME
trap 'rm -rf "$ROS_HOME"' EXIT

echo "== C++ tests (catkin run_tests) =="
rm -rf build/cmake/test_results
# A re-configure (CMakeLists.txt changed) must not see the sourced devel space in CMAKE_PREFIX_PATH: catkin would
# chain the install space onto it (test/python/test_install_space.py checks that it does not).
env -u CMAKE_PREFIX_PATH cmake --build build/cmake --target tests -j"$(nproc)" >/dev/null
# 'make run_tests' exits 0 even when tests fail: catkin_test_results decides.
cmake --build build/cmake --target run_tests -- --no-print-directory >build/run_tests.log 2>&1 || true
grep -E "^\[  (PASSED|FAILED) \]|^\[==========\]|Failure" build/run_tests.log || true
cpp_status=0
catkin_test_results build/cmake/test_results || cpp_status=$?
echo "== C++ core under AddressSanitizer + UndefinedBehaviorSanitizer =="
san_status=0
rm -f build/asan_results.xml
if [ ! -f build/asan/Makefile ]; then
  cmake -S test/sanitize -B build/asan >build/asan_configure.log 2>&1 || { cat build/asan_configure.log; san_status=1; }
fi
if [ "$san_status" -eq 0 ]; then
  cmake --build build/asan -j"$(nproc)" >build/asan_build.log 2>&1 || { tail -30 build/asan_build.log; san_status=1; }
fi
if [ "$san_status" -eq 0 ]; then
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
    build/asan/test_core_asan --gtest_output=xml:build/asan_results.xml >build/asan_run.log 2>&1 || san_status=$?
  tail -3 build/asan_run.log
  [ "$san_status" -eq 0 ] || grep -E "ERROR|runtime error|FAILED" build/asan_run.log | head -20
fi

# OpenMP threads that sleep at once when idle (the sanitizer runs share a small machine).
export OMP_WAIT_POLICY=passive KMP_BLOCKTIME=0
echo "== threaded paths under ThreadSanitizer (clang, LLVM libomp + Archer) =="
tsan_status=0
rm -f build/tsan_results.xml
if ! command -v clang++ >/dev/null; then
  echo "clang++ not found: apt-get install clang libomp-14-dev libclang-rt-14-dev (scripts/quickstart.sh does)"
  tsan_status=1
fi
if [ "$tsan_status" -eq 0 ] && [ ! -f build/tsan/Makefile ]; then
  CC=clang CXX=clang++ cmake -S test/sanitize -B build/tsan -DKP_SANITIZER=thread >build/tsan_configure.log 2>&1 ||
    { cat build/tsan_configure.log; tsan_status=1; }
fi
if [ "$tsan_status" -eq 0 ]; then
  cmake --build build/tsan -j"$(nproc)" >build/tsan_build.log 2>&1 || { tail -30 build/tsan_build.log; tsan_status=1; }
fi
if [ "$tsan_status" -eq 0 ]; then
  # libomp is not instrumented: Archer (loaded by libomp under TSan) supplies OpenMP's synchronisation, and
  # ignore_noninstrumented_modules stops reports about memory touched inside libomp / OpenCV's TBB themselves
  # (what LLVM's Archer asks for). Any report makes the run exit 66.
  export TSAN_OPTIONS="ignore_noninstrumented_modules=1 exitcode=66 second_deadlock_stack=1"
  build/tsan/test_core_tsan --gtest_filter='-*RaceCanary*' --gtest_output=xml:build/tsan_results.xml \
    >build/tsan_run.log 2>&1 || tsan_status=$?
  grep -E "^\[ info \]|PASSED|FAILED" build/tsan_run.log || true
  [ "$tsan_status" -eq 0 ] || grep -E "WARNING: ThreadSanitizer|SUMMARY|FAILED" build/tsan_run.log | head -20
  # The planted race must be reported, or this run proves nothing.
  if build/tsan/test_core_tsan --gtest_filter='Threads.DISABLED_RaceCanary' --gtest_also_run_disabled_tests \
    >build/tsan_canary.log 2>&1 || ! grep -q "WARNING: ThreadSanitizer: data race" build/tsan_canary.log; then
    echo "TSan did not report the planted race (Threads.DISABLED_RaceCanary): the TSan set-up hides races"
    tsan_status=1
  else
    echo "TSan reported the planted race, as it must"
  fi
  unset TSAN_OPTIONS
fi

echo "== C++ entry point under libFuzzer (short run; 'bash scripts/fuzz.sh' runs 100000) =="
fuzz_status=0
bash scripts/fuzz.sh "${KP_FUZZ_RUNS:-3000}" || fuzz_status=$?
rm -f build/fuzz_results.xml
/usr/bin/python3 - "$fuzz_status" <<'PY'
import sys
from xml.sax.saxutils import escape
ok = sys.argv[1] == "0"
log = open("build/fuzz_run.log", errors="replace").read()[-4000:] if not ok else ""
body = "" if ok else f'<failure message="libFuzzer finding">{escape(log)}</failure>'
with open("build/fuzz_results.xml", "w") as f:
    f.write(f'<testsuites><testsuite name="libfuzzer" tests="1"><testcase name="fuzz_pipeline" classname="fuzz">'
            f'{body}</testcase></testsuite></testsuites>')
PY

echo "== the core and its gtests cross-built for aarch64, under qemu (NEON and scalar targets) =="
arm_status=0
rm -f build/aarch64/test_core.xml
bash scripts/cross_aarch64.sh >build/aarch64_run.log 2>&1 || arm_status=$?
grep -E "^== times|SIMD targets run|tests from .* ran|PASSED|FAILED" build/aarch64_run.log | sort -u | head -20
[ "$arm_status" -eq 0 ] || tail -40 build/aarch64_run.log

# qemu's SVE is slow: only the tests that hold every target to the plain loops, on an emulated CPU with SVE and SVE2,
# at three vector lengths: 512 bits (qemu's default), 256 and 128 (where Highway picks SVE2_128: Grace, Graviton4).
echo "== the every-target gtests for aarch64 under qemu -cpu max (SVE2, SVE, NEON and scalar; 512, 256, 128 bits) =="
sve_status=0
rm -f build/aarch64/test_core_sve*.xml
if [ "$arm_status" -eq 0 ]; then
  # qemu -cpu, the XML's name, the targets the run must have run (a run that never reached SVE would pass on NEON).
  for run in "max sve sve2, sve, neon, scalar" \
             "max,sve-default-vector-length=32 sve256 sve2, sve, neon, scalar" \
             "max,sve-default-vector-length=16 sve128 sve2_128, sve2, sve, neon, scalar"; do
    read -r cpu name targets <<<"$run"
    status=0
    bash scripts/cross_aarch64.sh --no-install --qemu-cpu "$cpu" -- --gtest_filter='*EveryTarget*:ScanPull*' \
      --gtest_output=xml:build/aarch64/test_core_$name.xml >build/aarch64_$name.log 2>&1 || status=$?
    echo "-- qemu -cpu $cpu:"
    grep -E "SIMD targets run|tests from .* ran|PASSED|FAILED" build/aarch64_$name.log | sort -u | head -10
    if [ "$status" -eq 0 ] && ! grep -q "SIMD targets run: $targets\$" build/aarch64_$name.log; then
      echo "the run did not run the targets $targets (build/aarch64_$name.log)"
      status=1
    fi
    [ "$status" -eq 0 ] || { tail -40 build/aarch64_$name.log; sve_status=1; }
  done
else
  echo "skipped: the aarch64 build above failed"
fi

echo "== Python tests (pytest) =="
py_status=0
python3 -m pytest test/python -q -p no:cacheprovider --junitxml=build/pytest.xml || py_status=$?
# One closing line over every JUnit file (catkin_test_results counts gtest suites twice).
read -r passed failed skipped cpp_total py_total <<<"$(python3 - <<'PY'
import glob
import xml.etree.ElementTree as ET
counts = {"passed": 0, "failed": 0, "skipped": 0}
totals = {"cpp": 0, "py": 0}
sanitizers = ["build/asan_results.xml", "build/tsan_results.xml", "build/fuzz_results.xml", "build/aarch64/test_core.xml",
              "build/aarch64/test_core_sve.xml", "build/aarch64/test_core_sve256.xml",
              "build/aarch64/test_core_sve128.xml"]
for path in glob.glob("build/cmake/test_results/**/*.xml", recursive=True) + sanitizers + ["build/pytest.xml"]:
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        continue
    for case in root.iter("testcase"):
        totals["py" if path.endswith("pytest.xml") else "cpp"] += 1
        if case.find("failure") is not None or case.find("error") is not None:
            counts["failed"] += 1
        elif case.find("skipped") is not None or case.get("status") == "notrun":
            counts["skipped"] += 1
        else:
            counts["passed"] += 1
print(counts["passed"], counts["failed"], counts["skipped"], totals["cpp"], totals["py"])
PY
)"
echo "kinect_pipeline: $passed passed, $failed failed, $skipped skipped"
if [ "$cpp_status" -ne 0 ] || [ "$san_status" -ne 0 ] || [ "$tsan_status" -ne 0 ] || [ "$fuzz_status" -ne 0 ] || [ "$arm_status" -ne 0 ] || [ "$sve_status" -ne 0 ] || [ "$py_status" -ne 0 ] || [ "$failed" -ne 0 ] || [ "$cpp_total" -eq 0 ] || [ "$py_total" -eq 0 ]; then
  exit 1
fi
