#!/usr/bin/env python3
"""A fresh ROS client for test/python/test_ros_restart.py: publishes depth + camera_info at 15 Hz on /cam and exits 0
once the node under test answered with ``--scans`` scans on /scan (after ``--range-max`` was set through
dynamic_reconfigure, if given), or 1 at the deadline. Started anew after each master restart, so it registers with
the master of the moment: only the node under test has to survive the restart."""

from __future__ import annotations

import argparse
import sys
import threading
import time

import numpy as np
import rospy
from sensor_msgs.msg import CameraInfo, Image, LaserScan


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scans", type=int, default=3)
    ap.add_argument("--range-max", type=float, default=None)
    ap.add_argument("--node", default="/kp")
    ap.add_argument("--deadline", type=float, default=40.0)
    args = ap.parse_args()
    rospy.init_node("restart_helper", anonymous=True, disable_signals=True)
    got: list[LaserScan] = []
    lock = threading.Lock()

    def on_scan(msg: LaserScan) -> None:
        with lock:
            got.append(msg)

    rospy.Subscriber("/scan", LaserScan, on_scan, queue_size=20)
    image_pub = rospy.Publisher("/cam/image_depth", Image, queue_size=2)
    info_pub = rospy.Publisher("/cam/camera_info", CameraInfo, queue_size=2)
    w, h = 64, 53
    depth = np.full((h, w), 2000, np.uint16)
    start = time.monotonic()
    reconfigured_at: rospy.Time | None = None

    def wanted() -> int:
        with lock:
            scans = [s for s in got if reconfigured_at is None or s.header.stamp > reconfigured_at]
        if args.range_max is not None:
            scans = [s for s in scans if abs(s.range_max - args.range_max) < 1e-6]
        return len(scans)

    while time.monotonic() - start < args.deadline:
        stamp = rospy.Time.now()
        info = CameraInfo()
        info.header.stamp = stamp
        info.header.frame_id = "cam_optical"
        info.width, info.height = w, h
        info.K = [45.0, 0, 31.5, 0, 45.0, 26.0, 0, 0, 1]
        img = Image()
        img.header = info.header
        img.width, img.height, img.encoding, img.step = w, h, "16UC1", 2 * w
        img.data = depth.tobytes()
        info_pub.publish(info)
        image_pub.publish(img)
        if args.range_max is not None and reconfigured_at is None and len(got) >= 1:
            from dynamic_reconfigure.client import Client

            Client(args.node, timeout=10.0).update_configuration({"range_max": args.range_max})
            reconfigured_at = rospy.Time.now()
        if wanted() >= args.scans:
            print(f"restart_helper: {wanted()} scans from the node", flush=True)
            return 0
        time.sleep(1.0 / 15)
    print(f"restart_helper: {len(got)} scans in {args.deadline} s (wanted {args.scans})", flush=True)
    return 1


if __name__ == "__main__":
    sys.exit(main())
