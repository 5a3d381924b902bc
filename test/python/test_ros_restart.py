"""The node and the nodelet survive the ROS master restarting: roscpp registers topics and services only once, so
the node registers them again itself (src/ros/master_reconnect.cpp) and serves clients that start afterwards. And
the node starts over when ROS time jumps back (a bag played again with use_sim_time), instead of dropping every
frame as older than the last one.

A roscore of its own on a free loopback port; every process is started here and stopped by its own PID (its own
process group); deadlines, no fixed sleeps."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from ros_graph import NODE, ROOT, Processes, free_port

HELPER = ROOT / "test" / "ros" / "restart_helper.py"
REMAPS = ["image:=/cam/image_depth", "_pose_source:=static"]


class Client(Processes):
    def helper(self, name: str, *args: str) -> str:
        """Runs the client once; its exit status says whether the node served it."""
        out = subprocess.run(
            [sys.executable, str(HELPER), *args], env=self.env, capture_output=True, text=True, timeout=90
        )
        (self.logdir / f"{name}.log").write_text(out.stdout + out.stderr)
        assert out.returncode == 0, f"{name}: the node did not serve a new client:\n{out.stdout}{out.stderr[-3000:]}"
        return out.stdout


@pytest.fixture
def procs(tmp_path: Path) -> Iterator[Client]:
    if not NODE.exists():
        pytest.skip("no build: run scripts/quickstart.sh first")
    port = free_port()
    env = dict(os.environ)
    env.update(
        ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1", ROS_HOME=str(tmp_path / "ros"), PORT=str(port)
    )
    env.pop("ROS_HOSTNAME", None)
    p = Client(env, tmp_path)
    yield p
    p.stop_all()


@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_serves_again_after_the_master_restarts(procs: Client, kind: str) -> None:
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


def test_clock_jumping_back_starts_over(procs: Client) -> None:
    procs.start("roscore", "roscore", "-p", procs.env["PORT"])
    deadline = time.monotonic() + 60
    while subprocess.run(["rosparam", "set", "/use_sim_time", "true"], env=procs.env, capture_output=True).returncode:
        assert time.monotonic() < deadline, "roscore did not come up"
        time.sleep(0.2)
    procs.start("node", str(NODE), "__name:=kp", *REMAPS)
    procs.helper("clock_1000", "--scans", "5", "--clock", "1000")
    # Time goes back by 900 s: without starting over, every later frame would be dropped as out of order.
    procs.helper("clock_100", "--scans", "5", "--clock", "100")
    assert "ROS time moved backwards" in procs.log("node")
