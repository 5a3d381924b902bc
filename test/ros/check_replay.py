#!/usr/bin/env python3
"""Checks that every depth frame of a bag played by replay.launch gave a LaserScan with the frame's stamp."""

from __future__ import annotations

import sys
import time
import unittest

import rosbag
import rosgraph
import rospy
import rostest
from sensor_msgs.msg import LaserScan
from std_srvs.srv import SetBool

DEADLINE = 120.0


class ReplayTest(unittest.TestCase):
    def test_every_frame_gives_a_scan(self) -> None:
        rospy.init_node("check_replay")
        path = rospy.get_param("~bag")
        subscriber = rospy.get_param("~subscriber", "/kinect2/kinect_pipeline")  # a nodelet's is its manager
        with rosbag.Bag(path) as bag:
            stamps = {m.header.stamp for _, m, _ in bag.read_messages(topics=["/kinect2/sd/image_depth"])}
        self.assertGreater(len(stamps), 5)
        scans: list[LaserScan] = []
        rospy.Subscriber("/kinect2/scan", LaserScan, scans.append, queue_size=1000)

        # Unpause only once the pipeline listens to the images and our subscription is registered.
        master = rosgraph.Master("/check_replay")
        deadline = time.monotonic() + DEADLINE
        while time.monotonic() < deadline:
            _, subs, _ = master.getSystemState()
            subs = dict(subs)
            if subscriber in subs.get("/kinect2/sd/image_depth", []) and \
                    rospy.get_name() in subs.get("/kinect2/scan", []):
                break
            time.sleep(0.05)
        else:
            self.fail("the pipeline never subscribed to /kinect2/sd/image_depth")
        rospy.wait_for_service("/player/pause_playback", timeout=DEADLINE)
        rospy.ServiceProxy("/player/pause_playback", SetBool)(False)

        while time.monotonic() < deadline and len({s.header.stamp for s in scans} & stamps) < len(stamps):
            time.sleep(0.05)
        got = {s.header.stamp for s in scans}
        missing = sorted(stamps - got)
        self.assertFalse(missing, f"{len(missing)} of {len(stamps)} frames gave no scan, first {missing[:3]}")
        self.assertTrue(all(s.header.frame_id == "kinect2_scan" for s in scans))


if __name__ == "__main__":
    rostest.rosrun("kinect_pipeline", "check_replay", ReplayTest, sys.argv)
