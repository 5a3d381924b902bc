"""A ROS graph of a test's own: a roscore on a free loopback port, processes started in their own process groups and
stopped by their own PIDs (SIGINT, then SIGKILL at a deadline), their output in files, and waits with deadlines."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kinect_pipeline.tools.bench_ros import _free_port as free_port
from kinect_pipeline.tools.bench_ros import _stop

ROOT = Path(__file__).resolve().parents[2]
NODE = ROOT / "build" / "devel" / "lib" / "kinect_pipeline" / "kinect_pipeline_node"
FEEDER = ROOT / "test" / "ros" / "feeder.py"


def wait_for(what: str, cond: Callable[[], Any], timeout: float = 60.0, poll: float = 0.05) -> Any:
    """Polls ``cond`` until it returns something true; fails the test at the deadline."""
    deadline = time.monotonic() + timeout
    while True:
        got = cond()
        if got:
            return got
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(poll)


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
        _stop(p)

    def stop_all(self) -> None:
        for p in reversed(self.procs):
            self.stop(p)
        self.procs.clear()

    def log(self, name: str) -> str:
        path = self.logdir / f"{name}.log"
        return path.read_text(errors="replace") if path.exists() else ""


class RosGraph(Processes):
    """A roscore of its own; roslaunch, nodes and the feeder (test/ros/feeder.py) against it."""

    def __init__(self, logdir: Path) -> None:
        port = free_port()
        env = dict(os.environ)
        env.update(ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1", ROS_HOME=str(logdir / "ros"))
        env.pop("ROS_HOSTNAME", None)
        env.pop("ROS_NAMESPACE", None)
        super().__init__(env, logdir)
        self.port = port
        self.core: subprocess.Popen[bytes] | None = None
        self.runs = 0

    def session(self, logdir: Path) -> RosGraph:
        """The same roscore, with processes and logs of another test's own."""
        g = RosGraph.__new__(RosGraph)
        g.__dict__.update(self.__dict__)
        g.logdir, g.procs = logdir, []
        return g

    def stop_all(self) -> None:
        """Stops this graph's processes; the graph that started the roscore then checks that nothing it started is
        left (a node that outlived its roslaunch: roslaunch starts nodes in sessions of their own), kills what is
        (by PID) and fails naming it."""
        owner = self.core is not None and self.core in self.procs
        super().stop_all()
        if owner:
            deadline = time.monotonic() + 30
            while self.leftovers() and time.monotonic() < deadline:
                time.sleep(0.1)  # polled under the deadline: a process shutting down
            left = self.leftovers()
            for pid in left:
                os.kill(pid, signal.SIGKILL)
            # Killed, a process lingers in /proc until the kernel has torn it down and its parent (init, for a node
            # roslaunch left) has reaped it: polled under a deadline, so that what was left is gone on return.
            deadline = time.monotonic() + 10
            while left and set(left) & set(self.leftovers()) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not left, f"processes left running after the test: {left}"

    def leftovers(self) -> dict[int, str]:
        """PID -> command line of the processes whose ROS_HOME is this graph's."""
        mine = f"\0ROS_HOME={self.env['ROS_HOME']}\0".encode()
        found = {}
        for p in Path("/proc").iterdir():
            try:
                env = b"\0" + (p / "environ").read_bytes() + b"\0" if p.name.isdigit() else b""
                if mine in env and int(p.name) != os.getpid():
                    found[int(p.name)] = (p / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:  # gone meanwhile, or not ours to read
                pass
        return found

    def master(self) -> Any:
        import rosgraph

        return rosgraph.Master("/first_day_test", master_uri=self.env["ROS_MASTER_URI"])

    def has_service(self, service: str) -> bool:
        """Whether the master knows the service (a node offers it)."""
        try:
            self.master().lookupService(service)
            return True
        except Exception:
            return False

    def start_core(self, sim_time: bool = False) -> None:
        self.core = self.start("roscore", "roscore", "-p", str(self.port))
        wait_for("roscore", lambda: self._online(), timeout=60)
        if sim_time:
            self.master().setParam("/use_sim_time", True)

    def _online(self) -> bool:
        try:
            return bool(self.master().is_online())
        except Exception:
            return False

    def reset_params(self) -> None:
        """Forgets what earlier nodes left on the parameter server (dynamic_reconfigure writes every parameter)."""
        m = self.master()
        for ns in ("/kinect2", "/kp", "/use_sim_time"):
            try:
                m.deleteParam(ns)
            except Exception:
                pass

    def launch(self, name: str, launch_file: str, *args: str) -> subprocess.Popen[bytes]:
        return self.start(name, "roslaunch", "--screen", "kinect_pipeline", launch_file, *args)

    def feed(self, name: str, *args: str, deadline: float = 60.0, must: bool = True) -> dict[str, Any]:
        """Runs the feeder once; @return what it recorded. ``must``: the condition must have been met."""
        out = self.logdir / f"{name}.json"
        run = subprocess.run(
            [sys.executable, str(FEEDER), "--out", str(out), "--deadline", str(deadline), *args],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=deadline + 60,
        )
        (self.logdir / f"{name}.log").write_text(run.stdout + run.stderr)
        assert out.exists(), f"{name}: the feeder wrote nothing:\n{run.stdout}{run.stderr[-3000:]}"
        result: dict[str, Any] = json.loads(out.read_text())
        if must:
            assert result["ok"], (
                f"{name}: condition not met by the deadline ({len(result['sent'])} frames sent, "
                f"{len(result['scans'])} scans):\n{run.stdout}{run.stderr[-3000:]}"
            )
        return result


def newest(result: dict[str, Any], status: str, key: str) -> str | None:
    """The newest value of a diagnostics key of one status in a feeder's result."""
    for d in reversed(result["diags"]):
        st = d["status"].get(status)
        if st and key in st["values"]:
            return str(st["values"][key])
    return None
