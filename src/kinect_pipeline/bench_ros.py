"""Image -> scan latency and CPU through the node and the nodelet at 30 Hz, next to a bare image_transport relay
measured in the same run (its own roscore on loopback, processes stopped by their PIDs)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import kinect_v2_camera
from .scenes import lab_scene, render_frame


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
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=5)


def run(frames: int = 300, rate: float = 30.0, threads: int = 1, only: str | None = None) -> list[Measurement]:
    """Runs relay, node and nodelet one after the other with the same frames and returns their numbers.
    ``threads`` is the pipeline's num_threads (0: OpenMP's default)."""
    port = _free_port()
    work = Path(tempfile.mkdtemp(prefix="kp-bench-ros-"))
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1", ROS_HOME=str(work))
    os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME")})
    core = subprocess.Popen(
        ["roscore", "-p", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    results: list[Measurement] = []
    try:
        import rosgraph
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import CameraInfo, Image, LaserScan

        deadline = time.monotonic() + 30
        while not rosgraph.is_master_online() and time.monotonic() < deadline:
            time.sleep(0.1)
        rospy.init_node("kp_bench_ros", anonymous=True, disable_signals=True)
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
        image_pub = rospy.Publisher("/kinect2/sd/image_depth", Image, queue_size=5)
        info_pub = rospy.Publisher("/kinect2/sd/camera_info", CameraInfo, queue_size=5)

        params = work / "params.yaml"
        params.write_text(f"num_threads: {threads}\n")
        subjects = [
            (
                "image_transport relay",
                [
                    "rosrun",
                    "image_transport",
                    "republish",
                    "raw",
                    "in:=/kinect2/sd/image_depth",
                    "raw",
                    "out:=/relay/image",
                ],
                "/relay/image",
                Image,
            ),
            (
                "kinect_pipeline node",
                [
                    "roslaunch",
                    "kinect_pipeline",
                    "kinect_pipeline.launch",
                    "pose_source:=static",
                    "sensor_pitch:=0.26",
                    f"params:={params}",
                ],
                "/kinect2/scan",
                LaserScan,
            ),
            (
                "kinect_pipeline nodelet",
                ["roslaunch", "kinect_pipeline", "bench_nodelet.launch", f"params:={params}"],
                "/kinect2/scan",
                LaserScan,
            ),
        ]
        for name, cmd, topic, msg_type in subjects:
            if only is not None and not name.endswith(" " + only):
                continue
            lat: list[float] = []
            lock = threading.Lock()

            def on_msg(m: Any, lat: list[float] = lat, lock: threading.Lock = lock) -> None:
                now = rospy.get_rostime()
                with lock:
                    lat.append((now - m.header.stamp).to_sec() * 1e3)

            sub = rospy.Subscriber(topic, msg_type, on_msg, queue_size=100, tcp_nodelay=True)
            counters: dict[str, int] = {}

            def on_diag(m: Any, counters: dict[str, int] = counters, lock: threading.Lock = lock) -> None:
                with lock:
                    for st in m.status:
                        for kv in st.values:
                            if kv.key.startswith("dropped: ") or kv.key in _NODE_COUNTERS:
                                counters[kv.key] = int(kv.value)

            diag_sub = rospy.Subscriber("/diagnostics", DiagnosticArray, on_diag, queue_size=10)
            proc = subprocess.Popen(
                cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
            )
            try:
                # Warm up until output flows (deadline), then measure.
                deadline = time.monotonic() + 60
                period = 1.0 / rate
                while time.monotonic() < deadline:
                    stamp = rospy.get_rostime()
                    img.header.stamp = info.header.stamp = stamp
                    info_pub.publish(info)
                    image_pub.publish(img)
                    time.sleep(period)
                    with lock:
                        if len(lat) >= 10:
                            break
                time.sleep(0.5)
                pids = _descendants(proc.pid)
                with lock:
                    lat.clear()
                cpu0, t0 = _cpu_seconds(pids), time.monotonic()
                rss0 = _rss_mb(pids)
                next_t = time.monotonic()
                trace = [rss0]
                next_sample = next_t + 60.0
                for _ in range(frames):
                    stamp = rospy.get_rostime()
                    img.header.stamp = info.header.stamp = stamp
                    info_pub.publish(info)
                    image_pub.publish(img)
                    next_t += period
                    if next_t >= next_sample:
                        trace.append(_rss_mb(pids))
                        next_sample += 60.0
                    time.sleep(max(0.0, next_t - time.monotonic()))
                end = time.monotonic() + 2.0
                while time.monotonic() < end:
                    with lock:
                        if len(lat) >= frames:
                            break
                    time.sleep(0.01)
                cpu = (_cpu_seconds(pids) - cpu0) / (time.monotonic() - t0) * 100.0
                rss1 = _rss_mb(pids)
                with lock:
                    m = Measurement(name, frames, len(lat), np.array(lat), cpu, rss0, rss1, [*trace, rss1])
                    m.node_counters = dict(counters) if counters else None
                    results.append(m)
            finally:
                sub.unregister()
                diag_sub.unregister()
                _stop(proc)
    finally:
        _stop(core)
    return results


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
