"""ROS 1 bags of synthetic Segway sequences, written with the PyPI ``rosbags`` library (no ROS install needed).

The tf tree is the one of a Segway robot: ``base_footprint`` (on the floor, gravity-aligned) -> ``base_link``
(pitching about the wheel axle, on /tf every frame) -> ``kinect2_link`` (mounting, /tf_static) ->
``kinect2_depth_optical_frame`` (/tf_static); a level 2-D LiDAR ``laser`` on ``base_footprint``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core, kinect_v2_camera
from ..bags.messages import image_message, typestore
from ..bags.writer import BagWriter, output_format
from ..outputs import atomic_new, progress
from .robot import AXLE_HEIGHT, Rig, SegwayMotion
from .scenes import ENCODINGS, KEPT, Scene, ideal_scan, lab_scene, render_frame, truth_labels

_SUFFIX_FORMAT = {".mcap": "mcap", ".db3": "sqlite3"}  #: single-file rosbag2 bags


def _quat_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    q = _core.quaternion_from_rpy(roll, pitch, yaw)
    return (q[0], q[1], q[2], q[3])


# Optical frame in the sensor's body frame (x right, y down, z forward vs x forward, z up).
_OPTICAL_IN_BODY = (-0.5, 0.5, -0.5, 0.5)


def write_sequence_bag(
    path: Path,
    frames: int = 30,
    encoding: str = "16UC1",
    seed: int = 1,
    scene: Scene | None = None,
    rig: Rig | None = None,
    motion: SegwayMotion | None = None,
    rate_hz: float = 30.0,
    start_s: float = 1000.0,
    max_depth: float = 12.0,
    show_progress: bool = False,
    tof: bool = True,
    roll: float = 0.0,
    ceiling_height: float = 2.0,
    tf_error: tuple[float, float, float] = (0.0, 0.0, 0.0),
    fmt: str | None = None,
    info_after_image: bool = False,
    extras: bool = True,
    compressed: bool = False,
) -> dict[str, Any]:
    """Renders ``frames`` frames of a Segway driving in ``scene`` and writes depth, camera_info, tf and a LiDAR
    scan to a new bag at ``path`` (written to a temporary file, then renamed), with the ground truth of every
    frame: its per-pixel labels (``/ground_truth/labels``, mono8, the pipeline's label values) and the ideal scan
    (``/ground_truth/scan``: nearest obstacle below the ``ceiling_height`` plane per beam). ``tof`` adds flying
    pixels and the Kinect's range limit; ``roll`` is the sensor's roll on its mount [rad]. ``tf_error`` (height [m],
    pitch [rad], roll [rad]) is added to the mounting the bag's tf states (a wrong URDF: the frames are rendered
    at the true pose). ``fmt``: ros1, sqlite3 or mcap (rosbag2; a ``.mcap`` name is a single file), by default what
    the name says (ROS 1 unless it ends in .mcap or .db3); ``info_after_image`` writes each camera_info right after
    its image (some drivers do); ``extras=False`` leaves out the LiDAR and the ground truth (a plain camera bag);
    ``compressed`` writes the depth as ``<image topic>/compressedDepth`` (the core's PNG encoder; 16UC1 / 32FC1).
    Returns a summary."""
    if encoding not in ENCODINGS:
        raise ValueError(f"encoding {encoding!r}: expected one of {', '.join(ENCODINGS)}")
    if frames < 1:
        raise ValueError(f"frames = {frames}: expected >= 1")
    if compressed and encoding == "8UC1":
        raise ValueError("compressedDepth carries 16UC1 or 32FC1 depth, not 8UC1")
    if len(tf_error) != 3 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in tf_error):
        raise ValueError(f"tf_error = {tf_error!r}: expected three finite numbers (height [m], pitch, roll [rad])")
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} exists: not overwriting it")
    scene = scene or lab_scene()
    rig = rig or Rig()
    motion = motion or SegwayMotion()
    cam = kinect_v2_camera()
    ts = typestore()
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Image, CameraInfo, LaserScan = (
        T["sensor_msgs/msg/Image"],
        T["sensor_msgs/msg/CameraInfo"],
        T["sensor_msgs/msg/LaserScan"],
    )
    TFMessage, TransformStamped = T["tf2_msgs/msg/TFMessage"], T["geometry_msgs/msg/TransformStamped"]
    Transform, Vector3, Quaternion = (
        T["geometry_msgs/msg/Transform"],
        T["geometry_msgs/msg/Vector3"],
        T["geometry_msgs/msg/Quaternion"],
    )
    RegionOfInterest = T["sensor_msgs/msg/RegionOfInterest"]

    def stamp(t: float) -> Any:
        sec = math.floor(t)
        return Time(sec=sec, nanosec=round((t - sec) * 1e9) % 1_000_000_000)

    def tf(
        parent: str, child: str, t: float, xyz: tuple[float, float, float], q: tuple[float, float, float, float]
    ) -> Any:
        return TransformStamped(
            header=Header(seq=0, stamp=stamp(t), frame_id=parent),
            child_frame_id=child,
            transform=Transform(
                translation=Vector3(x=xyz[0], y=xyz[1], z=xyz[2]), rotation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
            ),
        )

    lidar_beams, lidar_min = 720, -math.pi * 0.75
    lidar_inc = 1.5 * math.pi / lidar_beams
    pitches: list[float] = []
    fmt = output_format(path, _SUFFIX_FORMAT.get(path.suffix.lower(), "ros1"), fmt)
    single = path.suffix.lower() in _SUFFIX_FORMAT
    with atomic_new(path) as tmp, BagWriter(tmp, fmt, single_file=single, name=path.name) as w:
        c_img = (
            w.add(rig.image_topic + "/compressedDepth", "sensor_msgs/msg/CompressedImage")
            if compressed
            else w.add(rig.image_topic, Image.__msgtype__)
        )
        c_info = w.add(rig.info_topic, CameraInfo.__msgtype__)
        c_tf = w.add("/tf", TFMessage.__msgtype__)
        c_tfs = w.add("/tf_static", TFMessage.__msgtype__, latching=True)
        if extras:
            c_lidar = w.add(rig.lidar_topic, LaserScan.__msgtype__)
            c_gt_labels = w.add("/ground_truth/labels", Image.__msgtype__)
            c_gt_scan = w.add("/ground_truth/scan", LaserScan.__msgtype__)
        # The beams of the pipeline's default scan, for the ideal scan.
        probe = _core.Pipeline(cam, _core.Config()).process(np.zeros((cam.height, cam.width), np.uint16))
        t0 = start_s
        static = TFMessage(
            transforms=[
                # Roll about the sensor's own axis after its tilt: R = Ry(tilt) Rx(roll), so that with the base's
                # pitch the total is Ry(base + tilt) Rx(roll), the renderer's convention, exactly.
                tf(
                    "base_link",
                    "kinect2_link",
                    t0,
                    (rig.kinect_xyz[0], rig.kinect_xyz[1], rig.kinect_xyz[2] + tf_error[0]),
                    _quat_from_rpy(roll + tf_error[2], rig.kinect_tilt + tf_error[1], 0.0),
                ),
                tf("kinect2_link", rig.optical_frame, t0, (0.0, 0.0, 0.0), _OPTICAL_IN_BODY),
                tf("base_footprint", "laser", t0, (0.2, 0.0, rig.lidar_height), (0.0, 0.0, 0.0, 1.0)),
            ]
        )
        w.write(c_tfs, int(t0 * 1e9), w.encode_ros1(static, TFMessage.__msgtype__))
        for i in progress(range(frames), frames, "synth") if show_progress else range(frames):
            t = t0 + 0.05 + i / rate_hz
            ns = round(t * 1e9)
            bp = motion.pitch(i)
            pitches.append(bp)
            px, _, total_pitch, height = rig.sensor_pose(bp)
            # The renderer's frame sits under the sensor: move the world by the sensor's x.
            shifted = Scene(
                boxes=tuple((b[0] - px, b[1] - px, *b[2:]) for b in scene.boxes),
                holes=tuple((h[0] - px, h[1] - px, h[2], h[3]) for h in scene.holes),
                hole_depth=scene.hole_depth,
                ceiling=scene.ceiling,
            )
            frame = render_frame(cam, shifted, height, total_pitch, roll, encoding, seed + i, max_depth, tof=tof)
            base = TFMessage(
                transforms=[tf("base_footprint", "base_link", t, (0.0, 0.0, AXLE_HEIGHT), _quat_from_rpy(0.0, bp, 0.0))]
            )
            w.write(c_tf, ns, w.encode_ros1(base, TFMessage.__msgtype__))
            header = Header(seq=i, stamp=stamp(t), frame_id=rig.optical_frame)
            depth = np.ascontiguousarray(frame.depth)
            img = image_message(T, header, depth, encoding)
            if compressed:
                fmt_text, payload = _core.encode_compressed_depth(depth)
                img = T["sensor_msgs/msg/CompressedImage"](
                    header=header, format=fmt_text, data=np.frombuffer(payload, np.uint8)
                )
            info = CameraInfo(
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
                roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
            )
            first, second = ((c_img, img), (c_info, info)) if info_after_image else ((c_info, info), (c_img, img))
            for k, (c, msg) in enumerate((first, second)):
                w.write(c, ns + 1 + k, w.encode_ros1(msg, c.msgtype))
            if not extras:
                continue
            lidar_boxes = [(b[0] - 0.2, b[1] - 0.2, *b[2:]) for b in scene.boxes]
            ranges = _core.render_lidar(lidar_boxes, rig.lidar_height, lidar_min, lidar_inc, lidar_beams, 30.0)
            scan = LaserScan(
                header=Header(seq=i, stamp=stamp(t), frame_id="laser"),
                angle_min=lidar_min,
                angle_max=lidar_min + lidar_inc * (lidar_beams - 1),
                angle_increment=lidar_inc,
                time_increment=0.0,
                scan_time=1.0 / rate_hz,
                range_min=0.05,
                range_max=30.0,
                ranges=ranges,
                intensities=np.zeros(0, np.float32),
            )
            w.write(c_lidar, ns + 3, w.encode_ros1(scan, LaserScan.__msgtype__))
            labels = truth_labels(frame.truth, ceiling_height)
            gt_img = Image(
                header=header,
                height=labels.shape[0],
                width=labels.shape[1],
                encoding="mono8",
                is_bigendian=0,
                step=labels.shape[1],
                data=labels.reshape(-1),
            )
            w.write(c_gt_labels, ns + 4, w.encode_ros1(gt_img, Image.__msgtype__))
            # The ideal scan is seen from the optical centre, as the pipeline's (x shifted by px).
            ideal = ideal_scan(frame.truth, probe.angle_min, probe.angle_increment, len(probe.ranges), labels == KEPT)
            gt_scan = LaserScan(
                header=Header(seq=i, stamp=stamp(t), frame_id="kinect2_scan"),
                angle_min=probe.angle_min,
                angle_max=probe.angle_max,
                angle_increment=probe.angle_increment,
                time_increment=0.0,
                scan_time=1.0 / rate_hz,
                range_min=probe.range_min,
                range_max=probe.range_max,
                ranges=ideal.astype(np.float32),
                intensities=np.zeros(0, np.float32),
            )
            w.write(c_gt_scan, ns + 5, w.encode_ros1(gt_scan, LaserScan.__msgtype__))
    return {
        "path": str(path),
        "frames": frames,
        "encoding": encoding,
        "image_topic": rig.image_topic + ("/compressedDepth" if compressed else ""),
        "base_pitch_deg_range": [math.degrees(min(pitches)), math.degrees(max(pitches))],
        "tf_error": {
            "height": tf_error[0],
            "pitch_deg": math.degrees(tf_error[1]),
            "roll_deg": math.degrees(tf_error[2]),
        },
    }
