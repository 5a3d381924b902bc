#!/usr/bin/env python3
"""rostest of a README launch example (test/ros/driver_topics.test): frames on the driver's own topics give a
scan on <camera>/scan, and the node runs with the sensor_model preset's parameters (an explicit curve wins)."""

from __future__ import annotations

import sys
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from sensor_msgs.msg import CameraInfo, Image, LaserScan

import kinect_pipeline as kp
from kinect_pipeline.simulation.scenes import boxes_scene, render_frame

DEADLINE = 30.0


class DriverTopics(unittest.TestCase):
    @classmethod
    def setUpClass(cls) -> None:
        rospy.init_node("driver_topics_test", anonymous=True)
        cls.camera = rospy.get_param("~camera").strip("/")
        cls.image = rospy.get_param("~image")
        cls.model = kp.sensor_model(rospy.get_param("~sensor_model"))
        cls.curve = rospy.get_param("~curve", "")
        cls.prefix = f"/{cls.camera}" if cls.camera else ""
        cls.scans: list[LaserScan] = []
        rospy.Subscriber(f"{cls.prefix}/scan", LaserScan, cls.scans.append)
        image_topic = f"{cls.prefix}/{cls.image}"
        cls.info_topic = image_topic.rsplit("/", 1)[0] + "/camera_info"
        cls.image_pub = rospy.Publisher(image_topic, Image, queue_size=2)
        cls.info_pub = rospy.Publisher(cls.info_topic, CameraInfo, queue_size=2)
        cls.stop = False
        cls.thread = threading.Thread(target=cls.feed, daemon=True)
        cls.thread.start()

    @classmethod
    def tearDownClass(cls) -> None:
        cls.stop = True
        cls.thread.join(timeout=5)

    @classmethod
    def feed(cls) -> None:
        cam = cls.model["camera"]
        depth = render_frame(cam, boxes_scene(), 1.1, 0.26, 0.0, "16UC1", seed=3).depth
        rate = rospy.Rate(10)
        while not cls.stop and not rospy.is_shutdown():
            stamp = rospy.Time.now()
            img = Image(encoding="16UC1", height=cam.height, width=cam.width, step=2 * cam.width)
            img.header.stamp, img.header.frame_id = stamp, "camera_depth_optical_frame"
            img.data = np.ascontiguousarray(depth).tobytes()
            info = CameraInfo(width=cam.width, height=cam.height, distortion_model="plumb_bob", D=[0.0] * 5)
            info.header = img.header
            info.K = [cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1]
            info.P = [cam.fx, 0, cam.cx, 0, 0, cam.fy, cam.cy, 0, 0, 0, 1, 0]
            cls.info_pub.publish(info)
            cls.image_pub.publish(img)
            rate.sleep()

    def wait_for_scan(self) -> LaserScan:
        deadline = time.monotonic() + DEADLINE
        while not self.scans and time.monotonic() < deadline and not rospy.is_shutdown():
            time.sleep(0.05)
        self.assertTrue(self.scans, f"no scan on {self.prefix}/scan within {DEADLINE:g} s")
        return self.scans[-1]

    def test_the_drivers_topics_give_a_scan_with_the_presets_range(self) -> None:
        scan = self.wait_for_scan()
        self.assertEqual(len(scan.ranges), self.model["camera"].width)
        self.assertAlmostEqual(scan.range_max, self.model["range_max"], places=5)
        self.assertTrue(np.isfinite(np.array(scan.ranges)).any(), "the boxes are seen")

    def test_the_node_runs_with_the_presets_parameters(self) -> None:
        self.wait_for_scan()
        node = f"{self.prefix}/kinect_pipeline"
        curve = rospy.get_param(f"{node}/threshold_curve")
        want = self.curve or self.model["threshold_curve"]
        self.assertEqual(
            kp.Config(threshold_curve=curve).threshold_curve, kp.Config(threshold_curve=want).threshold_curve
        )
        self.assertEqual(rospy.get_param(f"{node}/cliff_min_pixels"), self.model["cliff_min_pixels"])


if __name__ == "__main__":
    rostest.rosrun("kinect_pipeline", "driver_topics", DriverTopics, sys.argv)
