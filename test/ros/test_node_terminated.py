#!/usr/bin/python3
"""SIGTERM ends the node like SIGINT: its own bag is written out, closed and renamed, holding what it published."""
import os
import signal
import sys
import time
import unittest
import xmlrpc.client

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rosbag  # noqa: E402
import rosgraph  # noqa: E402
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from helpers import Collector, wait_for  # noqa: E402

NODE = "/backlash_servo"


class NodeTerminated(unittest.TestCase):
    def test_sigterm_closes_the_bag(self):
        rospy.init_node("test_node_terminated")
        path = rospy.get_param("~bag")
        joints = Collector("/joint_states", JointState)
        self.assertTrue(joints.wait_connected())
        self.assertTrue(wait_for(lambda: len(joints.msgs) >= 300, 60.0))  # 3 s of sim time, moving (command 1 rad)
        api = rosgraph.Master("/test_node_terminated").lookupNode(NODE)
        code, _, pid = xmlrpc.client.ServerProxy(api).getPid("/test_node_terminated")
        self.assertEqual(code, 1)
        os.kill(pid, signal.SIGTERM)
        self.assertTrue(wait_for(lambda: os.path.exists(path) and not os.path.exists(path + ".active"), 30.0), path)
        time.sleep(0.5)  # the last messages in flight to this client
        with rosbag.Bag(path) as bag:
            stamps = [m.header.stamp for _, m, _ in bag.read_messages(topics=["/joint_states"])]
            clocks = bag.get_message_count("/clock")
        got = [m.header.stamp for m in joints.msgs]
        # The bag holds every sample from t = 0 (10 ms apart, none missing) to the end, and every sample the client
        # received (from when it connected) in order; it holds more at the end — published while the client lagged,
        # which roscpp drops from a subscriber's outgoing queue when the node exits but the node's own bag keeps.
        self.assertGreaterEqual(len(stamps), 300)
        first = stamps.index(got[0])
        self.assertEqual(stamps[first:first + len(got)], got)
        self.assertEqual([(b - a).to_nsec() for a, b in zip(stamps, stamps[1:])], [10**7] * (len(stamps) - 1))
        self.assertEqual(clocks, len(stamps))
        os.remove(path)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "node_terminated", NodeTerminated)
