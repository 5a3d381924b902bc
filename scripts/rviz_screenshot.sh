#!/usr/bin/env bash
# Renders the shipped rviz view of a replayed synthetic bag under Xvfb and saves a screenshot.
#   bash scripts/rviz_screenshot.sh OUT.png [BAG]
# Starts its own roscore (port 11411), Xvfb (:91) and roslaunch, and stops them by PID.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
OUT=${1:?usage: rviz_screenshot.sh OUT.png [BAG]}
cd "$ROOT"
# shellcheck disable=SC1091
. ./env.sh
WORK=$(mktemp -d /tmp/kp-rviz.XXXXXX)
BAG=${2:-$WORK/demo.bag}
[ -f "$BAG" ] || kinect-pipeline synth "$BAG" --frames 450 --quiet >/dev/null
export ROS_HOME=$WORK ROS_MASTER_URI=http://127.0.0.1:11411 ROS_IP=127.0.0.1 DISPLAY=:91 LIBGL_ALWAYS_SOFTWARE=1
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; rm -rf "$WORK"; }
trap cleanup EXIT
Xvfb :91 -screen 0 1200x800x24 >/dev/null 2>&1 & pids+=($!)
roscore -p 11411 >/dev/null 2>&1 & pids+=($!)
for _ in $(seq 100); do rostopic list >/dev/null 2>&1 && break; sleep 0.1; done
roslaunch kinect_pipeline rviz.launch bag:="$BAG" loop:=false >"$WORK/launch.log" 2>&1 & pids+=($!)
# Wait until the Kinect scan flows, then give rviz a few rendered frames.
timeout 60 rostopic echo -n 3 /kinect2/scan/header/stamp >/dev/null
for _ in $(seq 30); do xwininfo -root -tree 2>/dev/null | grep -qi rviz && break; sleep 0.2; done
sleep 6
import -window root "$OUT"
echo "screenshot: $OUT"
