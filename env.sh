# Source from the repository root after a Quick start command:  . ./env.sh
# Gives python3 (with kinect_pipeline importable), the kinect-pipeline command and the package's ROS environment.
if [ -n "${BASH_SOURCE:-}" ]; then _kp_root=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd); else _kp_root=$(pwd); fi
if [ ! -f "$_kp_root/build/devel/setup.sh" ]; then
  echo "env.sh: $_kp_root/build/devel/setup.sh is missing: run 'bash scripts/quickstart.sh demo' first" >&2
else
  _kp_u=$(set +o | grep nounset); set +u
  # shellcheck disable=SC1091
  . "$_kp_root/build/devel/setup.sh"
  eval "$_kp_u"
  export ROS_PACKAGE_PATH="$_kp_root${ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}"
  export PATH="$_kp_root/.venv/bin:$_kp_root/scripts:/usr/bin:$PATH"
  export KINECT_PIPELINE_ROOT="$_kp_root"
fi
unset _kp_u
