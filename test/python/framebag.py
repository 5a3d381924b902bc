"""A ROS 1 bag of depth frames, each with its camera_info, as a camera driver records them (written with rosbags)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

ENCODING = {np.dtype(np.uint16): "16UC1", np.dtype(np.float32): "32FC1", np.dtype(np.uint8): "8UC1"}


def write_frames_bag(
    path: Path, frames: Sequence[np.ndarray], infos: Sequence[dict[str, Any]], topic: str = "/cam/depth/image_raw"
) -> None:
    """Frame i at 10 + i s on ``topic`` (its encoding from its dtype; a 32FC1 frame may hold millimetres), and its
    camera_info beside it 1 ns later (none where ``infos`` is empty): ``infos[i]`` (the last one for the rest) gives
    ``width``, ``height``, ``K`` (9) and optionally ``distortion_model`` and ``D`` (plumb_bob, zeros), ``R`` (the
    identity), ``P`` (zeros: not set), ``binning`` (x, y) and ``roi`` (x_offset, y_offset, width, height; 0: all)."""
    from kinect_pipeline.bags.writer import BagWriter

    w = BagWriter(path, "ros1")
    T = w.types
    c_img = w.add(topic, "sensor_msgs/msg/Image")
    c_info = w.add(topic.rsplit("/", 1)[0] + "/camera_info", "sensor_msgs/msg/CameraInfo") if infos else None
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    for i, px in enumerate(frames):
        head = Header(seq=i, stamp=Time(sec=10 + i, nanosec=0), frame_id="cam")
        img = T["sensor_msgs/msg/Image"](
            header=head,
            height=px.shape[0],
            width=px.shape[1],
            encoding=ENCODING[px.dtype],
            is_bigendian=0,
            step=px.strides[0],
            data=np.ascontiguousarray(px).view(np.uint8).reshape(-1),
        )
        w.write(c_img, (10 + i) * 10**9, w.encode(img, "sensor_msgs/msg/Image"))
        if c_info is None:
            continue
        info = infos[min(i, len(infos) - 1)]
        x, y, rw, rh = info.get("roi", (0, 0, 0, 0))
        bx, by = info.get("binning", (0, 0))
        msg = T["sensor_msgs/msg/CameraInfo"](
            header=head,
            height=info["height"],
            width=info["width"],
            distortion_model=info.get("distortion_model", "plumb_bob"),
            D=np.array(info.get("D", np.zeros(5)), float),
            K=np.array(info["K"], float),
            R=np.array(info.get("R", np.eye(3).reshape(-1)), float),
            P=np.array(info.get("P", np.zeros(12)), float),
            binning_x=bx,
            binning_y=by,
            roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=x, y_offset=y, height=rh, width=rw, do_rectify=False),
        )
        w.write(c_info, (10 + i) * 10**9 + 1, w.encode(msg, "sensor_msgs/msg/CameraInfo"))
    w.close()
