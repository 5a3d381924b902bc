"""Image -> scan latency and CPU through the node and the nodelet at 30 Hz, next to a bare image_transport relay
measured in the same run (its own roscore on loopback, processes stopped by their PIDs)."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import kinect_v2_camera
from ..simulation.scenes import lab_scene, render_frame


@dataclass
class Measurement:
    name: str
    sent: int
    received: int
    latencies_ms: np.ndarray
    cpu_percent: float
    rss_start_mb: float = float("nan")
    rss_end_mb: float = float("nan")
    rss_trace_mb: list[float] | None = None  # one value a minute while frames flow
    node_counters: dict[str, int] | None = None  # the node's own drop / fallback counters (/diagnostics) at the end

    def row(self, relay: Measurement | None) -> str:
        med, p99 = np.median(self.latencies_ms), np.percentile(self.latencies_ms, 99)
        added = ""
        if relay is not None and relay is not self:
            added = f"{med - np.median(relay.latencies_ms):+.3f} / {p99 - np.percentile(relay.latencies_ms, 99):+.3f}"
        return (
            f"| {self.name} | {self.sent} | {self.received} | {self.sent - self.received} | {med:.3f} | {p99:.3f} "
            f"| {added or '–'} | {self.cpu_percent:.1f} |"
        )


_NODE_COUNTERS = ("frames in", "frames out", "pose fallbacks")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_seconds(pids: list[int]) -> float:
    total = 0.0
    tick = os.sysconf("SC_CLK_TCK")
    for pid in pids:
        for task in Path(f"/proc/{pid}/task").glob("*"):
            try:
                fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
                total += (int(fields[11]) + int(fields[12])) / tick
            except (OSError, IndexError, ValueError):
                pass
    return total


def _rss_mb(pids: list[int]) -> float:
    total = 0
    for pid in pids:
        try:
            for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1])
        except OSError:
            pass
    return total / 1024.0


def _descendants(pid: int) -> list[int]:
    out = [pid]
    for p in Path("/proc").glob("[0-9]*"):
        try:
            if int((p / "stat").read_text().rsplit(")", 1)[1].split()[1]) in out:
                out.append(int(p.name))
        except (OSError, ValueError, IndexError):
            pass
    return out


def _stop(proc: subprocess.Popen[Any]) -> None:
    """SIGINT to the process's group, SIGKILL at a deadline. The deadline outlasts roslaunch's own escalation (SIGINT,
    15 s, SIGTERM, 2 s, SIGKILL): roslaunch starts its nodes in sessions of their own, which a SIGKILL of roslaunch's
    group does not reach."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=5)


@dataclass
class _Subject:
    name: str
    cmd: list[str]
    ns: str  # its input: NS/sd/image_depth and NS/sd/camera_info
    topic: str  # its output
    msg_type: Any
    image_pub: Any = None
    info_pub: Any = None
    proc: subprocess.Popen[Any] | None = None
    pids: list[int] | None = None


def run(
    frames: int = 300, rate: float = 30.0, threads: int = 1, only: str | None = None, sequential: bool = False
) -> list[Measurement]:
    """Runs relay, node and nodelet side by side with the same frames and returns their numbers.

    Each subject has its own input topics, and frame i goes to subject i mod n at n * ``rate`` frames per second:
    each gets ``rate`` frames per second, and all of them meet the machine's hiccups of the same minutes (run one
    after the other on a shared machine, their tails were minutes apart and differed by more than the node adds).
    ``threads`` is the pipeline's num_threads (0: OpenMP's default); ``only`` ("relay", "node" or "nodelet") runs
    that one; ``sequential`` runs them one after the other, through the same roscore.
    """
    if threading.current_thread() is threading.main_thread():  # a SIGTERM stops what this run started, too
        signal.signal(signal.SIGTERM, _exit_on_sigterm)
    work = Path(tempfile.mkdtemp(prefix="kp-bench-ros-"))
    port = _free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1", ROS_HOME=str(work))
    os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME")})
    core = subprocess.Popen(
        ["roscore", "-p", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    done = False
    try:
        _join_master(port)
        subjects = _subjects(work, threads, only)
        results: list[Measurement] = []
        for group in [[c] for c in subjects] if sequential else [subjects]:
            bench = _Bench(env, group)
            try:
                bench.start()
                period = 1.0 / (rate * len(group))
                bench.warm_up(period)
                results += bench.measure(frames, period)
            finally:
                bench.stop()
        done = True
        return results
    finally:
        _stop(core)
        _clean_up(work, done)


def _clean_up(work: Path, done: bool) -> None:
    """Removes the run's work folder (ROS_HOME: the processes' logs, the parameters, roscore's PID file) after a run
    that ended well; after one that did not, keeps it for its logs and says where."""
    if done:
        shutil.rmtree(work, ignore_errors=True)
    else:
        print(f"the run's logs (its ROS_HOME) are kept in {work}", file=sys.stderr)


def _exit_on_sigterm(signum: int, _frame: Any) -> None:
    raise SystemExit(128 + signum)


def _join_master(port: int) -> None:
    """Waits for this run's roscore (30 s at most) and makes this process a ROS node of it (once per process: rospy
    cannot join a second master)."""
    import rosgraph
    import rospy

    if rospy.core.is_initialized():
        uri = rosgraph.get_master_uri()
        raise RuntimeError(f"this process is a ROS node of {uri} already: expected one run per process")
    deadline = time.monotonic() + 30
    while not rosgraph.is_master_online():
        if time.monotonic() > deadline:
            raise RuntimeError(f"roscore -p {port} did not come up within 30 s")
        time.sleep(0.1)
    rospy.init_node("kp_bench_ros", anonymous=True, disable_signals=True)


def _subjects(work: Path, threads: int, only: str | None) -> list[_Subject]:
    """The relay, the node and the nodelet (or ``only`` the one named), each on its own topics."""
    from sensor_msgs.msg import Image, LaserScan

    params = work / "params.yaml"
    params.write_text(f"num_threads: {threads}\n")
    launch = ["pose_source:=static", "sensor_pitch:=0.26", f"params:={params}"]
    relay = [
        "rosrun",
        "image_transport",
        "republish",
        "raw",
        "in:=/relay_in/sd/image_depth",
        "raw",
        "out:=/relay/image",
    ]
    node = ["roslaunch", "kinect_pipeline", "kinect_pipeline.launch", "camera:=bench_node", *launch]
    nodelet = ["roslaunch", "kinect_pipeline", "bench_nodelet.launch", "camera:=bench_nodelet", f"params:={params}"]
    candidates = [
        _Subject("image_transport relay", relay, "/relay_in", "/relay/image", Image),
        _Subject("kinect_pipeline node", node, "/bench_node", "/bench_node/scan", LaserScan),
        _Subject("kinect_pipeline nodelet", nodelet, "/bench_nodelet", "/bench_nodelet/scan", LaserScan),
    ]
    return [c for c in candidates if only is None or c.name.endswith(" " + only)]


class _Bench:
    """The subjects' processes, the frame they are sent, and what came back: latencies and the node's counters."""

    def __init__(self, env: dict[str, str], subjects: list[_Subject]) -> None:
        self.env, self.subjects = env, subjects
        self.lock = threading.Lock()
        self.lat: dict[str, list[float]] = {c.name: [] for c in subjects}
        self.counters: dict[str, dict[str, int]] = {c.name: {} for c in subjects}
        self.sent: dict[str, int] = {c.name: 0 for c in subjects}
        self.subs: list[Any] = []

    def start(self) -> None:
        """Publishes to and subscribes to every subject, then starts their processes."""
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import CameraInfo, Image

        self.img, self.info = _messages()
        for c in self.subjects:
            c.image_pub = rospy.Publisher(f"{c.ns}/sd/image_depth", Image, queue_size=5)
            c.info_pub = rospy.Publisher(f"{c.ns}/sd/camera_info", CameraInfo, queue_size=5)
            self.subs.append(
                rospy.Subscriber(
                    c.topic, c.msg_type, self._on_output, callback_args=c.name, queue_size=100, tcp_nodelay=True
                )
            )
        self.subs.append(rospy.Subscriber("/diagnostics", DiagnosticArray, self._on_diagnostics, queue_size=10))
        for c in self.subjects:
            c.proc = subprocess.Popen(
                c.cmd, env=self.env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
            )

    def _on_output(self, m: Any, name: str) -> None:
        import rospy

        now = rospy.get_rostime()
        with self.lock:
            self.lat[name].append((now - m.header.stamp).to_sec() * 1e3)

    def _on_diagnostics(self, m: Any) -> None:
        with self.lock:
            for st in m.status:
                for c in self.subjects:
                    if st.hardware_id.startswith(c.ns + "/"):
                        for kv in st.values:
                            if kv.key.startswith("dropped: ") or kv.key in _NODE_COUNTERS:
                                self.counters[c.name][kv.key] = int(kv.value)

    def send(self, c: _Subject) -> None:
        import rospy

        self.img.header.stamp = self.info.header.stamp = rospy.get_rostime()
        c.info_pub.publish(self.info)
        c.image_pub.publish(self.img)
        self.sent[c.name] += 1

    def _wait(self, done: Callable[[], bool], seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            with self.lock:
                if done():
                    return
            time.sleep(0.01)

    def warm_up(self, period: float) -> None:
        """Sends frames until every subject's output flows (90 s at most), lets the last ones arrive (2 s at most),
        then forgets what came back."""
        n, deadline, i = len(self.subjects), time.monotonic() + 90, 0
        while time.monotonic() < deadline:
            self.send(self.subjects[i % n])
            i += 1
            time.sleep(period)
            with self.lock:
                if all(len(v) >= 10 for v in self.lat.values()):
                    break
        self._wait(lambda: all(len(self.lat[k]) >= self.sent[k] for k in self.sent), 2.0)
        with self.lock:
            for v in self.lat.values():
                v.clear()
        for c in self.subjects:
            assert c.proc is not None
            c.pids = _descendants(c.proc.pid)

    def measure(self, frames: int, period: float) -> list[Measurement]:
        """Sends ``frames`` frames to each subject, interleaved, at one frame every ``period`` seconds in all."""
        n = len(self.subjects)
        cpu0 = {c.name: _cpu_seconds(c.pids or []) for c in self.subjects}
        trace = {c.name: [_rss_mb(c.pids or [])] for c in self.subjects}
        t0 = next_t = time.monotonic()
        next_sample = next_t + 60.0
        for i in range(frames * n):
            self.send(self.subjects[i % n])
            next_t += period
            if next_t >= next_sample:  # the memory once a minute
                for c in self.subjects:
                    trace[c.name].append(_rss_mb(c.pids or []))
                next_sample += 60.0
            time.sleep(max(0.0, next_t - time.monotonic()))
        self._wait(lambda: all(len(v) >= frames for v in self.lat.values()), 2.0)
        elapsed = time.monotonic() - t0
        results = []
        for c in self.subjects:
            cpu = (_cpu_seconds(c.pids or []) - cpu0[c.name]) / elapsed * 100.0
            rss1 = _rss_mb(c.pids or [])
            with self.lock:
                m = Measurement(c.name, frames, len(self.lat[c.name]), np.array(self.lat[c.name]), cpu)
                m.rss_start_mb, m.rss_end_mb, m.rss_trace_mb = trace[c.name][0], rss1, [*trace[c.name], rss1]
                m.node_counters = dict(self.counters[c.name]) or None
            results.append(m)
        return results

    def stop(self) -> None:
        for sub in self.subs:
            sub.unregister()
        for c in self.subjects:
            for pub in (c.image_pub, c.info_pub):
                if pub is not None:
                    pub.unregister()
            if c.proc is not None:
                _stop(c.proc)


def _messages() -> tuple[Any, Any]:
    """The one frame every subject gets (the lab scene, 16UC1) and its camera_info."""
    from sensor_msgs.msg import CameraInfo, Image

    cam = kinect_v2_camera()
    frame = render_frame(cam, lab_scene(), 1.1, 0.26, 0.0, "16UC1", seed=3)
    img = Image(
        height=cam.height,
        width=cam.width,
        encoding="16UC1",
        is_bigendian=0,
        step=cam.width * 2,
        data=frame.depth.tobytes(),
    )
    img.header.frame_id = "kinect2_depth_optical_frame"
    info = CameraInfo(width=cam.width, height=cam.height, K=[cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1])
    info.header.frame_id = img.header.frame_id
    return img, info


def report(results: list[Measurement]) -> str:
    relay = next((r for r in results if "relay" in r.name), None)
    lines = [
        "| subject | frames sent | received | dropped | latency median [ms] | p99 [ms] "
        "| added vs relay median / p99 [ms] | CPU [%] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [r.row(relay) for r in results]
    return "\n".join(lines)


def soak_report(results: list[Measurement]) -> str:
    lines = [
        "| subject | frames in | out | dropped | latency p50 [ms] | p99 [ms] | RSS start [MB] | RSS end [MB] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r.name} | {r.sent} | {r.received} | {r.sent - r.received} | "
            f"{np.median(r.latencies_ms):.3f} | {np.percentile(r.latencies_ms, 99):.3f} | "
            f"{r.rss_start_mb:.1f} | {r.rss_end_mb:.1f} |"
        )
    for r in results:
        if r.rss_trace_mb:
            lines.append(f"\n{r.name}: RSS each minute [MB]: " + " ".join(f"{v:.1f}" for v in r.rss_trace_mb))
        if r.node_counters:
            lines.append(
                f"\n{r.name}: its diagnostics at the end (frames of the warm-up included): "
                + ", ".join(f"{k} {v}" for k, v in sorted(r.node_counters.items()) if v or not k.startswith("dropped"))
            )
    return "\n".join(lines)
