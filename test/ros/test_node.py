#!/usr/bin/env python3
"""rostest of the node / nodelet wiring: depth + camera_info + tf in, LaserScan + cleaned image out, as the core
predicts; and what must not stop it: bad frames, zero and out-of-order stamps, a resolution change, tf appearing
late, inputs stopping and resuming, dynamic_reconfigure at 100 Hz while frames flow. Run by test/ros/node.test and
test/ros/nodelet.test (real roscore, real nodelet manager)."""

from __future__ import annotations

import math
import sys
import threading
import time
import unittest
from collections.abc import Callable

import numpy as np
import rospy
import rostest
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray
from dynamic_reconfigure.client import Client
from frames import optical_quaternion, quaternion_from_matrix
from geometry_msgs.msg import Quaternion, TransformStamped
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import CameraInfo, Image, Imu, LaserScan

import kinect_pipeline as kp
from kinect_pipeline.simulation.scenes import boxes_scene, render_frame

NODE = "/kinect2/kinect_pipeline"
HEIGHT, TILT = 1.1, 0.26
CAM = kp.Camera(512, 424, 365.0, 365.0, 255.5, 211.5)
DEADLINE = 20.0


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
    """Publishes tf then image + camera_info at 15 Hz with whatever pose / image / frame the test sets."""

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
        self.frame_id = "kinect2_depth_optical_frame"
        self.tf_frames = {"kinect2_depth_optical_frame"}  # optical frames whose transform is broadcast
        self.paused = False
        self.stamps: list[rospy.Time] = []  # stamps for the next frames instead of now (zero, out of order)
        self.sent: list[rospy.Time] = []
        self.stop = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        rate = rospy.Rate(15)
        while not self.stop and not rospy.is_shutdown():
            now = rospy.Time.now()
            with self.lock:
                if self.paused:
                    rate.sleep()
                    continue
                stamp = self.stamps.pop(0) if self.stamps else now
                frame_id = self.frame_id
                for child in sorted(self.tf_frames):
                    t = TransformStamped()
                    t.header.stamp = now
                    t.header.frame_id = "base_footprint"
                    t.child_frame_id = child
                    t.transform.translation.x = 0.1
                    t.transform.translation.z = HEIGHT
                    t.transform.rotation = optical_quaternion(self.pitch)
                    self.tf.sendTransform(t)
                if self.imu_pitch is not None:
                    imu = Imu()
                    imu.header.stamp = stamp
                    q = quaternion_from_matrix(
                        np.array(
                            [
                                [math.cos(self.imu_pitch), 0, math.sin(self.imu_pitch), 0],
                                [0, 1, 0, 0],
                                [-math.sin(self.imu_pitch), 0, math.cos(self.imu_pitch), 0],
                                [0, 0, 0, 1],
                            ]
                        )
                    )
                    imu.orientation = Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
                    self.imu_pub.publish(imu)
                depth, encoding, cam = self.depth, self.encoding, self.cam
            time.sleep(0.005)  # let tf arrive before the image (the node also waits tf_timeout)
            info, image = info_msg(cam, stamp), depth_msg(depth, stamp, encoding)
            info.header.frame_id = image.header.frame_id = frame_id
            self.info_pub.publish(info)
            self.image_pub.publish(image)
            self.sent.append(stamp)
            rate.sleep()


class NodeTest(unittest.TestCase):
    feeder: Feeder
    scans: list[LaserScan]
    images: list[Image]
    diags: list[DiagnosticArray]
    logs: list[Log]

    @classmethod
    def setUpClass(cls) -> None:
        rospy.init_node("kinect_pipeline_test", anonymous=True)
        cls.scans, cls.images, cls.diags, cls.logs = [], [], [], []
        rospy.Subscriber("/rosout", Log, cls.logs.append, queue_size=200)
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

    def expected(self, pitch: float, cam: kp.Camera = CAM, depth: np.ndarray | None = None, **cfg: object) -> kp.Result:
        pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=pitch, refine_floor=False, **cfg))
        return pipe.process(self.feeder.depth if depth is None else depth)

    def counter(self, key: str, after: rospy.Time | None = None) -> int:
        """The node's newest diagnostics value ``key`` (published after ``after``), -1 if none yet."""
        for d in reversed(list(self.diags)):
            if after is not None and d.header.stamp <= after:
                break
            for st in d.status:
                for kv in st.values:
                    if kv.key == key:
                        return int(kv.value)
        return -1

    def wait_count_above(self, key: str, before: int) -> int:
        t = rospy.Time.now()
        self.wait_for(f"diagnostics counting '{key}' above {before}", lambda: self.counter(key, t) > before)
        return self.counter(key, t)

    def current(self, key: str) -> int:
        """A diagnostics counter as of now (waits for diagnostics published after this call)."""
        t = rospy.Time.now()
        self.wait_for(f"diagnostics with '{key}'", lambda: self.counter(key, t) >= 0)
        return self.counter(key, t)

    def node_errors(self, text: str, after: rospy.Time) -> list[str]:
        return [
            m.msg
            for m in list(self.logs)
            if m.level >= Log.ERROR and m.header.stamp > after and text in m.msg and "kinect_pipeline" in m.name + m.msg
        ]

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

    def test_7_zero_and_out_of_order_stamps_are_dropped_counted_and_said(self) -> None:
        zero0, order0 = self.current("dropped: zero stamp"), self.current("dropped: stamp out of order")
        t = rospy.Time.now()
        with self.feeder.lock:
            old = rospy.Time.now() - rospy.Duration(2.0)
            self.feeder.stamps = [rospy.Time(0), rospy.Time(0), old, rospy.Time(0), old - rospy.Duration(1.0)]
        zero = self.wait_count_above("dropped: zero stamp", zero0 + 2)
        order = self.wait_count_above("dropped: stamp out of order", order0 + 1)
        self.assertEqual(zero, zero0 + 3)
        self.assertEqual(order, order0 + 2)
        # One clear line per reason (throttled: 5 bad frames within a second give one line each), naming the value.
        self.wait_for("the zero-stamp error on /rosout", lambda: bool(self.node_errors("(zero stamp)", t)))
        self.wait_for("the out-of-order error on /rosout", lambda: bool(self.node_errors("(stamp out of order)", t)))
        zero_lines = self.node_errors("(zero stamp)", t)
        order_lines = self.node_errors("(stamp out of order)", t)
        self.assertEqual(len(zero_lines), 1, zero_lines)
        self.assertEqual(len(order_lines), 1, order_lines)
        self.assertIn("image stamp is 0", zero_lines[0])
        self.assertIn(f"stamp {old.secs}.", order_lines[0])
        self.assertIn("is not newer than the previous frame's", order_lines[0])
        # Good frames go on being served.
        self.assert_scan_equal(self.scan_after(rospy.Time.now()), self.expected(TILT))

    def test_7b_a_loop_whose_first_pass_began_at_its_second_frame_drops_nothing(self) -> None:
        # rosbag play publishes before the node is connected, so the first pass may begin at the bag's second
        # frame; on the next pass, the first frame (older than that start) must be served, not dropped.
        order0 = self.current("dropped: stamp out of order")
        seen = len(self.scans)
        base = rospy.Time.now() - rospy.Duration(3.0)
        bag = [base + rospy.Duration(0.1 * k) for k in range(1, 5)]
        with self.feeder.lock:
            self.feeder.stamps = bag[1:] + bag + bag
        self.wait_for("three passes served", lambda: sum(s.header.stamp == bag[-1] for s in self.scans[seen:]) >= 3)
        served = [s.header.stamp for s in self.scans[seen:] if s.header.stamp <= bag[-1]]
        self.assertEqual(served, bag[1:] + bag + bag)
        self.scan_after(rospy.Time.now())
        self.assertEqual(self.current("dropped: stamp out of order"), order0)

    def test_8_camera_changing_resolution_is_followed(self) -> None:
        size0 = self.current("dropped: image size differs from camera_info")
        changes0 = self.current("camera model changes")
        half = kp.Camera(256, 212, CAM.fx / 2, CAM.fy / 2, 127.5, 105.5)
        small = render_frame(half, boxes_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None).depth
        big = self.feeder.depth
        for cam, depth in ((half, small), (CAM, big)):
            with self.feeder.lock:
                self.feeder.depth, self.feeder.cam = depth, cam
            t = rospy.Time.now() + rospy.Duration(0.1)
            self.wait_for(
                f"a scan of {cam.width} beams",
                lambda t=t, w=cam.width: any(s.header.stamp > t and len(s.ranges) == w for s in self.scans),
            )
            scan = next(s for s in self.scans if s.header.stamp > t and len(s.ranges) == cam.width)
            self.assert_scan_equal(scan, self.expected(TILT, cam=cam, depth=depth))
        self.assertGreaterEqual(self.wait_count_above("camera model changes", changes0 + 1), changes0 + 2)
        # camera_info and image changed together: nothing was dropped for disagreeing sizes.
        self.assertEqual(self.current("dropped: image size differs from camera_info"), size0)

    def test_9_tf_appearing_late_falls_back_then_is_used(self) -> None:
        fallbacks0 = self.current("pose fallbacks")
        with self.feeder.lock:
            self.feeder.frame_id = "kinect2_late_optical_frame"  # no transform for it yet
        self.wait_count_above("pose fallbacks", fallbacks0)
        # pose_fallback: static -> the launch file's static pose (sensor_height 1.1, sensor_pitch 0).
        self.assert_scan_equal(self.scan_after(rospy.Time.now()), self.expected(0.0))
        with self.feeder.lock:
            self.feeder.tf_frames.add("kinect2_late_optical_frame")
        t = rospy.Time.now()
        self.wait_for(
            "a scan at the tf pose once tf appeared",
            lambda: any(s.header.stamp > t and self.same_scan(s, self.expected(TILT)) for s in self.scans),
        )
        with self.feeder.lock:
            self.feeder.frame_id = "kinect2_depth_optical_frame"
            self.feeder.tf_frames.discard("kinect2_late_optical_frame")

    def same_scan(self, scan: LaserScan, res: kp.Result) -> bool:
        try:
            self.assert_scan_equal(scan, res)
        except AssertionError:
            return False
        return True

    def test_a_inputs_stopping_and_resuming(self) -> None:
        with self.feeder.lock:
            self.feeder.paused = True
        t = rospy.Time.now()

        def silence_reported() -> bool:
            for d in list(self.diags):
                if d.header.stamp > t:
                    for st in d.status:
                        if "No events" in st.message or "too low" in st.message:
                            return True
            return False

        self.wait_for("diagnostics reporting that no image comes", silence_reported)
        with self.feeder.lock:
            self.feeder.paused = False
        self.assert_scan_equal(self.scan_after(rospy.Time.now()), self.expected(TILT))

    def test_b_reconfigure_at_100hz_while_frames_flow(self) -> None:
        configs = [{"range_max": 4.0, "scan_beams": 128}, {"range_max": 8.0, "scan_beams": 256}]
        want = {(c["scan_beams"], c["range_max"]): self.expected(TILT, **c) for c in configs}
        want[(512, 10.0)] = self.expected(TILT)
        n_before = len(self.scans)
        errors: list[str] = []
        counts = [0, 0]

        def hammer(i: int) -> None:
            # Two clients at 50 Hz each, one per config: 100 changes a second reach the node's server.
            client = Client(NODE, timeout=DEADLINE)
            next_t = time.monotonic()
            while counts[i] < 150 and not rospy.is_shutdown():
                try:
                    client.update_configuration(configs[i])
                except Exception as e:
                    errors.append(repr(e))
                counts[i] += 1
                next_t += 0.02
                time.sleep(max(0.0, next_t - time.monotonic()))

        t0 = time.monotonic()
        threads = [threading.Thread(target=hammer, args=(i,)) for i in range(2)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        rate = sum(counts) / (time.monotonic() - t0)
        print(f"[ info ] {sum(counts)} dynamic_reconfigure updates at {rate:.0f} Hz", file=sys.stderr)
        self.assertEqual(errors, [])
        self.reconfigure(range_max=10.0, scan_beams=0)
        t = rospy.Time.now()
        self.assert_scan_equal(self.scan_after(t), self.expected(TILT))
        during = list(self.scans)[n_before:]
        self.assertGreater(len(during), 5)
        for scan in during:
            key = (len(scan.ranges), round(scan.range_max, 3))
            self.assertIn(key, want, f"scan with {key[0]} beams and range_max {key[1]}: not one config")
            self.assert_scan_equal(scan, want[key])


if __name__ == "__main__":
    rostest.rosrun("kinect_pipeline", "test_node", NodeTest, sys.argv)
