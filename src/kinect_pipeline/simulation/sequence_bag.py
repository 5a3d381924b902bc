"""Bags of synthetic Segway sequences with their ground truth, written with the PyPI ``rosbags`` library (no ROS
install needed).

The tf tree is the one of a Segway robot: ``base_footprint`` (on the floor, gravity-aligned) -> ``base_link``
(pitching about the wheel axle, on /tf every frame) -> ``kinect2_link`` (mounting, /tf_static) ->
``kinect2_depth_optical_frame`` (/tf_static); a level 2-D LiDAR ``laser`` on ``base_footprint``.

>>> write_sequence_bag(Path("lab.bag"), Scenario(frames=40, encoding="8UC1"))  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core, kinect_v2_camera
from ..bags.messages import CAMERA_INFO, COMPRESSED, IMAGE, LASER_SCAN, image_message, typestore
from ..bags.writer import BagWriter, output_format
from ..outputs import atomic_new, progress
from .robot import AXLE_HEIGHT, Rig, SegwayMotion
from .scenes import ENCODINGS, KEPT, Frame, Scene, ideal_scan, lab_scene, render_frame, truth_labels

_SUFFIX_FORMAT = {".mcap": "mcap", ".db3": "sqlite3"}  #: single-file rosbag2 bags
_OPTICAL_IN_BODY = (-0.5, 0.5, -0.5, 0.5)  #: optical frame (x right, y down, z forward) in the sensor's body frame
_LIDAR_BEAMS, _LIDAR_MIN = 720, -math.pi * 0.75
_LIDAR_INC = 1.5 * math.pi / _LIDAR_BEAMS
_LIDAR_X = 0.2  #: the LiDAR ahead of base_footprint [m]
_LIDAR_RANGE = 30.0
_TF_MESSAGE = "tf2_msgs/msg/TFMessage"
_ROI = "sensor_msgs/msg/RegionOfInterest"


@dataclass(frozen=True)
class Scenario:
    """What a synthetic sequence shows: the scene, the robot and its motion, the sensor's artefacts, the mistakes in
    its tf, and what the bag holds besides the depth frames."""

    frames: int = 30
    encoding: str = "16UC1"  #: 8UC1, 16UC1 or 32FC1
    seed: int = 1  #: the noise of frame i is seeded with seed + i
    scene: Scene = field(default_factory=lab_scene)
    rig: Rig = field(default_factory=Rig)
    motion: SegwayMotion = field(default_factory=SegwayMotion)
    rate_hz: float = 30.0
    start_s: float = 1000.0  #: the stamp of /tf_static [s]; frame i is at start_s + 0.05 + i / rate_hz
    max_depth: float = 12.0  #: the 8UC1 encoding's range [m]
    tof: bool = True  #: flying pixels and the Kinect's range limit
    roll: float = 0.0  #: the sensor's roll on its mount [rad]
    ceiling_height: float = 2.0  #: the ground truth's ceiling plane [m]
    #: (height [m], pitch [rad], roll [rad]) added to the mounting the bag's tf states (a wrong URDF: the frames are
    #: rendered at the true pose)
    tf_error: tuple[float, float, float] = (0.0, 0.0, 0.0)
    info_after_image: bool = False  #: each camera_info right after its image (some drivers do)
    extras: bool = True  #: the LiDAR and the ground truth; False: a plain camera bag
    compressed: bool = False  #: the depth as ``<image topic>/compressedDepth`` (16UC1 / 32FC1)

    def check(self) -> None:
        """Raises ValueError naming the first value a bag cannot be written with."""
        if self.encoding not in ENCODINGS:
            raise ValueError(f"encoding {self.encoding!r}: expected one of {', '.join(ENCODINGS)}")
        if self.frames < 1:
            raise ValueError(f"frames = {self.frames}: expected >= 1")
        if self.compressed and self.encoding == "8UC1":
            raise ValueError("compressedDepth carries 16UC1 or 32FC1 depth, not 8UC1")
        err = self.tf_error
        if len(err) != 3 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in err):
            raise ValueError(f"tf_error = {err!r}: expected three finite numbers (height [m], pitch, roll [rad])")

    def stamp(self, i: int) -> float:
        """The stamp of frame ``i`` [s]."""
        return self.start_s + 0.05 + i / self.rate_hz


def write_sequence_bag(
    path: Path, scenario: Scenario | None = None, fmt: str | None = None, show_progress: bool = False
) -> dict[str, Any]:
    """Renders the frames of ``scenario`` (the default one when None) and writes depth, camera_info, tf and, with
    ``extras``, a LiDAR scan and the ground truth of every frame (its per-pixel labels on ``/ground_truth/labels``,
    mono8 with the pipeline's label values, and the ideal scan on ``/ground_truth/scan``: the nearest obstacle below
    the ceiling plane per beam) to a new bag at ``path`` (written to a temporary file, then renamed; an existing
    ``path`` raises FileExistsError). ``fmt``: ros1, sqlite3 or mcap (rosbag2; a ``.mcap`` name is a single file),
    by default what the name says (ROS 1 unless it ends in .mcap or .db3). Returns a summary."""
    sc = scenario or Scenario()
    sc.check()
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} exists: not overwriting it")
    fmt = output_format(path, _SUFFIX_FORMAT.get(path.suffix.lower(), "ros1"), fmt)
    single = path.suffix.lower() in _SUFFIX_FORMAT
    pitches = [sc.motion.pitch(i) for i in range(sc.frames)]
    with atomic_new(path) as tmp, BagWriter(tmp, fmt, single_file=single, name=path.name) as w:
        out = _SequenceWriter(w, sc)
        out.write_static()
        for i in progress(range(sc.frames), sc.frames, "synth") if show_progress else range(sc.frames):
            out.write_frame(i, pitches[i])
    return _summary(path, sc, pitches)


def _summary(path: Path, sc: Scenario, pitches: list[float]) -> dict[str, Any]:
    return {
        "path": str(path),
        "frames": sc.frames,
        "encoding": sc.encoding,
        "image_topic": sc.rig.image_topic + ("/compressedDepth" if sc.compressed else ""),
        "base_pitch_deg_range": [math.degrees(min(pitches)), math.degrees(max(pitches))],
        "tf_error": {
            "height": sc.tf_error[0],
            "pitch_deg": math.degrees(sc.tf_error[1]),
            "roll_deg": math.degrees(sc.tf_error[2]),
        },
    }


def _quat_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    q = _core.quaternion_from_rpy(roll, pitch, yaw)
    return (q[0], q[1], q[2], q[3])


def _under_sensor(scene: Scene, px: float) -> Scene:
    """``scene`` in the renderer's frame, which sits under the sensor: the world moved by the sensor's x."""
    return Scene(
        boxes=tuple((b[0] - px, b[1] - px, *b[2:]) for b in scene.boxes),
        holes=tuple((h[0] - px, h[1] - px, h[2], h[3]) for h in scene.holes),
        hole_depth=scene.hole_depth,
        ceiling=scene.ceiling,
    )


class _SequenceWriter:
    """The connections of a sequence bag and the messages of each frame (ROS 1 definitions, converted by the writer
    for rosbag2)."""

    def __init__(self, w: BagWriter, sc: Scenario) -> None:
        self.w, self.sc, self.cam = w, sc, kinect_v2_camera()
        self.T = typestore().types
        rig = sc.rig
        if sc.compressed:
            self.c_img = w.add(rig.image_topic + "/compressedDepth", COMPRESSED)
        else:
            self.c_img = w.add(rig.image_topic, IMAGE)
        self.c_info = w.add(rig.info_topic, CAMERA_INFO)
        self.c_tf = w.add("/tf", _TF_MESSAGE)
        self.c_tfs = w.add("/tf_static", _TF_MESSAGE, latching=True)
        if sc.extras:
            self.c_lidar = w.add(rig.lidar_topic, LASER_SCAN)
            self.c_gt_labels = w.add("/ground_truth/labels", IMAGE)
            self.c_gt_scan = w.add("/ground_truth/scan", LASER_SCAN)
        # The beams of the pipeline's default scan, for the ideal scan.
        cam = self.cam
        self.probe = _core.Pipeline(cam, _core.Config()).process(np.zeros((cam.height, cam.width), np.uint16))

    def put(self, conn: Any, t_ns: int, msg: Any) -> None:
        self.w.write(conn, t_ns, self.w.encode_ros1(msg, msg.__msgtype__))

    def time(self, t: float) -> Any:
        sec = math.floor(t)
        return self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9) % 1_000_000_000)

    def header(self, seq: int, t: float, frame_id: str) -> Any:
        return self.T["std_msgs/msg/Header"](seq=seq, stamp=self.time(t), frame_id=frame_id)

    def transform(
        self, parent: str, child: str, t: float, xyz: tuple[float, float, float], q: tuple[float, float, float, float]
    ) -> Any:
        T = self.T
        return T["geometry_msgs/msg/TransformStamped"](
            header=self.header(0, t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
            ),
        )

    def write_static(self) -> None:
        """The mounting of the Kinect (with the scenario's tf error) and of the LiDAR, on /tf_static."""
        sc, rig, t0 = self.sc, self.sc.rig, self.sc.start_s
        err = sc.tf_error
        mount = (rig.kinect_xyz[0], rig.kinect_xyz[1], rig.kinect_xyz[2] + err[0])
        static = self.T[_TF_MESSAGE](
            transforms=[
                # Roll about the sensor's own axis after its tilt: R = Ry(tilt) Rx(roll), so that with the base's
                # pitch the total is Ry(base + tilt) Rx(roll), the renderer's convention, exactly.
                self.transform(
                    "base_link",
                    "kinect2_link",
                    t0,
                    mount,
                    _quat_from_rpy(sc.roll + err[2], rig.kinect_tilt + err[1], 0.0),
                ),
                self.transform("kinect2_link", rig.optical_frame, t0, (0.0, 0.0, 0.0), _OPTICAL_IN_BODY),
                self.transform("base_footprint", "laser", t0, (_LIDAR_X, 0.0, rig.lidar_height), (0.0, 0.0, 0.0, 1.0)),
            ]
        )
        self.put(self.c_tfs, int(t0 * 1e9), static)

    def write_frame(self, i: int, base_pitch: float) -> None:
        """Frame ``i`` with the base pitched by ``base_pitch``: the base's tf, the depth and its camera_info, and
        with ``extras`` the LiDAR scan and the ground truth."""
        sc = self.sc
        t = sc.stamp(i)
        ns = round(t * 1e9)
        px, _, total_pitch, height = sc.rig.sensor_pose(base_pitch)
        scene = _under_sensor(sc.scene, px)
        frame = render_frame(
            self.cam, scene, height, total_pitch, sc.roll, sc.encoding, sc.seed + i, sc.max_depth, tof=sc.tof
        )
        base = self.transform(
            "base_footprint", "base_link", t, (0.0, 0.0, AXLE_HEIGHT), _quat_from_rpy(0, base_pitch, 0)
        )
        self.put(self.c_tf, ns, self.T[_TF_MESSAGE](transforms=[base]))
        header = self.header(i, t, sc.rig.optical_frame)
        image, info = (self.c_img, self.depth_message(header, frame)), (self.c_info, self.camera_info(header))
        for k, (conn, msg) in enumerate((image, info) if sc.info_after_image else (info, image)):
            self.w.write(conn, ns + 1 + k, self.w.encode_ros1(msg, conn.msgtype))
        if sc.extras:
            self.put(self.c_lidar, ns + 3, self.lidar_scan(i, t))
            self.write_truth(i, t, ns, header, frame)

    def depth_message(self, header: Any, frame: Frame) -> Any:
        depth = np.ascontiguousarray(frame.depth)
        if not self.sc.compressed:
            return image_message(self.T, header, depth, self.sc.encoding)
        fmt_text, payload = _core.encode_compressed_depth(depth)
        return self.T[COMPRESSED](header=header, format=fmt_text, data=np.frombuffer(payload, np.uint8))

    def camera_info(self, header: Any) -> Any:
        cam, T = self.cam, self.T
        return T[CAMERA_INFO](
            header=header,
            height=cam.height,
            width=cam.width,
            distortion_model="plumb_bob",
            D=np.zeros(5),
            K=np.array([cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1.0]),
            R=np.eye(3).reshape(-1),
            P=np.array([cam.fx, 0, cam.cx, 0, 0, cam.fy, cam.cy, 0, 0, 0, 1.0, 0]),
            binning_x=0,
            binning_y=0,
            roi=T[_ROI](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
        )

    def scan(
        self, header: Any, angles: tuple[float, float, float], ranges: np.ndarray, limits: tuple[float, float]
    ) -> Any:
        """A LaserScan over ``angles`` (min, max, increment [rad]) with range ``limits`` (min, max [m])."""
        return self.T[LASER_SCAN](
            header=header,
            angle_min=angles[0],
            angle_max=angles[1],
            angle_increment=angles[2],
            time_increment=0.0,
            scan_time=1.0 / self.sc.rate_hz,
            range_min=limits[0],
            range_max=limits[1],
            ranges=ranges,
            intensities=np.zeros(0, np.float32),
        )

    def lidar_scan(self, i: int, t: float) -> Any:
        """The level LiDAR's scan of the scene's boxes (no noise)."""
        boxes = [(b[0] - _LIDAR_X, b[1] - _LIDAR_X, *b[2:]) for b in self.sc.scene.boxes]
        lidar_height = self.sc.rig.lidar_height
        ranges = _core.render_lidar(boxes, lidar_height, _LIDAR_MIN, _LIDAR_INC, _LIDAR_BEAMS, _LIDAR_RANGE)
        angles = (_LIDAR_MIN, _LIDAR_MIN + _LIDAR_INC * (_LIDAR_BEAMS - 1), _LIDAR_INC)
        return self.scan(self.header(i, t, "laser"), angles, ranges, (0.05, _LIDAR_RANGE))

    def write_truth(self, i: int, t: float, ns: int, header: Any, frame: Frame) -> None:
        """The frame's true labels (mono8) and its ideal scan, seen from the optical centre as the pipeline's."""
        labels = truth_labels(frame.truth, self.sc.ceiling_height)
        gt_img = self.T[IMAGE](
            header=header,
            height=labels.shape[0],
            width=labels.shape[1],
            encoding="mono8",
            is_bigendian=0,
            step=labels.shape[1],
            data=labels.reshape(-1),
        )
        self.put(self.c_gt_labels, ns + 4, gt_img)
        p = self.probe
        ideal = ideal_scan(frame.truth, p.angle_min, p.angle_increment, len(p.ranges), labels == KEPT)
        gt_header = self.header(i, t, "kinect2_scan")
        angles = (p.angle_min, p.angle_max, p.angle_increment)
        gt_scan = self.scan(gt_header, angles, ideal.astype(np.float32), (p.range_min, p.range_max))
        self.put(self.c_gt_scan, ns + 5, gt_scan)
