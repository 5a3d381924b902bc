"""The node and the nodelet survive the ROS master restarting: roscpp registers topics and services only once, so
the node registers them again itself (src/ros/master_reconnect.cpp) and serves clients that start afterwards.

A roscore of its own on a free loopback port; every process is started here and stopped by its own PID (its own
process group); deadlines, no fixed sleeps."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NODE = ROOT / "build" / "devel" / "lib" / "kinect_pipeline" / "kinect_pipeline_node"
HELPER = ROOT / "test" / "ros" / "restart_helper.py"
REMAPS = ["image:=/cam/image_depth", "_pose_source:=static"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Processes:
    """Processes started in their own process group, stopped by that PID: SIGINT, then SIGKILL at a deadline."""

    def __init__(self, env: dict[str, str], logdir: Path) -> None:
        self.env, self.logdir = env, logdir
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self, name: str, *cmd: str) -> subprocess.Popen[bytes]:
        with open(self.logdir / f"{name}.log", "ab") as log:  # the child keeps its own descriptor
            p = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        self.procs.append(p)
        return p

    def stop(self, p: subprocess.Popen[bytes]) -> None:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGINT)
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=15)

    def stop_all(self) -> None:
        for p in reversed(self.procs):
            self.stop(p)

    def helper(self, name: str, *args: str) -> str:
        """Runs the client once; its exit status says whether the node served it."""
        out = subprocess.run(
            [sys.executable, str(HELPER), *args], env=self.env, capture_output=True, text=True, timeout=90
        )
        (self.logdir / f"{name}.log").write_text(out.stdout + out.stderr)
        assert out.returncode == 0, f"{name}: the node did not serve a new client:\n{out.stdout}{out.stderr[-3000:]}"
        return out.stdout

    def log(self, name: str) -> str:
        return (self.logdir / f"{name}.log").read_text(errors="replace")


@pytest.fixture
def procs(tmp_path: Path) -> Iterator[Processes]:
    if not NODE.exists():
        pytest.skip("no build: run scripts/quickstart.sh first")
    port = free_port()
    env = dict(os.environ)
    env.update(
        ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1", ROS_HOME=str(tmp_path / "ros"), PORT=str(port)
    )
    env.pop("ROS_HOSTNAME", None)
    p = Processes(env, tmp_path)
    yield p
    p.stop_all()


@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_serves_again_after_the_master_restarts(procs: Processes, kind: str) -> None:
    port = procs.env["PORT"]
    core = procs.start("roscore1", "roscore", "-p", port)
    if kind == "node":
        procs.start("node", str(NODE), "__name:=kp", *REMAPS)
        name = "node"
    else:
        procs.start("manager", "rosrun", "nodelet", "nodelet", "manager", "__name:=mgr")
        procs.start("load", "rosrun", "nodelet", "nodelet", "load", "kinect_pipeline/KinectPipelineNodelet", "mgr",
                    "__name:=kp", *REMAPS)  # fmt: skip
        name = "manager"
    procs.helper("before", "--scans", "3")

    procs.stop(core)  # the master goes away: the node keeps running
    core = procs.start("roscore2", "roscore", "-p", port)
    # A client that registers with the new master only: topics, the scan and the reconfigure service must work.
    procs.helper("after", "--scans", "3", "--range-max", "3.5")
    assert "registered this process's topics and services again" in procs.log(name)
