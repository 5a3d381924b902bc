#!/usr/bin/env python3
"""Checks that every depth frame of a bag played by replay.launch gave a LaserScan with the frame's stamp."""

from __future__ import annotations

import sys
import time
import unittest
from xmlrpc.client import ServerProxy

import numpy as np
import rosbag
import rosgraph
import rospy
import rostest
from sensor_msgs.msg import LaserScan
from std_srvs.srv import SetBool

import kinect_pipeline as kp
from kinect_pipeline.simulation.robot import Rig, SegwayMotion

DEADLINE = 120.0


def delivers(publisher: str, topic: str, subscriber: str) -> bool:
    """Whether publisher sends topic to subscriber: a connection in publisher's bus info (getBusInfo), which roscpp
    lists once the subscriber's header is taken; a message published before that is not sent to it."""
    try:
        uri = rosgraph.Master("/check_replay").lookupNode(publisher)
        code, _, info = ServerProxy(uri).getBusInfo("/check_replay")
    except (rosgraph.MasterError, OSError):
        return False
    # Each connection: [id, the other end, direction, transport, topic, connected, ...].
    return code == 1 and any(c[1] == subscriber and c[2] == "o" and c[4] == topic and c[5] for c in info)


class ReplayTest(unittest.TestCase):
    def test_every_frame_gives_a_scan(self) -> None:
        rospy.init_node("check_replay")
        path = rospy.get_param("~bag")
        subscriber = rospy.get_param("~subscriber", "/kinect2/kinect_pipeline")  # a nodelet's is its manager
        with rosbag.Bag(path) as bag:
            images = {m.header.stamp: m for _, m, _ in bag.read_messages(topics=["/kinect2/sd/image_depth"])}
        stamps = set(images)
        self.assertGreater(len(stamps), 5)
        scans: list[LaserScan] = []
        scan_sub = rospy.Subscriber("/kinect2/scan", LaserScan, scans.append, queue_size=1000)

        # Unpause only once the player sends the images to the pipeline and our subscription takes its scans:
        # connected, not only registered with the master (a frame sent before its connection is up is lost: CI once
        # missed the first three scans).
        deadline = time.monotonic() + DEADLINE
        while time.monotonic() < deadline:
            if scan_sub.get_num_connections() > 0 and delivers("/player", "/kinect2/sd/image_depth", subscriber):
                break
            time.sleep(0.05)
        else:
            self.fail(f"the player never sent /kinect2/sd/image_depth to {subscriber}, or no scan connection came up")
        rospy.wait_for_service("/player/pause_playback", timeout=DEADLINE)
        rospy.ServiceProxy("/player/pause_playback", SetBool)(False)

        while time.monotonic() < deadline and len({s.header.stamp for s in scans} & stamps) < len(stamps):
            time.sleep(0.05)
        got = {s.header.stamp for s in scans}
        missing = sorted(stamps - got)
        self.assertFalse(missing, f"{len(missing)} of {len(stamps)} frames gave no scan, first {missing[:3]}")
        self.assertTrue(all(s.header.frame_id == "kinect2_scan" for s in scans))

        # The pose the node got from the bag's tf tree is the one the frames were rendered at: its scans are what
        # the core gives at that pose, frame after frame as the node took them (what the floor refinement learns
        # carries over; a beam may differ where a pixel sits on a threshold boundary).
        rig, motion, cam = Rig(), SegwayMotion(), kp.kinect_v2_camera()
        by_stamp = {s.header.stamp: s for s in scans}
        core = kp.Pipeline(cam, kp.Config())
        bad = 0
        for st, img in sorted(images.items()):
            _, _, pitch, height = rig.sensor_pose(motion.pitch(img.header.seq))
            depth = np.frombuffer(img.data, np.uint16).reshape(img.height, img.width)
            want = core.process_pose(depth, height, pitch, 0.0, stamp=st.to_sec()).ranges
            got = np.array(by_stamp[st].ranges, np.float32)
            same = np.isclose(got, want, rtol=1e-4, atol=1e-5) | (np.isnan(got) & np.isnan(want))
            bad += int((~same).sum())
        self.assertLessEqual(bad, len(images) * 512 * 0.002, f"{bad} beams differ from the core at the rig's pose")


if __name__ == "__main__":
    rostest.rosrun("kinect_pipeline", "check_replay", ReplayTest, sys.argv)
