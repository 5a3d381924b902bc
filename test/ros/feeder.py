#!/usr/bin/env python3
"""A ROS client for test/python/test_ros_first_day.py, started anew by each test against the test's own roscore.

Publishes rendered depth frames (raw Image or compressedDepth CompressedImage, with camera_info), optionally tf,
an IMU or a base pitch and /clock, as the options say; records what the node under test publishes (scans, cliff
scans, /diagnostics, /rosout, the scan frame's tf) and exits once ``--until`` (a Python expression over what was
recorded) holds, or at the deadline. Writes everything to ``--out`` as JSON; the exit status says whether the
condition was met. No fixed sleeps: frames go out at ``--rate`` on ROS time (wall time without /clock)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from typing import Any

import numpy as np
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray
from frames import optical_quaternion
from geometry_msgs.msg import Quaternion, TransformStamped
from rosgraph_msgs.msg import Clock, Log
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, Imu, LaserScan
from std_msgs.msg import Float64
from tf2_msgs.msg import TFMessage

import kinect_pipeline as kp
from kinect_pipeline.simulation.scenes import Scene, boxes_scene, lab_scene, render_frame

CAM = kp.Camera(512, 424, 365.0, 365.0, 255.5, 211.5)
OPTICAL = "kinect2_depth_optical_frame"
SCENES = {
    "boxes": boxes_scene,
    "lab": lab_scene,
    # An obstacle filling the view 0.8 m ahead: no floor to fit.
    "wall": lambda: Scene(boxes=((0.8, 1.0, -5.0, 5.0, 0.0, 3.0),)),
}


def triple(text: str) -> tuple[float, float, float]:
    h, p, r = (float(x) for x in text.split(","))
    return h, p, r


class Recorder:
    """What the node publishes, as plain data."""

    def __init__(self, ns: str, scan_frame: str) -> None:
        self.lock = threading.Lock()
        self.scans: list[dict[str, Any]] = []
        self.cliffs: list[dict[str, Any]] = []
        self.diags: list[dict[str, Any]] = []
        self.logs: list[dict[str, Any]] = []
        self.tfs: list[dict[str, Any]] = []
        self.scan_frame = scan_frame
        rospy.Subscriber(ns + "/scan", LaserScan, self.on_scan, (self.scans,), queue_size=100)
        rospy.Subscriber(ns + "/cliff_scan", LaserScan, self.on_scan, (self.cliffs,), queue_size=100)
        rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_diag, queue_size=100)
        rospy.Subscriber("/rosout", Log, self.on_log, queue_size=500)
        rospy.Subscriber("/tf", TFMessage, self.on_tf, queue_size=500)

    def on_scan(self, msg: LaserScan, into: tuple[list[dict[str, Any]]]) -> None:
        with self.lock:
            into[0].append(
                {
                    "stamp": msg.header.stamp.to_sec(),
                    "wall": time.time(),
                    "frame_id": msg.header.frame_id,
                    "range_min": msg.range_min,
                    "range_max": msg.range_max,
                    "ranges": list(msg.ranges),
                }
            )

    def on_diag(self, msg: DiagnosticArray) -> None:
        statuses = {}
        for st in msg.status:
            if "kinect_pipeline" not in st.name and "kinect_pipeline" not in st.hardware_id:
                continue
            statuses[st.name.split(": ", 1)[-1]] = {
                "level": int.from_bytes(st.level, "little") if isinstance(st.level, bytes) else int(st.level),
                "message": st.message,
                "values": {kv.key: kv.value for kv in st.values},
            }
        if statuses:
            with self.lock:
                self.diags.append({"stamp": msg.header.stamp.to_sec(), "wall": time.time(), "status": statuses})

    def on_log(self, msg: Log) -> None:
        with self.lock:
            self.logs.append({"level": msg.level, "name": msg.name, "msg": msg.msg})

    def on_tf(self, msg: TFMessage) -> None:
        for t in msg.transforms:
            if t.child_frame_id == self.scan_frame:
                q, p = t.transform.rotation, t.transform.translation
                with self.lock:
                    self.tfs.append(
                        {
                            "parent": t.header.frame_id,
                            "stamp": t.header.stamp.to_sec(),
                            "q": [q.x, q.y, q.z, q.w],
                            "t": [p.x, p.y, p.z],
                        }
                    )

    def diag(self, key: str, status: str | None = None) -> str | None:
        """The newest value of a diagnostics key (of one status, or of any)."""
        with self.lock:
            diags = list(self.diags)
        for d in reversed(diags):
            for name, st in d["status"].items():
                if (status is None or name == status) and key in st["values"]:
                    return st["values"][key]
        return None

    def num(self, key: str, status: str | None = None) -> float:
        v = self.diag(key, status)
        return float("nan") if v is None else float(v)


def frames_for(args: argparse.Namespace, scene_name: str) -> list[np.ndarray]:
    h, p, r = triple(args.render)
    seeds = [None] if args.noise_free else list(range(args.variants))
    frames = [render_frame(CAM, SCENES[scene_name](), h, p, r, args.encoding, seed=s).depth for s in seeds]
    return [window_of(d, window(args)) for d in frames]


def window(args: argparse.Namespace) -> tuple[int, ...]:
    """--window as binning_x, binning_y, x_offset, y_offset, width, height (all six 0 without it)."""
    return tuple(int(v) for v in args.window.split(",")) if args.window else (0,) * 6


def window_of(depth: np.ndarray, w: tuple[int, ...]) -> np.ndarray:
    """What image_proc's crop_decimate sends of a full frame: the roi, every binning-th column and row."""
    bx, by, x, y, rw, rh = max(w[0], 1), max(w[1], 1), *w[2:]
    rw, rh = (rw, rh) if rw else (depth.shape[1], depth.shape[0])
    return np.ascontiguousarray(depth[y : y + rh - rh % by : by, x : x + rw - rw % bx : bx])


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--deadline", type=float, default=60.0)
    ap.add_argument("--until", default="len(scans) >= 3")
    ap.add_argument("--ns", default="/kinect2")
    ap.add_argument("--image", default="sd/image_depth")
    ap.add_argument("--scan-frame", default="kinect2_scan")
    ap.add_argument("--transport", choices=["raw", "compressedDepth", "none"], default="raw")
    ap.add_argument("--codec", choices=["png", "rvl"], default="png")
    ap.add_argument("--encoding", choices=["16UC1", "32FC1"], default="16UC1")
    ap.add_argument("--scene", choices=list(SCENES), default="boxes")
    ap.add_argument("--render", default="1.1,0.26,0.0", help="true pose HEIGHT,PITCH,ROLL the frames are rendered at")
    ap.add_argument("--noise-free", action="store_true")
    ap.add_argument("--variants", type=int, default=4, help="noisy frames rendered (seeds 0..N-1), sent in turn")
    ap.add_argument("--tf", default=None, help="HEIGHT,PITCH,ROLL of the optical frame in base_footprint")
    ap.add_argument("--tf-frames", type=int, default=-1, help="stop tf after this many frames (-1: never)")
    ap.add_argument("--imu-pitch", type=float, default=None)
    ap.add_argument("--base-pitch", type=float, default=None)
    ap.add_argument("--rate", type=float, default=15.0)
    ap.add_argument("--bad-payload-every", type=int, default=0, help="every Nth compressed frame is garbage")
    ap.add_argument("--clock", type=float, default=None, help="publish /clock from this time [s]")
    ap.add_argument("--clock-jump", default=None, help="FRAME:T: at that frame the clock starts again from T")
    ap.add_argument("--switch-scene", default=None, help="SCENE:EXPR: render SCENE once EXPR holds")
    ap.add_argument("--distortion", default=None, help="K1,K2,P1,P2,K3: the camera_info's plumb_bob D (default: 0)")
    ap.add_argument("--off", choices=["K", "P"], default=None, help="that matrix's fx, fy 10 %% off, the other right")
    ap.add_argument(
        "--window",
        default=None,
        help="BX,BY,X,Y,W,H: send that window of each frame, as crop_decimate does (camera_info at full resolution)",
    )
    return ap.parse_args()


class Feeder:
    """Sends the frames (and tf, IMU, base pitch, /clock) as the options say, on the feeder's clock."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.rec = Recorder(args.ns, args.scan_frame)
        self.frames = frames_for(args, args.scene)
        image_topic = f"{args.ns}/{args.image}"
        self.info_pub = rospy.Publisher(image_topic.rsplit("/", 1)[0] + "/camera_info", CameraInfo, queue_size=5)
        self.image_pub = None
        if args.transport == "raw":
            self.image_pub = rospy.Publisher(image_topic, Image, queue_size=5)
        elif args.transport == "compressedDepth":
            self.image_pub = rospy.Publisher(image_topic + "/compressedDepth", CompressedImage, queue_size=5)
        self.imu_pub = rospy.Publisher("/imu", Imu, queue_size=5)
        self.pitch_pub = rospy.Publisher("/base_pitch", Float64, queue_size=5)
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
        self.tf = tf2_ros.TransformBroadcaster()
        self.sent: list[float] = []
        self.state: dict[str, Any] = {"switched": False}
        self.t0, self.wall0 = args.clock, time.monotonic()  # the feeder's clock: /clock from t0, or ROS time

    def now(self) -> rospy.Time:
        if self.t0 is None:
            return rospy.Time.now()
        return rospy.Time.from_sec(self.t0 + time.monotonic() - self.wall0)

    def env(self) -> dict[str, Any]:
        """What ``--until`` and ``--switch-scene`` see."""
        rec = self.rec
        with rec.lock:
            return {
                "scans": list(rec.scans),
                "cliffs": list(rec.cliffs),
                "diags": list(rec.diags),
                "logs": list(rec.logs),
                "tfs": list(rec.tfs),
                "sent": list(self.sent),
                "diag": rec.diag,
                "num": rec.num,
                "math": math,
                "switched": self.state["switched"],
            }

    def run(self) -> bool:
        """Sends frame after frame at ``--rate`` until ``--until`` holds (True) or the deadline passes (False)."""
        args = self.args
        jump_frame, jump_to = (-1, 0.0)
        if args.clock_jump:
            jump_frame, jump_to = int(args.clock_jump.split(":")[0]), float(args.clock_jump.split(":")[1])
        start = next_frame = time.monotonic()
        i = 0
        while time.monotonic() - start < args.deadline:
            if self.t0 is not None:
                self.clock_pub.publish(Clock(clock=self.now()))
            if time.monotonic() < next_frame:
                time.sleep(min(0.005, max(0.0, next_frame - time.monotonic())))
                continue
            next_frame += 1.0 / args.rate
            if i == jump_frame:
                self.t0, self.wall0 = jump_to, time.monotonic()
                self.clock_pub.publish(Clock(clock=self.now()))
            self.switch_scene()
            stamp = self.now()
            if args.transport != "none" and not stamp.is_zero():  # else only listening, or no /clock yet
                self.send(i, stamp)
                i += 1
            if eval(args.until, self.env()):
                return True
        return False

    def switch_scene(self) -> None:
        if self.args.switch_scene and not self.state["switched"]:
            scene, expr = self.args.switch_scene.split(":", 1)
            if eval(expr, self.env()):
                self.frames = frames_for(self.args, scene)
                self.state.update(switched=True, switched_at=len(self.sent))

    def send(self, i: int, stamp: rospy.Time) -> None:
        """Frame i, its camera_info and the pose sources the options name, at ``stamp``."""
        args = self.args
        if args.tf and (args.tf_frames < 0 or i < args.tf_frames):
            h, p, r = triple(args.tf)
            t = TransformStamped()
            t.header.stamp = stamp
            t.header.frame_id = "base_footprint"
            t.child_frame_id = OPTICAL
            t.transform.translation.x = 0.1
            t.transform.translation.z = h
            t.transform.rotation = optical_quaternion(p, r)
            self.tf.sendTransform(t)
            self.state["last_tf"] = stamp.to_sec()
        if args.imu_pitch is not None:
            imu = Imu()
            imu.header.stamp = stamp
            c, s = math.cos(args.imu_pitch / 2), math.sin(args.imu_pitch / 2)
            imu.orientation = Quaternion(x=0.0, y=s, z=0.0, w=c)
            self.imu_pub.publish(imu)
        if args.base_pitch is not None:
            self.pitch_pub.publish(Float64(data=args.base_pitch))
        info = CameraInfo()
        info.header.stamp = stamp
        info.header.frame_id = OPTICAL
        info.width, info.height = CAM.width, CAM.height
        info.K = [CAM.fx, 0, CAM.cx, 0, CAM.fy, CAM.cy, 0, 0, 1]
        info.P = [CAM.fx, 0, CAM.cx, 0, 0, CAM.fy, CAM.cy, 0, 0, 0, 1, 0]
        if args.off == "K":
            info.K[0], info.K[4] = 1.1 * CAM.fx, 1.1 * CAM.fy
        elif args.off == "P":
            info.P[0], info.P[5] = 1.1 * CAM.fx, 1.1 * CAM.fy
        if args.distortion:
            info.distortion_model, info.D = "plumb_bob", [float(v) for v in args.distortion.split(",")]
        w = window(args)
        info.binning_x, info.binning_y = w[0], w[1]
        info.roi.x_offset, info.roi.y_offset, info.roi.width, info.roi.height = w[2:]
        msg = self.image(i, info.header)
        self.info_pub.publish(info)
        if self.image_pub is not None:
            self.image_pub.publish(msg)
        self.sent.append(stamp.to_sec())

    def image(self, i: int, header: Any) -> Image | CompressedImage:
        """Frame i as the transport sends it (every ``--bad-payload-every``-th compressed one garbage)."""
        args, depth = self.args, self.frames[i % len(self.frames)]
        if args.transport == "raw":
            msg = Image()
            msg.header = header
            msg.height, msg.width = depth.shape
            msg.encoding = args.encoding
            msg.step = depth.strides[0]
            msg.data = depth.tobytes()
            return msg
        out = CompressedImage()
        out.header = header
        if args.bad_payload_every and i % args.bad_payload_every == args.bad_payload_every - 1:
            out.format, out.data = f"{args.encoding}; compressedDepth png", b"\x00" * 40
        else:
            out.format, data = kp.encode_compressed_depth(depth, codec=args.codec)
            out.data = bytes(data)
        return out


def main() -> int:
    args = parse_args()
    rospy.init_node("feeder", anonymous=True, disable_signals=True)
    feeder = Feeder(args)
    ok = feeder.run()
    result = feeder.env()
    for k in ("diag", "num", "math"):
        result.pop(k)
    result.update(ok=ok, state=feeder.state)
    with open(args.out, "w") as f:
        json.dump(result, f)
    said = "condition met" if ok else "deadline"
    print(f"feeder: {said} after {len(feeder.sent)} frames, {len(result['scans'])} scans", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
