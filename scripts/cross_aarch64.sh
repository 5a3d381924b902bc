#!/usr/bin/env bash
# Cross-builds the ROS-free core, the offline tools and the core's gtests (test/core) for aarch64 and runs the
# gtests under qemu-user, on an x86-64 Debian 12 host. For CI; idempotent (a second run installs nothing,
# fetches nothing and rebuilds only what changed).
#
#   bash scripts/cross_aarch64.sh [--no-install] [--jobs N] [-- gtest arguments...]
#
#   --no-install  no apt at all: use what is installed and the sysroot already in build/aarch64-sysroot (or
#                 arm64 packages installed by multiarch)
#   --jobs N      parallel compiles (default 2; they run under nice -n 19)
#   --qemu-cpu CPU
#                 qemu's -cpu (default 'max,sve=off': an ARMv8 CPU without SVE, so the tests run the NEON and
#                 scalar targets, in about 90 s); 'max' has SVE and SVE2 too, and the tests run those targets as
#                 well (qemu emulates SVE about 8x slower: about 15 min; the test command runs only the
#                 every-target tests there, '*EveryTarget*', about 30 s). Every target is compiled either way.
#
# What it does:
#   1. apt (as root): the host's cross tools: g++-aarch64-linux-gnu (brings libgomp and libstdc++ for aarch64),
#      qemu-user-static, googletest (sources in /usr/src/googletest, built with the cross compiler), cmake.
#   2. The target's libraries, OpenCV core/imgproc/imgcodecs and Highway, as arm64 .debs unpacked into
#      build/aarch64-sysroot/root (dpkg --add-architecture arm64; apt-get download; dpkg-deb -x), with only
#      the shared libraries they need at run time (followed by ELF DT_NEEDED). Not installed by multiarch:
#      libopencv-imgcodecs406:arm64 needs libgdal32:arm64, which is not Multi-Arch: same, so apt would remove
#      the host's (amd64) libopencv-dev, cv_bridge and python3-opencv to install it.
#   3. cmake -S test/cross -B build/aarch64 with cmake/aarch64-toolchain.cmake, and the build.
#   4. build/aarch64/test_core under qemu-aarch64 -L /usr/aarch64-linux-gnu; the XML report in
#      build/aarch64/test_core.xml.
# Exits non-zero on the first failure, a failed test included.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"

INSTALL=1
JOBS=2
QEMU_CPU_ARG=(-cpu 'max,sve=off')
GTEST_ARGS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --no-install) INSTALL=0 ;;
    --jobs) JOBS=$2; shift ;;
    --jobs=*) JOBS=${1#--jobs=} ;;
    --qemu-cpu) QEMU_CPU_ARG=(-cpu "$2"); shift ;;
    --qemu-cpu=*) QEMU_CPU_ARG=(-cpu "${1#--qemu-cpu=}") ;;
    --) shift; GTEST_ARGS=("$@"); break ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "cross_aarch64.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done

TRIPLE=aarch64-linux-gnu
BUILD=$ROOT/build/aarch64
SYSROOT_BASE=$ROOT/build/aarch64-sysroot
SYSROOT=$SYSROOT_BASE/root
# The arm64 packages the core builds against; their run-time libraries are followed from these.
TARGET_PACKAGES=(libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libhwy-dev)
HOST_PACKAGES=(g++-aarch64-linux-gnu qemu-user-static googletest cmake make binutils python3)

run() {
  echo "+ $*"
  "$@"
}
step() {
  echo
  echo "== $* =="
}
T0=$SECONDS
declare -A TIMES=()

# ---------------------------------------------------------------- 1. host packages
if [ "$INSTALL" -eq 1 ]; then
  step "install (apt)"
  t=$SECONDS
  if [ "$(id -u)" -ne 0 ]; then
    echo "cross_aarch64.sh: apt needs root (run as root, or with --no-install once the packages are there)" >&2
    exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then
    run dpkg --add-architecture arm64
  fi
  missing=()
  for p in "${HOST_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  # The arm64 package lists: fetched once after the architecture was added.
  if [ ${#missing[@]} -gt 0 ] || ! apt-cache show libhwy-dev:arm64 >/dev/null 2>&1; then
    run apt-get update -q
  fi
  if [ ${#missing[@]} -gt 0 ]; then
    run apt-get install -y -q --no-install-recommends "${missing[@]}"
  else
    echo "host packages present: ${HOST_PACKAGES[*]}"
  fi
  TIMES[install]=$((SECONDS - t))

  # -------------------------------------------------------------- 2. the target's sysroot (arm64 .debs, unpacked)
  step "arm64 sysroot ($SYSROOT)"
  t=$SECONDS
  stamp="${TARGET_PACKAGES[*]} $(apt-cache policy "${TARGET_PACKAGES[@]/%/:arm64}" | grep Candidate | tr -d ' \n')"
  if [ -f "$SYSROOT/.kp_stamp" ] && [ "$(cat "$SYSROOT/.kp_stamp")" = "$stamp" ]; then
    echo "up to date: $(wc -l <"$SYSROOT/.kp_packages") packages ($SYSROOT/.kp_packages)"
  else
    rm -rf "$SYSROOT"
    mkdir -p "$SYSROOT" "$SYSROOT_BASE/debs"
    # Fetches the -dev packages and their direct dependencies, then, for every shared library in the sysroot,
    # a dependency that holds each DT_NEEDED library that neither the sysroot nor the cross toolchain
    # (/usr/aarch64-linux-gnu/lib: libc, libstdc++, libgcc_s, libgomp) has. Packages that hold none are dropped.
    run python3 - "$SYSROOT" "$SYSROOT_BASE/debs" "/usr/$TRIPLE/lib" "${TARGET_PACKAGES[@]}" <<'PY'
import os, re, shutil, subprocess, sys

sysroot, debdir, toolchain_lib, seeds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
ARCH, TRIPLE = "arm64", "aarch64-linux-gnu"
SKIP = {"libc6", "libgcc-s1", "libstdc++6", "libgomp1", "libatomic1", "libc6-dev", "libc-dev-bin",
        "linux-libc-dev", "libcrypt-dev", "libnsl-dev", "libtirpc-dev", "rpcsvc-proto"}
LIBDIRS = ["usr/lib/" + TRIPLE, "lib/" + TRIPLE]
SO = re.compile(r"\.so(\.\d+)*$")

def sonames_in(top):
    """Shared-library file names (links included) under top's library folders: name -> path."""
    found = {}
    for d in LIBDIRS + ["usr/lib", "lib"]:
        base = os.path.join(top, d)
        if not os.path.isdir(base):
            continue
        for dirpath, _, files in os.walk(base):
            for f in files:
                if SO.search(f):
                    found.setdefault(f, os.path.join(dirpath, f))
    return found

def needed(path):
    if os.path.islink(path) or not os.path.isfile(path):
        return set()
    out = subprocess.run(["readelf", "-d", path], capture_output=True, text=True).stdout
    return set(re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", out))

def depends(pkg):
    out = subprocess.run(["apt-cache", "depends", "--no-recommends", "--no-suggests", "--no-conflicts",
                          "--no-breaks", "--no-replaces", "--no-enhances", pkg + ":" + ARCH],
                         capture_output=True, text=True, check=True).stdout
    deps = []
    for line in out.splitlines():
        m = re.match(r"^\s*\|?(?:Pre)?Depends: ([^<>\s]+):" + ARCH + r"$", line)  # arch all and virtual: skipped
        if m and m.group(1) not in SKIP and m.group(1) not in deps:
            deps.append(m.group(1))
    return deps

def fetch(pkg):
    """Downloads (once) and unpacks pkg into a folder of its own; returns that folder."""
    debs = [f for f in os.listdir(debdir) if f.startswith(pkg + "_") and f.endswith("_" + ARCH + ".deb")]
    if not debs:
        subprocess.run(["apt-get", "download", "-q", "-o", "APT::Sandbox::User=root", pkg + ":" + ARCH], cwd=debdir, check=True,
                       stdout=subprocess.DEVNULL)
        debs = [f for f in os.listdir(debdir) if f.startswith(pkg + "_") and f.endswith("_" + ARCH + ".deb")]
    deb = os.path.join(debdir, sorted(debs)[-1])
    x = os.path.join(debdir, "x", pkg)
    shutil.rmtree(x, ignore_errors=True)
    os.makedirs(x)
    subprocess.run(["dpkg-deb", "-x", deb, x], check=True)
    return x, os.path.basename(deb)

have = set(sonames_in("/usr/" + TRIPLE).keys()) | {f for f in os.listdir(toolchain_lib) if SO.search(f)}
kept, tried, total = [], set(), 0

def keep(pkg, x, deb):
    global total
    total += os.path.getsize(os.path.join(debdir, deb))
    subprocess.run(["cp", "-a", x + "/.", sysroot], check=True)
    kept.append(deb)
    libs = {name: os.path.join(sysroot, os.path.relpath(path, x)) for name, path in sonames_in(x).items()}
    have.update(libs)
    return libs

def key(s):
    return re.sub(r"[^a-z0-9]", "", s.replace(".so", ""))

def resolve(pkg, libs):
    """Fetches pkg's dependencies until every DT_NEEDED of its libraries is found."""
    missing = set()
    for path in libs.values():
        missing |= needed(path)
    missing -= have
    if not missing:
        return
    # The likeliest holder first: libgdal.so.32 -> libgdal32.
    deps = [d for d in depends(pkg) if d not in tried]
    deps.sort(key=lambda d: -max(len(os.path.commonprefix([key(d), key(m)])) for m in missing))
    for d in deps:
        if not (missing - have):
            break
        if d in tried:  # taken (or rejected) further down in the meantime
            continue
        tried.add(d)
        x, deb = fetch(d)
        got = set(sonames_in(x)) & missing
        if got:
            resolve(d, keep(d, x, deb))
        shutil.rmtree(x, ignore_errors=True)
    left = missing - have
    if left:
        sys.exit("no arm64 package among %s's dependencies holds %s" % (pkg, ", ".join(sorted(left))))

# The -dev packages and their direct dependencies (the run-time libraries the .so links point at, and the
# headers' -dev dependencies), then what the libraries need.
queue = []
for s in seeds:
    tried.add(s)
    x, deb = fetch(s)
    queue.append((s, keep(s, x, deb)))
    for d in depends(s):
        if d in tried:
            continue
        tried.add(d)
        x, deb = fetch(d)
        queue.append((d, keep(d, x, deb)))
for pkg, libs in queue:
    resolve(pkg, libs)
# Libraries chosen by update-alternatives (libblas.so.3 in .../blas/): linked into the main folder.
for name, path in sonames_in(sysroot).items():
    for d in LIBDIRS:
        main = os.path.join(sysroot, d)
        if os.path.dirname(path) != main and path.startswith(main + "/") and not os.path.lexists(
                os.path.join(main, name)):
            os.symlink(os.path.relpath(path, main), os.path.join(main, name))
shutil.rmtree(os.path.join(debdir, "x"), ignore_errors=True)
with open(os.path.join(sysroot, ".kp_packages"), "w") as f:
    f.write("\n".join(sorted(kept)) + "\n")
print("%d arm64 packages, %.1f MB of .debs, in %s (list: .kp_packages)" % (len(kept), total / 1e6, sysroot))
PY
    echo "$stamp" >"$SYSROOT/.kp_stamp"
  fi
  TIMES[sysroot]=$((SECONDS - t))
fi

# ---------------------------------------------------------------- 3. configure and build
step "configure"
t=$SECONDS
SYSROOT_ARG=()
if [ -f "$SYSROOT/.kp_stamp" ]; then
  SYSROOT_ARG=(-DKP_AARCH64_SYSROOT="$SYSROOT")
else
  echo "no sysroot in $SYSROOT: using arm64 packages installed by multiarch"
fi
# The toolchain's *_INIT flags are read on the first configure only: start again when it changed.
if [ -f "$BUILD/CMakeCache.txt" ] && [ "$ROOT/cmake/aarch64-toolchain.cmake" -nt "$BUILD/CMakeCache.txt" ]; then
  run rm -f "$BUILD/CMakeCache.txt"
fi
run cmake -S test/cross -B "$BUILD" -DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/aarch64-toolchain.cmake" \
  -DCMAKE_BUILD_TYPE=Release "${SYSROOT_ARG[@]}" >"$BUILD.configure.log" 2>&1 || {
  cat "$BUILD.configure.log"
  exit 1
}
grep -E "OpenCV|Highway|OpenMP|CMAKE_CXX_COMPILER|Warning" "$BUILD.configure.log" || true
step "build (nice -n 19, -j$JOBS)"
run nice -n 19 cmake --build "$BUILD" -j"$JOBS" -- --no-print-directory
TIMES[build]=$((SECONDS - t))

# ---------------------------------------------------------------- 4. the gtests under qemu
step "test under qemu-aarch64"
t=$SECONDS
QEMU=$(command -v qemu-aarch64-static || command -v qemu-aarch64 || true)
[ -n "$QEMU" ] || {
  echo "cross_aarch64.sh: no qemu-aarch64[-static] (apt-get install qemu-user-static)" >&2
  exit 1
}
LD_PATH=/usr/lib/$TRIPLE:/lib/$TRIPLE
[ -f "$SYSROOT/.kp_stamp" ] && LD_PATH=$SYSROOT/usr/lib/$TRIPLE:$SYSROOT/lib/$TRIPLE:$SYSROOT/usr/lib:$LD_PATH
command -v file >/dev/null && echo "test_core: $(file -b "$BUILD/test_core" | cut -d, -f1-2)"
status=0
run "$QEMU" "${QEMU_CPU_ARG[@]}" -L "/usr/$TRIPLE" -E LD_LIBRARY_PATH="$LD_PATH" "$BUILD/test_core" \
  --gtest_output=xml:"$BUILD/test_core.xml" "${GTEST_ARGS[@]}" || status=$?
TIMES[test]=$((SECONDS - t))

echo
echo "== times (s): install ${TIMES[install]:--} sysroot ${TIMES[sysroot]:--} build ${TIMES[build]} test ${TIMES[test]}" \
  "total $((SECONDS - T0)) =="
[ "$status" -eq 0 ] || echo "cross_aarch64.sh: test_core failed under qemu (exit $status)" >&2
exit "$status"
