#!/usr/bin/env bash
# One-command set-up for a Debian bookworm machine (as root), idempotent:
#   bash scripts/quickstart.sh demo   apt + Python env + build, then the main job on the bundled default
#   bash scripts/quickstart.sh test   apt + Python env + build, then every test
#   bash scripts/quickstart.sh build  apt + Python env + build only
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
MODE=${1:-demo}
cd "$ROOT"
# ROS 1 from Debian needs Debian's python3, not a pyenv or other interpreter first in PATH.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
log() { printf '\033[1m[quickstart]\033[0m %s\n' "$*"; }

APT_PACKAGES=(
  build-essential cmake python3-dev python3-venv catkin ros-core rosbash
  libroscpp-dev libnodeletlib-dev libnodeletlib-tools pluginlib-dev libimage-transport-dev libcv-bridge-dev
  libsensor-msgs-dev libstd-msgs-dev libtf2-ros-dev libdynamic-reconfigure-config-init-mutex-dev
  python3-dynamic-reconfigure librostest-dev python3-rostest python3-rospy python3-sensor-msgs python3-cv-bridge
  python3-tf2-ros libopencv-dev libhwy-dev libgtest-dev googletest pybind11-dev python3-pybind11 python3-numpy
  python3-opencv python3-pytest python3-matplotlib libdiagnostic-updater-dev libgeometry-msgs-dev
  python3-rosbag python3-roslaunch python3-rostopic python3-diagnostic-msgs python3-std-srvs rviz xvfb x11-apps
  imagemagick image-transport-tools libcamera-calibration-parsers-dev libroslib-dev
  clang libclang-rt-14-dev libomp-14-dev
)

install_apt() {
  local missing=()
  for p in "${APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    log "apt: all ${#APT_PACKAGES[@]} packages present"
    return
  fi
  log "apt: installing ${#missing[@]} packages: ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

install_venv() {
  # Debian's numpy 1.24 / cv_bridge / rospy are seen through --system-site-packages; numpy stays < 2.
  local want stamp=.venv/.kp-requirements
  want=$(sha256sum requirements.txt | cut -c1-64)
  if [ -x .venv/bin/python3 ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    log "python: .venv up to date"
    return
  fi
  log "python: creating .venv from /usr/bin/python3"
  /usr/bin/python3 -m venv --system-site-packages .venv
  .venv/bin/python3 -m pip install -q --disable-pip-version-check -r requirements.txt
  echo "$want" > "$stamp"
}

build() {
  log "build: catkin package in build/ (devel space build/devel)"
  # The install space must lie outside the package: roslaunch searches the whole package folder for launch files
  # and would find two of each.
  local install_prefix
  install_prefix="/tmp/kinect_pipeline_install-$(printf '%s' "$ROOT" | sha1sum | cut -c1-8)"
  if [ ! -f build/cmake/Makefile ] || ! grep -q "^CMAKE_INSTALL_PREFIX:PATH=$install_prefix\$" build/cmake/CMakeCache.txt; then
    rm -rf build/install
    env -u CMAKE_PREFIX_PATH cmake -S . -B build/cmake -DCMAKE_BUILD_TYPE=Release -DCATKIN_DEVEL_PREFIX="$ROOT/build/devel" \
      -DCMAKE_INSTALL_PREFIX="$install_prefix" -DPYTHON_EXECUTABLE=/usr/bin/python3 \
      -DPython3_EXECUTABLE=/usr/bin/python3 -DCATKIN_ENABLE_TESTING=ON >build/cmake.log 2>&1 ||
      { mkdir -p build; cat build/cmake.log; exit 1; }
  fi
  # Without a sourced devel space in CMAKE_PREFIX_PATH (a shell that ran env.sh): a re-configure would chain the
  # install space onto it.
  env -u CMAKE_PREFIX_PATH cmake --build build/cmake -j"$(nproc)" -- --no-print-directory 2>&1 |
    grep -E "error|warning|Error" || true
  env -u CMAKE_PREFIX_PATH cmake --build build/cmake -j"$(nproc)" >/dev/null
}

mkdir -p build
install_apt
install_venv
build
# shellcheck disable=SC1091
. ./env.sh

case "$MODE" in
  build) ;;
  demo)
    log "demo: synthetic sequence through the pipeline -> out/demo"
    kinect-pipeline demo --out out/demo
    ;;
  test)
    bash scripts/run_tests.sh
    ;;
  *)
    echo "usage: bash scripts/quickstart.sh demo|test|build" >&2
    exit 2
    ;;
esac
