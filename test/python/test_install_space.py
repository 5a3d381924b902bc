"""The package works from a catkin install space, not only from devel."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "cmake"


def _install_prefix() -> Path:
    for line in (BUILD / "CMakeCache.txt").read_text().splitlines():
        if line.startswith("CMAKE_INSTALL_PREFIX:"):
            return Path(line.split("=", 1)[1])
    raise AssertionError("no CMAKE_INSTALL_PREFIX in the CMake cache")


INSTALL = _install_prefix() if (BUILD / "CMakeCache.txt").exists() else ROOT / "build" / "install"


@pytest.fixture(scope="module")
def install_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    if not (BUILD / "Makefile").exists():
        pytest.skip("no build/cmake: run scripts/quickstart.sh first")
    subprocess.run(
        ["cmake", "--build", str(BUILD), "--target", "install"], check=True, capture_output=True, timeout=600
    )
    # A clean environment: only the install space, none of devel or the source tree; ROS's logs and rospack's cache
    # in a folder of the test's own.
    ros_home = str(tmp_path_factory.mktemp("ros_home"))
    clean = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root"), "ROS_HOME": ros_home}
    out = subprocess.run(
        ["bash", "-c", f"set +u; . {INSTALL}/setup.sh && env -0"],
        env=clean,
        check=True,
        capture_output=True,
        timeout=60,
    ).stdout
    env = dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)
    assert str(ROOT / "build" / "devel") not in env.get("PYTHONPATH", "")
    assert not INSTALL.is_relative_to(ROOT), "an install space inside the package confuses roslaunch"
    return env


def run(env: dict[str, str], *cmd: str) -> str:
    return subprocess.run(cmd, env=env, check=True, capture_output=True, text=True, timeout=120, cwd="/").stdout


def test_python_module_and_tools_come_from_the_install_space(install_env: dict[str, str]) -> None:
    where = run(
        install_env, "python3", "-c", "import kinect_pipeline._core as c, kinect_pipeline.tools.demo; print(c.__file__)"
    )
    assert where.startswith(str(INSTALL)), where
    assert "usage: kinect-pipeline" in run(install_env, str(INSTALL / "lib/kinect_pipeline/kinect-pipeline"), "--help")


def test_package_launch_files_and_nodelet_are_found(install_env: dict[str, str]) -> None:
    share = run(install_env, "rospack", "find", "kinect_pipeline").strip()
    assert share == str(INSTALL / "share" / "kinect_pipeline")
    for f in (
        "launch/kinect_pipeline.launch",
        "launch/replay.launch",
        "launch/rviz.launch",
        "rviz/kinect_pipeline.rviz",
        "cfg/KinectPipeline.cfg",
        "nodelet_plugins.xml",
    ):
        assert (Path(share) / f).exists(), f
    plugins = run(install_env, "rospack", "plugins", "--attrib=plugin", "nodelet")
    assert f"kinect_pipeline {share}/nodelet_plugins.xml" in plugins
    assert (INSTALL / "lib" / "libkinect_pipeline_nodelet.so").exists()
    assert (INSTALL / "lib" / "kinect_pipeline" / "kinect_pipeline_node").exists()


def test_node_help_loader_and_readme_come_from_the_install_space(install_env: dict[str, str]) -> None:
    share = INSTALL / "share" / "kinect_pipeline"
    assert (share / "README.md").exists()
    out = run(install_env, "rosrun", "kinect_pipeline", "kinect_pipeline_node", "--help")
    assert "usage:" in out and f"{share}/README.md" in out, out
    # The launch file's nodelet loader is installed beside the node, and runs from there.
    loader = INSTALL / "lib" / "kinect_pipeline" / "load_into_manager"
    assert loader.exists()
    assert "usage: load_into_manager" in run(install_env, str(loader), "--help")
