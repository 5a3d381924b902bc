"""Messages of either ROS version: the definitions (one typestore per ROS version) and helpers that read and build
them. ROS 2 has no ``seq`` and spells CameraInfo's ``K`` as ``k``; the depth image and camera conversions are the C++
core's, the ones the ROS node uses.
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Any

import numpy as np

from .. import _core
from .ros1 import BagError

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
TF_TOPICS = ("/tf", "/tf_static")


def typestore(ros2: bool = False) -> Any:
    """The message definitions of a bag: ROS 2 Humble's, or ROS 1 Noetic's with tf2_msgs/TFMessage added."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if ros2:
        return get_typestore(Stores.ROS2_HUMBLE)
    ts = get_typestore(Stores.ROS1_NOETIC)
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    return ts


def stamp(msg: Any) -> float:
    """The header stamp [s] of a message."""
    s = msg.header.stamp
    return float(s.sec + s.nanosec * 1e-9)


def intrinsics_matrix(info: Any) -> list[float]:
    """K of a CameraInfo (ROS 1 ``K``, ROS 2 ``k``), row-major."""
    k = info.k if hasattr(info, "k") else info.K
    return [float(v) for v in k]


def distortion_of(info: Any) -> tuple[str, list[float], list[float]]:
    """distortion_model, D and R of a CameraInfo (ROS 1 ``D``, ``R``; ROS 2 ``d``, ``r``; R empty where absent)."""

    def field(name: str) -> list[float]:
        v = getattr(info, name.lower(), None)
        v = getattr(info, name, []) if v is None else v
        return [float(x) for x in v]

    return str(getattr(info, "distortion_model", "")), field("D"), field("R")


def camera_from_info(info: Any, rectified: bool = False) -> Any:
    """The core's camera of the images a CameraInfo goes with, its ROI and binning applied (the node's checks: K[0] =
    0 is an uncalibrated camera). ``rectified``: of a rectified image, whose camera is P's where P is set (as
    image_geometry takes it; the node's rectifiedCameraFromInfo)."""
    k = intrinsics_matrix(info)
    if rectified:
        p = getattr(info, "p", None)
        p = getattr(info, "P", None) if p is None else p
        k = (_core.rectified_intrinsics([float(v) for v in p]) if p is not None and len(p) == 12 else None) or k
    roi = getattr(info, "roi", None)  # every CameraInfo has it; a message-like object may not
    window = (0, 0, 0, 0) if roi is None else (int(roi.x_offset), int(roi.y_offset), int(roi.width), int(roi.height))
    try:
        return _core.camera_from_intrinsics(
            int(info.width),
            int(info.height),
            k,
            info.header.frame_id,
            binning_x=int(getattr(info, "binning_x", 0)),
            binning_y=int(getattr(info, "binning_y", 0)),
            roi=window,
        )
    except ValueError as exc:
        raise BagError(str(exc)) from exc


#: The transports of a depth image whose topics the tools read: image_transport's ``compressedDepth`` plugin, and
#: its ``compressed`` plugin where it holds a lossless PNG of 16-bit or 8-bit depth (``16UC1; png compressed``).
TRANSPORTS = ("/compressedDepth", "/compressed")


def is_compressed_depth(msgtype: str, topic: str) -> bool:
    """A CompressedImage topic of a transport the tools read (``…/compressedDepth``, ``…/compressed``)."""
    return msgtype == COMPRESSED and topic.rstrip("/").endswith(TRANSPORTS)


def depth_array(msg: Any) -> np.ndarray:
    """The depth image of an Image, a compressedDepth or a PNG ``compressed`` CompressedImage message as a 2-D
    array (uint8, uint16 mm or float32 m), through the core's conversions; a message it cannot read raises
    BagError saying why (and, for a format it does not read, what it reads)."""
    try:
        if hasattr(msg, "encoding"):
            return np.asarray(
                _core.depth_from_buffer(msg.encoding, msg.width, msg.height, msg.step, bool(msg.is_bigendian), msg.data)
            )
        decode = getattr(_core, "decode_compressed_depth", None)
        if decode is None:
            raise BagError("compressed depth images: this build of the core has no decoder")
        # Which formats are depth (compressedDepth, a PNG of 16-bit depth) is the core's rule: it names the others.
        return np.asarray(decode(str(msg.format), msg.data))
    except (ValueError, TypeError) as exc:
        raise BagError(str(exc)) from exc


def header(types: Any, stamp_msg: Any, frame_id: str, seq: int = 0) -> Any:
    """A std_msgs/Header of the typestore's definition (ROS 1 with ``seq``, ROS 2 without)."""
    Header = types["std_msgs/msg/Header"]
    fields = {f.name for f in dataclasses.fields(Header)}
    kw: dict[str, Any] = {"stamp": stamp_msg, "frame_id": frame_id}
    if "seq" in fields:
        kw["seq"] = seq
    return Header(**kw)


def image_message(types: Any, header_msg: Any, depth: np.ndarray, encoding: str) -> Any:
    """A sensor_msgs/Image of a 2-D array (host byte order) with this header and encoding."""
    depth = np.ascontiguousarray(depth)
    return types[IMAGE](
        header=header_msg,
        height=depth.shape[0],
        width=depth.shape[1],
        encoding=encoding,
        is_bigendian=int(sys.byteorder == "big"),
        step=depth.strides[0],
        data=depth.view(np.uint8).reshape(-1),
    )
