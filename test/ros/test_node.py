#!/usr/bin/env python3
"""rostest of the node / nodelet wiring: depth + camera_info + tf in, LaserScan + cleaned image out, as the core
predicts. Run by test/ros/node.test and test/ros/nodelet.test (real roscore, real nodelet manager)."""

from __future__ import annotations

import math
import sys
import threading
import time
import unittest
from typing import Callable

import numpy as np
import rospy
import rostest
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray
from dynamic_reconfigure.client import Client
from geometry_msgs.msg import Quaternion, TransformStamped
from sensor_msgs.msg import CameraInfo, Image, Imu, LaserScan

import kinect_pipeline as kp
from kinect_pipeline.scenes import boxes_scene, render_frame

NODE = "/kinect2/kinect_pipeline"
HEIGHT, TILT = 1.1, 0.26
CAM = kp.Camera(512, 424, 365.0, 365.0, 255.5, 211.5)
DEADLINE = 20.0


def quaternion_from_matrix(m: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix (upper-left 3x3 of m)."""
    r = m[:3, :3]
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2
    y = math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2
    z = math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2
    x = math.copysign(x, r[2, 1] - r[1, 2])
    y = math.copysign(y, r[0, 2] - r[2, 0])
    z = math.copysign(z, r[1, 0] - r[0, 1])
    return x, y, z, w


def optical_quaternion(pitch: float, roll: float = 0.0) -> Quaternion:
    """Orientation of the optical frame in base_footprint for a sensor pitched down by ``pitch``."""
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    body_from_optical = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]])  # optical axes in the body frame
    m = np.eye(4)
    m[:3, :3] = ry @ rx @ body_from_optical
    q = quaternion_from_matrix(m)
    return Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])


def depth_msg(depth: np.ndarray, stamp: rospy.Time, encoding: str = "16UC1") -> Image:
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = "kinect2_depth_optical_frame"
    msg.height, msg.width = depth.shape[:2]
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = depth.strides[0]
    msg.data = depth.tobytes()
    return msg


def info_msg(cam: kp.Camera, stamp: rospy.Time) -> CameraInfo:
    msg = CameraInfo()
    msg.header.stamp = stamp
    msg.header.frame_id = "kinect2_depth_optical_frame"
    msg.width, msg.height = cam.width, cam.height
    msg.K = [cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1]
    msg.P = [cam.fx, 0, cam.cx, 0, 0, cam.fy, cam.cy, 0, 0, 0, 1, 0]
    msg.distortion_model = "plumb_bob"
    msg.D = [0.0] * 5
    return msg


class Feeder:
    """Publishes tf then image + camera_info at 15 Hz with whatever pose / image the test sets."""

    def __init__(self) -> None:
        self.image_pub = rospy.Publisher("/kinect2/sd/image_depth", Image, queue_size=5)
        self.info_pub = rospy.Publisher("/kinect2/sd/camera_info", CameraInfo, queue_size=5)
        self.imu_pub = rospy.Publisher("/imu", Imu, queue_size=5)
        self.tf = tf2_ros.TransformBroadcaster()
        self.lock = threading.Lock()
        self.pitch = TILT
        self.imu_pitch: float | None = None
        self.depth = render_frame(CAM, boxes_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None).depth
        self.encoding = "16UC1"
        self.cam = CAM
        self.sent: list[rospy.Time] = []
        self.stop = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        rate = rospy.Rate(15)
        while not self.stop and not rospy.is_shutdown():
            stamp = rospy.Time.now()
            with self.lock:
                t = TransformStamped()
                t.header.stamp = stamp
                t.header.frame_id = "base_footprint"
                t.child_frame_id = "kinect2_depth_optical_frame"
                t.transform.translation.x = 0.1
                t.transform.translation.z = HEIGHT
                t.transform.rotation = optical_quaternion(self.pitch)
                self.tf.sendTransform(t)
                if self.imu_pitch is not None:
                    imu = Imu()
                    imu.header.stamp = stamp
                    q = quaternion_from_matrix(np.array([[math.cos(self.imu_pitch), 0, math.sin(self.imu_pitch), 0],
                                                         [0, 1, 0, 0],
                                                         [-math.sin(self.imu_pitch), 0, math.cos(self.imu_pitch), 0],
                                                         [0, 0, 0, 1]]))
                    imu.orientation = Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
                    self.imu_pub.publish(imu)
                depth, encoding, cam = self.depth, self.encoding, self.cam
            time.sleep(0.005)  # let tf arrive before the image (the node also waits tf_timeout)
            self.info_pub.publish(info_msg(cam, stamp))
            self.image_pub.publish(depth_msg(depth, stamp, encoding))
            self.sent.append(stamp)
            rate.sleep()


class NodeTest(unittest.TestCase):
    feeder: Feeder
    scans: list[LaserScan]
    images: list[Image]
    diags: list[DiagnosticArray]

    @classmethod
    def setUpClass(cls) -> None:
        rospy.init_node("kinect_pipeline_test", anonymous=True)
        cls.scans, cls.images, cls.diags = [], [], []
        rospy.Subscriber("/kinect2/scan", LaserScan, cls.scans.append, queue_size=50)
        rospy.Subscriber("/kinect2/sd/image_depth/processed", Image, cls.images.append, queue_size=50)
        rospy.Subscriber("/diagnostics", DiagnosticArray, cls.diags.append, queue_size=50)
        cls.feeder = Feeder()
        cls.client = Client(NODE, timeout=DEADLINE)

    @classmethod
    def tearDownClass(cls) -> None:
        cls.feeder.stop = True

    def wait_for(self, what: str, cond: Callable[[], bool], timeout: float = DEADLINE) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not rospy.is_shutdown():
            if cond():
                return
            time.sleep(0.02)
        self.fail(f"timed out after {timeout} s waiting for {what}")

    def scan_after(self, t: rospy.Time) -> LaserScan:
        self.wait_for("a scan stamped after the change", lambda: any(s.header.stamp > t for s in self.scans))
        return next(s for s in self.scans if s.header.stamp > t)

    def expected(self, pitch: float, **cfg: object) -> kp.Result:
        pipe = kp.Pipeline(CAM, kp.Config(sensor_height=HEIGHT, sensor_pitch=pitch, **cfg))
        return pipe.process(self.feeder.depth)

    def assert_scan_equal(self, scan: LaserScan, res: kp.Result) -> None:
        got = np.array(scan.ranges, dtype=np.float32)
        np.testing.assert_array_equal(np.isnan(got), np.isnan(res.ranges))
        np.testing.assert_allclose(got, res.ranges, rtol=1e-5, atol=1e-6)
        self.assertAlmostEqual(scan.angle_min, res.angle_min, places=6)
        self.assertAlmostEqual(scan.angle_increment, res.angle_increment, places=7)

    def reconfigure(self, **values: object) -> dict:
        return self.client.update_configuration(values)

    # The tests run in name order; each leaves the node in its default state.
    def test_1_scan_and_cleaned_image_as_the_core_predicts(self) -> None:
        # The first frames may come before the node's tf buffer has the transform (it falls back, as configured).
        self.scan_after(rospy.Time.now())
        t = rospy.Time.now() + rospy.Duration(0.3)
        scan = self.scan_after(t)
        self.assertEqual(scan.header.frame_id, "kinect2_scan")
        self.assertIn(scan.header.stamp, self.feeder.sent)
        self.assert_scan_equal(scan, self.expected(TILT))
        self.assertEqual(len(scan.intensities), len(scan.ranges))
        self.wait_for("a cleaned image", lambda: any(i.header.stamp > t for i in self.images))
        img = next(i for i in self.images if i.header.stamp > t)
        self.assertEqual(img.encoding, "16UC1")
        cleaned = np.frombuffer(img.data, np.uint16).reshape(img.height, img.width)
        np.testing.assert_array_equal(cleaned, self.expected(TILT).depth)

    def test_2_pitch_via_tf_changes_the_output(self) -> None:
        with self.feeder.lock:
            self.feeder.pitch = TILT + 0.1
        t = rospy.Time.now() + rospy.Duration(0.2)
        self.assert_scan_equal(self.scan_after(t), self.expected(TILT + 0.1))
        with self.feeder.lock:
            self.feeder.pitch = TILT

    def test_3_pitch_via_imu_changes_the_output(self) -> None:
        with self.feeder.lock:
            self.feeder.imu_pitch = 0.05
        self.reconfigure(pose_source="imu", sensor_height=HEIGHT, sensor_pitch=TILT)
        t = rospy.Time.now() + rospy.Duration(0.3)
        self.assert_scan_equal(self.scan_after(t), self.expected(TILT + 0.05))
        self.reconfigure(pose_source="tf", sensor_pitch=0.0)
        with self.feeder.lock:
            self.feeder.imu_pitch = None

    def test_4_reconfigure_takes_effect(self) -> None:
        cfg = self.reconfigure(range_max=2.0)
        self.assertEqual(cfg["range_max"], 2.0)
        t = rospy.Time.now() + rospy.Duration(0.2)
        scan = self.scan_after(t)
        self.assert_scan_equal(scan, self.expected(TILT, range_max=2.0))
        self.reconfigure(range_max=10.0)

    def test_5_bad_parameter_is_refused(self) -> None:
        cfg = self.reconfigure(ceiling_height=0.5, sensor_height=1.1)
        self.assertEqual(cfg["ceiling_height"], 2.0, "the server must report the values still in force")
        cfg = self.reconfigure(threshold_curve="2:0.1, 1:0.2")
        self.assertNotEqual(cfg["threshold_curve"], "2:0.1, 1:0.2")
        t = rospy.Time.now()
        self.assert_scan_equal(self.scan_after(t), self.expected(TILT))

    def test_6_bad_frames_are_dropped_and_good_ones_still_served(self) -> None:
        good = self.feeder.depth
        for depth, encoding, cam, reason in (
            (np.zeros((424, 512, 3), np.uint8), "rgb8", CAM, "dropped: unsupported encoding"),
            (good[:100, :100].copy(), "16UC1", CAM, "dropped: image size differs from camera_info"),
        ):
            with self.feeder.lock:
                self.feeder.depth, self.feeder.encoding, self.feeder.cam = depth, encoding, cam
            t = rospy.Time.now()

            def counted(reason: str = reason, t: rospy.Time = t) -> bool:
                for d in self.diags:
                    if d.header.stamp <= t:
                        continue
                    for st in d.status:
                        for kv in st.values:
                            if kv.key == reason and int(kv.value) > 0:
                                return True
                return False

            self.wait_for(f"diagnostics counting '{reason}'", counted)
        with self.feeder.lock:
            self.feeder.depth, self.feeder.encoding, self.feeder.cam = good, "16UC1", CAM
        t = rospy.Time.now()
        self.assert_scan_equal(self.scan_after(t), self.expected(TILT))


if __name__ == "__main__":
    rostest.rosrun("kinect_pipeline", "test_node", NodeTest, sys.argv)
