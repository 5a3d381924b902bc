#!/usr/bin/env bash
# Runs every test of the package: C++ gtest (and rostest) through catkin, then pytest.
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
cmake --build build/cmake --target tests -j"$(nproc)" >/dev/null
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

echo "== Python tests (pytest) =="
py_status=0
python3 -m pytest test/python -q -p no:cacheprovider --junitxml=build/pytest.xml || py_status=$?
# One closing line over every JUnit file (catkin_test_results counts gtest suites twice).
read -r passed failed skipped cpp_total py_total <<<"$(python3 - <<'PY'
import glob
import xml.etree.ElementTree as ET
counts = {"passed": 0, "failed": 0, "skipped": 0}
totals = {"cpp": 0, "py": 0}
for path in glob.glob("build/cmake/test_results/**/*.xml", recursive=True) + ["build/asan_results.xml", "build/pytest.xml"]:
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
if [ "$cpp_status" -ne 0 ] || [ "$san_status" -ne 0 ] || [ "$py_status" -ne 0 ] || [ "$failed" -ne 0 ] || [ "$cpp_total" -eq 0 ] || [ "$py_total" -eq 0 ]; then
  exit 1
fi
